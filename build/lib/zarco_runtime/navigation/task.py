"""Navigation on the bus: GPS / compass / gyro messages → NavState.

The estimator folds each measurement in as it is published (a bus listener:
bounded-time work, done in the publishing driver's context, so a fix reaches
the controller with no scheduling delay) and publishes the updated NavState.
"""

from __future__ import annotations

import asyncio
from typing import TYPE_CHECKING

from zarco_core.bus import Bus, Listen
from zarco_core.clock import Clock
from zarco_core.geodesy import LocalFrame
from zarco_core.messages import GpsErrorStats, GpsFix, GpsVelocity, Heading, RateOfTurn
from zarco_runtime.navigation.ekf import EkfNavigator
from zarco_runtime.navigation.simple import SimpleNavigator

if TYPE_CHECKING:
    from zarco_runtime.settings import RuntimeConfig


class Navigation:
    """Wires a navigator to the bus."""

    def __init__(self, cfg: RuntimeConfig, bus: Bus, clock: Clock,
                 listen: Listen | None = None) -> None:
        o = cfg.origin
        frame = LocalFrame(o.lat_deg, o.lon_deg, o.alt_m)
        var = cfg.devices.compass.variation_deg
        self.nav: SimpleNavigator | EkfNavigator
        on = listen or bus.listen
        if cfg.navigation.estimator == "ekf":
            self.nav = EkfNavigator(cfg.ekf, frame, var)
            on(GpsErrorStats, self.nav.on_gst)
        else:
            self.nav = SimpleNavigator(cfg.navigation, frame, var)
        self.bus = bus
        self.clock = clock
        on(GpsFix, self._on_fix)
        on(GpsVelocity, self.nav.on_velocity)
        on(Heading, self._on_heading)
        on(RateOfTurn, self._on_rate)

    async def run(self) -> None:
        """The estimator works in its listeners; this task only keeps it alive."""
        await asyncio.Event().wait()

    def _publish(self, t: float) -> None:
        self.bus.publish(self.nav.state(t))

    def _on_fix(self, m: GpsFix) -> None:
        self.nav.on_fix(m)
        self._publish(m.t)

    def _on_heading(self, m: Heading) -> None:
        self.nav.on_heading(m)
        if not self.nav.has_gyro(m.t):  # with a gyro, the ROT that follows publishes
            self._publish(m.t)

    def _on_rate(self, m: RateOfTurn) -> None:
        self.nav.on_rate(m)
        self._publish(m.t)
