"""Navigation on the bus: GPS / compass / gyro messages and thruster commands → NavState.

The estimator folds each measurement in as it is published (a bus listener:
bounded-time work, done in the publishing driver's context) and publishes the
updated NavState after each yaw-rate (ROT) measurement: at the compass's rate
(20 Hz, the control rate), carrying every GPS position fused since (a fix
waits at most one compass period).  Without a gyro it publishes after each
heading and each GPS position instead.  The EKF also listens to the
controller's ThrusterCommand, the input of its vessel model (see
:mod:`zarco_runtime.navigation.ekf`).

What the runtime does with it: construct ``Navigation(cfg, bus, clock)`` before
the controller starts; nothing else (no task to run).  :meth:`Navigation.state`
gives the estimate predicted to any time for a caller that wants to read it
at its own rate instead of extrapolating the last NavState.
"""

from __future__ import annotations

import asyncio
from typing import TYPE_CHECKING

from zarco_core.bus import Bus, Listen
from zarco_core.clock import Clock
from zarco_core.geodesy import LocalFrame
from zarco_core.messages import (
    GpsErrorStats,
    GpsFix,
    GpsVelocity,
    Heading,
    NavState,
    RateOfTurn,
    ThrusterCommand,
)
from zarco_core.thruster_map import ThrusterMap
from zarco_runtime.navigation.ekf import EkfNavigator
from zarco_runtime.navigation.simple import SimpleNavigator

if TYPE_CHECKING:
    from zarco_runtime.settings import RuntimeConfig


class Navigation:
    """Wires a navigator to the bus (``navigation.estimator``: the EKF, or the first
    estimate as a fallback)."""

    def __init__(self, cfg: RuntimeConfig, bus: Bus, clock: Clock,
                 listen: Listen | None = None) -> None:
        o = cfg.origin
        frame = LocalFrame(o.lat_deg, o.lon_deg, o.alt_m)
        var = cfg.devices.compass.variation_deg
        self.nav: SimpleNavigator | EkfNavigator
        on = listen or bus.listen
        if cfg.navigation.estimator == "ekf":
            ekf = EkfNavigator(cfg.ekf, frame, var)
            th = cfg.thrusters
            ekf.set_vessel(cfg.vessel, ThrusterMap.from_table(th.port.u, th.port.f_n),
                           ThrusterMap.from_table(th.starboard.u, th.starboard.f_n))
            on(GpsErrorStats, ekf.on_gst)
            on(ThrusterCommand, ekf.on_command)
            self.nav = ekf
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

    def state(self, t: float) -> NavState:
        """The estimate predicted to time ``t`` (s), not published."""
        return self.nav.state(t)

    def _publish(self, t: float) -> None:
        self.bus.publish(self.nav.state(t))

    def _on_fix(self, m: GpsFix) -> None:
        # False: a sentence of an epoch another one carries; with a gyro, the
        # ROT that follows (within one compass period) publishes
        if self.nav.on_fix(m) and not self.nav.has_gyro(m.t):
            self._publish(m.t)

    def _on_heading(self, m: Heading) -> None:
        self.nav.on_heading(m)
        if not self.nav.has_gyro(m.t):  # with a gyro, the ROT that follows publishes
            self._publish(m.t)

    def _on_rate(self, m: RateOfTurn) -> None:
        self.nav.on_rate(m)
        self._publish(m.t)
