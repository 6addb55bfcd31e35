"""A simulated AUV flying straight lines between waypoints (paper V's motion model),
and the continuous turns (arcs, circles, spirals) the paper's model leaves out.

Kinematics in the local NED frame (x north, y east, metres; depth positive
down; heading ψ clockwise from north)::

    x' = v cos ψ      y' = v sin ψ      ψ' = clamp((ψ_d − ψ)/τ_ψ, ±ω_max)

at constant speed v and depth.  Guidance is line-of-sight on the current leg
(waypoint k−1 → k): ψ_d = ψ_leg − atan(d/Δ), d the cross-track offset
(starboard positive), Δ the look-ahead.  The next leg starts when the
along-track distance left is R tan(min(|Δψ|, 90°)/2), R = v/ω_max (the turn is
anticipated so that the finite-rate turn joins the next line rather than
overshooting it; a sharper turn, up to a reversal, starts R before the waypoint
and the line-of-sight guidance brings the AUV onto the next line).
After the last waypoint the AUV hovers there (``at_end = "stop"``) or keeps its
course (``"continue"``).  Before ``start_delay_s`` it hovers at the first
waypoint, pointing at the second.

A waypoint may carry a continuous turn (``arcs``): on reaching it (no
anticipation) the AUV turns at constant speed with radius
R(θ) = R₀ + g·θ/360°, θ the angle turned so far (g = 0: an arc of a circle;
g ≠ 0: a spiral), the yaw rate v/R(θ) clamped to ω_max, until it has turned
through the arc's angle; then it flies on from where it is to the next
waypoint (a draw places that waypoint along the exit course).

Lines may be defined on the fly: :meth:`Auv.append_waypoint` and
:meth:`Auv.set_waypoints`.  Motion is integrated ahead of the queries (the
acoustic simulation looks a few seconds ahead for propagation), so a change
takes effect from the first step not yet integrated.

Deterministic (no randomness); integrated on the fixed grid t_k = k dt
(midpoint rule for the heading), positions between grid points interpolated
linearly (chord error < v ω dt²/8, about 10 µm at 1 m/s, 10 °/s, 0.05 s).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from zarco_core.config import spec

#: ``at_end`` behaviours
AT_END = ("stop", "continue")


@dataclass(slots=True)
class AuvParams:
    """The simulated AUV (``[world.auv]`` of a scenario)."""

    waypoints: list[list[float]] = spec(
        [[100.0, 100.0], [300.0, 100.0], [300.0, 300.0]], "m",
        "waypoints [north, east] in the local NED frame; a single waypoint: the AUV "
        "hovers there")
    speed_mps: float = spec(1.0, "m/s", "speed along the lines", min=0.0, max=5.0)
    depth_m: float = spec(10.0, "m", "constant depth, positive down", min=0.0, max=6000.0)
    turn_rate_dps: float = spec(10.0, "deg/s", "largest turn rate", min=0.1, max=90.0)
    heading_tau_s: float = spec(1.0, "s", "heading response time constant",
                                min=0.05, max=60.0)
    lookahead_m: float = spec(10.0, "m", "line-of-sight look-ahead", min=0.5, max=1000.0)
    start_delay_s: float = spec(0.0, "s", "hover at the first waypoint until this time",
                                min=0.0, max=1e6)
    at_end: str = spec("stop", "", "after the last waypoint: hover there or keep the "
                       "course", choices=list(AT_END))
    dt_s: float = spec(0.05, "s", "integration step", min=0.001, max=1.0)
    arcs: list[list[float]] = spec(
        [], "", "continuous turns flown on reaching a waypoint: [waypoint index, radius m, "
        "angle deg (+ to starboard), radius growth m per 360°] each (growth 0: an arc of a "
        "circle; otherwise a spiral)")

    def validate(self) -> None:
        if not self.waypoints:
            raise ValueError("waypoints: at least one waypoint")
        for i, w in enumerate(self.waypoints):
            if len(w) != 2 or not all(math.isfinite(v) for v in w):
                raise ValueError(f"waypoints: waypoint {i} must be [north, east], got {w}")
        seen: set[int] = set()
        for i, a in enumerate(self.arcs):
            if len(a) != 4 or not all(math.isfinite(v) for v in a):
                raise ValueError(f"arcs: arc {i} must be [waypoint index, radius m, angle deg, "
                                 f"growth m per 360°], got {a}")
            k, radius, angle, growth = a
            if k != int(k) or not 1 <= int(k) < len(self.waypoints):
                raise ValueError(f"arcs: arc {i}: waypoint index must be an integer in 1.."
                                 f"{len(self.waypoints) - 1}, got {k}")
            if int(k) in seen:
                raise ValueError(f"arcs: arc {i}: waypoint {int(k)} already has an arc")
            seen.add(int(k))
            if not 1.0 <= radius <= 10_000.0:
                raise ValueError(f"arcs: arc {i}: radius must be in 1..10000 m, got {radius}")
            if not 1.0 <= abs(angle) <= 3600.0:
                raise ValueError(f"arcs: arc {i}: |angle| must be in 1..3600°, got {angle}")
            end_radius = radius + growth * abs(angle) / 360.0
            if not 1.0 <= end_radius <= 10_000.0:
                raise ValueError(f"arcs: arc {i}: the radius at the arc's end must be in "
                                 f"1..10000 m, got {end_radius:.1f}")


@dataclass(frozen=True, slots=True)
class AuvManoeuvre:
    """A course change of the AUV: from ``start_s`` to ``end_s`` (sim s), through
    ``angle_rad`` (signed, + to starboard).  A leg switch (``arc`` false) is an
    instant (start = end, the angle between the planned legs; the finite-rate
    turn follows it); an arc is a continuous turn, start to end."""

    start_s: float
    end_s: float
    angle_rad: float
    arc: bool


#: a leg switch after an arc counts as a turn only when the new leg's course is
#: at least this far (deg) from the course the arc ended on
ARC_EXIT_TURN_DEG = 5.0


@dataclass(frozen=True, slots=True)
class AuvTruth:
    """The AUV's true state at ``t_s``: NED position (m), depth (m, down),
    heading (rad, clockwise from north), speed (m/s), velocity north/east (m/s),
    and the index of the waypoint it is heading for."""

    t_s: float
    x_m: float
    y_m: float
    depth_m: float
    psi_rad: float
    speed_mps: float
    vx_mps: float
    vy_mps: float
    leg: int


def _wrap(a: float) -> float:
    """Angle to (−π, π]."""
    return math.atan2(math.sin(a), math.cos(a))


class Auv:
    """The AUV's motion; query with :meth:`truth` / :meth:`position` at any time
    ≥ 0 (the model integrates as far as needed and keeps its whole history)."""

    def __init__(self, params: AuvParams) -> None:
        params.validate()
        self.params = params
        self.wps: list[tuple[float, float]] = [(float(w[0]), float(w[1]))
                                               for w in params.waypoints]
        self.dt = params.dt_s
        self.v = params.speed_mps
        self.omega = math.radians(params.turn_rate_dps)
        x, y = self.wps[0]
        psi = (math.atan2(self.wps[1][1] - y, self.wps[1][0] - x) if len(self.wps) > 1
               else 0.0)
        # the leg being flown ends at waypoint `self.leg` (0: hovering at the start)
        self.leg = 1 if len(self.wps) > 1 else 0
        self.stopped = len(self.wps) < 2
        self._leg_start = (x, y)
        # history on the grid: k → (x, y, psi, v, leg)
        self._x = [x]
        self._y = [y]
        self._psi = [psi]
        self._v = [0.0]
        self._legs = [self.leg]
        #: (grid time s, signed course change rad, + to starboard) of each leg switch
        self._turns: list[tuple[float, float]] = []
        self._manoeuvres: list[AuvManoeuvre] = []
        #: continuous turns by waypoint index: (radius m, angle rad signed, growth m/rad)
        self._arc_at = {int(a[0]): (float(a[1]), math.radians(a[2]), float(a[3]) / math.tau)
                        for a in params.arcs}
        #: the arc being flown: [start s, radius m, angle rad signed, growth m/rad,
        #: turned rad]; None on a line
        self._arc: list[float] | None = None
        self._after_arc = False

    # ---------------------------------------------------- lines on the fly

    def append_waypoint(self, north_m: float, east_m: float) -> None:
        """Add a waypoint at the end of the route (resumes a stopped AUV)."""
        self.wps.append((float(north_m), float(east_m)))
        if self.stopped:
            k = len(self._x) - 1
            self._leg_start = (self._x[k], self._y[k])
            self.leg = len(self.wps) - 1
            self.stopped = False

    def set_waypoints(self, waypoints: list[list[float]]) -> None:
        """Replace the rest of the route: fly from the current position to
        ``waypoints[0]``, then on along the list."""
        if not waypoints:
            raise ValueError("set_waypoints: empty route")
        k = len(self._x) - 1
        start = (self._x[k], self._y[k])
        self.wps = [start, *((float(w[0]), float(w[1])) for w in waypoints)]
        self._leg_start = start
        self.leg = 1
        self.stopped = False

    # -------------------------------------------------------- integration

    def _desired(self, x: float, y: float) -> tuple[float, bool]:
        """(ψ_d, switch) for the current leg at (x, y)."""
        (x0, y0), (x1, y1) = self._leg_start, self.wps[self.leg]
        lx, ly = x1 - x0, y1 - y0
        length = math.hypot(lx, ly)
        if length < 1e-9:
            return self._psi[-1], True
        ux, uy = lx / length, ly / length
        along = (x - x0) * ux + (y - y0) * uy
        d = -(x - x0) * uy + (y - y0) * ux
        psi_leg = math.atan2(uy, ux)
        left = length - along
        if self.leg in self._arc_at:
            switch = left <= 0.0
        elif self.leg + 1 < len(self.wps):
            (x2, y2) = self.wps[self.leg + 1]
            turn = abs(_wrap(math.atan2(y2 - y1, x2 - x1) - psi_leg))
            radius = self.v / self.omega if self.omega > 0.0 else 0.0
            switch = left <= radius * math.tan(min(turn, math.radians(90.0)) / 2.0)
        else:
            switch = left <= 0.0
        return psi_leg - math.atan(d / self.params.lookahead_m), switch

    def _leg_course(self) -> float:
        """Course of the leg being flown (rad, clockwise from north)."""
        (x0, y0), (x1, y1) = self._leg_start, self.wps[self.leg]
        return math.atan2(y1 - y0, x1 - x0)

    def _step(self, t: float) -> None:
        """Integrate one step from grid time ``t``."""
        k = len(self._x) - 1
        x, y, psi = self._x[k], self._y[k], self._psi[k]
        dt = self.dt
        p = self.params
        if t + 1e-9 < p.start_delay_s or self.stopped:
            self._append(x, y, psi, 0.0)
            return
        if self._arc is not None:
            self._arc_step(t, x, y, psi)
            return
        psi_d, switch = self._desired(x, y)
        if self._after_arc:
            switch = True  # the arc at this leg's waypoint is flown: on to the next
        elif switch and self.leg in self._arc_at:
            radius, angle, growth = self._arc_at[self.leg]
            self._arc = [t, radius, angle, growth, 0.0]
            self._after_arc = True
            self._arc_step(t, x, y, psi)
            return
        if switch:
            if self.leg + 1 < len(self.wps):
                before = psi if self._after_arc else self._leg_course()
                self._leg_start = (x, y) if self._after_arc else self.wps[self.leg]
                self.leg += 1
                turn = _wrap(self._leg_course() - before)
                if not self._after_arc or abs(turn) >= math.radians(ARC_EXIT_TURN_DEG):
                    self._turns.append((t + dt, turn))
                    self._manoeuvres.append(AuvManoeuvre(t + dt, t + dt, turn, False))
                self._after_arc = False
                psi_d, _ = self._desired(x, y)
            elif p.at_end == "stop":
                self.stopped = True
                self._append(x, y, psi, 0.0)
                return
            else:
                psi_d = psi
        rate = max(-self.omega, min(self.omega, _wrap(psi_d - psi) / p.heading_tau_s))
        psi_mid = psi + 0.5 * rate * dt
        v = self.v
        self._append(x + v * math.cos(psi_mid) * dt, y + v * math.sin(psi_mid) * dt,
                     _wrap(psi + rate * dt), v)

    def _arc_step(self, t: float, x: float, y: float, psi: float) -> None:
        """One step of the continuous turn being flown (its last step turns only
        what is left of its angle); at its end the AUV flies on to the next
        waypoint from where it is."""
        arc = self._arc
        assert arc is not None
        t0, radius, angle, growth, turned = arc
        dt = self.dt
        v = self.v
        r_now = radius + growth * turned
        rate = min(v / max(r_now, 1e-6), self.omega) if self.omega > 0.0 else 0.0
        step = min(rate * dt, abs(angle) - turned)
        signed = math.copysign(step, angle)
        psi_mid = psi + 0.5 * signed
        self._append(x + v * math.cos(psi_mid) * dt, y + v * math.sin(psi_mid) * dt,
                     _wrap(psi + signed), v)
        arc[4] = turned + step
        if arc[4] >= abs(angle) - 1e-12:
            self._arc = None
            self._manoeuvres.append(AuvManoeuvre(t0 + dt, t + dt, angle, True))

    def _append(self, x: float, y: float, psi: float, v: float) -> None:
        self._x.append(x)
        self._y.append(y)
        self._psi.append(psi)
        self._v.append(v)
        self._legs.append(self.leg)

    def _ensure(self, t_s: float) -> None:
        need = math.floor(t_s / self.dt + 1e-9) + 1
        while len(self._x) - 1 < need:
            self._step((len(self._x) - 1) * self.dt)

    # ------------------------------------------------------------- queries

    def position(self, t_s: float) -> tuple[float, float, float]:
        """(north, east, depth) in metres at ``t_s`` ≥ 0."""
        t_s = max(t_s, 0.0)
        self._ensure(t_s)
        f = t_s / self.dt
        k = min(int(f), len(self._x) - 2)
        a = f - k
        xs, ys = self._x, self._y
        return (xs[k] + a * (xs[k + 1] - xs[k]), ys[k] + a * (ys[k + 1] - ys[k]),
                self.params.depth_m)

    def turn_times(self) -> list[float]:
        """Sim times (s) at which the AUV started a new leg, so far (a leg switch
        is where a turn begins)."""
        legs = self._legs
        return [k * self.dt for k in range(1, len(legs)) if legs[k] != legs[k - 1]]

    def turn_angles(self) -> list[tuple[float, float]]:
        """(sim time s, signed course change rad, positive to starboard) of every
        leg switch so far: the same times as :meth:`turn_times`, with the angle
        between the planned legs (what the AUV turns through)."""
        return list(self._turns)

    def manoeuvres(self) -> list[AuvManoeuvre]:
        """Every course change so far, in time order: the leg switches of
        :meth:`turn_angles` and the continuous turns (arcs, circles, spirals);
        an arc still being flown ends where the integration has got to, with
        the angle turned so far."""
        out = list(self._manoeuvres)
        if self._arc is not None:
            t0, _r, angle, _g, turned = self._arc
            out.append(AuvManoeuvre(t0 + self.dt, (len(self._x) - 1) * self.dt,
                                    math.copysign(turned, angle), True))
        return out

    def truth(self, t_s: float) -> AuvTruth:
        """The full true state at ``t_s`` ≥ 0 (heading and speed of the step
        containing ``t_s``; the ground velocity is the step's chord velocity)."""
        t_s = max(t_s, 0.0)
        self._ensure(t_s)
        f = t_s / self.dt
        k = min(int(f), len(self._x) - 2)
        a = f - k
        xs, ys = self._x, self._y
        vx = (xs[k + 1] - xs[k]) / self.dt
        vy = (ys[k + 1] - ys[k]) / self.dt
        psi = self._psi[k + 1] if self._v[k + 1] > 0.0 else self._psi[k]
        return AuvTruth(t_s, xs[k] + a * (xs[k + 1] - xs[k]), ys[k] + a * (ys[k + 1] - ys[k]),
                        self.params.depth_m, psi, math.hypot(vx, vy), vx, vy,
                        self._legs[k + 1])
