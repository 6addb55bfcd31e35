"""Navigation task: GPS / compass / gyro messages → NavState on the bus."""

from __future__ import annotations

from zarco_runtime.bus import Bus
from zarco_runtime.clock import Clock
from zarco_runtime.geodesy import LocalFrame
from zarco_runtime.messages import GpsFix, GpsVelocity, Heading, RateOfTurn
from zarco_runtime.navigation.simple import SimpleNavigator
from zarco_runtime.settings import RuntimeConfig


class NavigationTask:
    """Feeds the estimator every measurement in order; publishes after each batch."""

    def __init__(self, cfg: RuntimeConfig, bus: Bus, clock: Clock) -> None:
        o = cfg.origin
        self.nav = SimpleNavigator(cfg.navigation, LocalFrame(o.lat_deg, o.lon_deg, o.alt_m),
                                   cfg.devices.compass.variation_deg)
        self.bus = bus
        self.clock = clock
        self.sub = bus.subscribe(GpsFix, GpsVelocity, Heading, RateOfTurn, maxlen=512)

    def handle(self, m: object) -> None:
        nav = self.nav
        if isinstance(m, GpsFix):
            nav.on_fix(m)
        elif isinstance(m, GpsVelocity):
            nav.on_velocity(m)
        elif isinstance(m, Heading):
            nav.on_heading(m)
        elif isinstance(m, RateOfTurn):
            nav.on_rate(m)

    async def run(self) -> None:
        sub = self.sub
        while True:
            m = await sub.get()
            self.handle(m)
            for m2 in sub.drain():
                self.handle(m2)
            self.bus.publish(self.nav.state(self.clock.now()))
