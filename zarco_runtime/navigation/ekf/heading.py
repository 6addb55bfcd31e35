"""Heading and rate of turn in the EKF: compass, true heading, gyro.

A true heading (HDT/THS from a dual-antenna source) measures ψ; a compass
(magnetic + variation) measures ψ + b_c; the gyro (ROT) r + b_g.

Compass bias vs current (and crab)
----------------------------------
On a straight leg at constant speed a compass bias b_c and a cross-track
current c⊥ show the same thing, a constant angle between heading and course:
only U·b_c + c⊥ is seen.  What separates them is a change of the boat's
velocity through the water that the current does not share: a turn (on
headings ψ and ψ + 180° the current's share changes sign and the bias's does
not), and a change of speed along the heading — the acceleration from rest at
the start of a mission, which the thrust model predicts, shows the heading
directly.  The filter keeps both states with honest priors (b_c:
``compass_bias_sigma_deg``, 3°; current: ``current_sigma_mps``, 0.3 m/s).
With ``estimate_current = false`` the bias alone explains any crab: best
without current, wrong with one.  A true heading (HDT/THS) makes the bias
directly observable.  A constant sideways thrust (thrusters misaligned the
same way) cannot be told from a compass bias with these sensors: it ends up in
b_c (the heading then is the direction the boat moves through the water, which
is what line tracking needs).
"""

from __future__ import annotations

import math

from zarco_core.angles import wrap
from zarco_runtime.navigation.ekf.layout import (
    IBC,
    IBG,
    ICE,
    ICN,
    IPSI,
    IR,
    K_COMPASS,
    K_ROT,
    FilterState,
    Measurement,
)
from zarco_runtime.navigation.ekf.updates import Gatekeeping, reset_block, update1


class HeadingFusion(Gatekeeping):
    """Fuses headings (compass, true) and rates of turn into a :class:`FilterState`."""

    def fuse_heading(self, c: FilterState, m: Measurement) -> None:
        x = c.x
        compass = m.kind == K_COMPASS
        if not c.hdg_init or c.hdg_course:
            self.init_heading(c, m, compass)
            return
        nu = wrap(m.z1 - x[IPSI] - (x[IBC] if compass else 0.0))
        h = self.noise.h_compass if compass else self.noise.h_true
        if update1(c, h, nu, m.r1, self.gates[m.kind]):
            self.accepted(c, m.kind)
            c.t_hdg = m.tov
        elif self.rejected(c, m.kind, m.tov):
            self.init_heading(c, m, compass)

    def init_heading(self, c: FilterState, m: Measurement, compass: bool) -> None:
        """(Re-)initialise ψ from a heading measurement (ψ = z − b_c for a compass)."""
        x, P = c.x, c.P
        if c.hdg_course and self.cfg.estimate_current:
            # the first heading sensor after a heading from the course: now a current
            # can be told from the course, starting from its prior
            reset_block(c, (ICN, ICE), (self.cfg.current_sigma_mps**2,) * 2)
        c.hdg_course = False
        P[IPSI, :] = 0.0
        P[:, IPSI] = 0.0
        if compass:
            # ψ = z − b_c: ψ's covariance with everything is minus b_c's
            row = -P[IBC, :]
            row[IPSI] = P[IBC, IBC] + m.r1
            P[IPSI, :] = row
            P[:, IPSI] = row
            x[IPSI] = wrap(m.z1 - x[IBC])
        else:
            x[IPSI] = m.z1
            P[IPSI, IPSI] = m.r1
        c.hdg_init = True
        c.t_hdg = m.tov

    def fuse_rot(self, c: FilterState, m: Measurement) -> None:
        x = c.x
        h_rot = self.noise.h_rot
        nu = m.z1 - (x[IR] + x[IBG])
        if update1(c, h_rot, nu, m.r1, self.gates[K_ROT]):
            self.accepted(c, K_ROT)
            c.t_rot = m.tov
        elif self.rejected(c, K_ROT, m.tov):
            reset_block(c, (IR,), (nu * nu,))
            update1(c, h_rot, nu, m.r1, math.inf)
