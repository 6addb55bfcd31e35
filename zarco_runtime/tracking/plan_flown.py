"""The path an AUV flies round a corner no arc can round: its guidance, simulated.

An arc tangent to both legs (:class:`~.plan_geometry.Arc`) is what an AUV
flies round a corner when it has room: the corner turns less than a
reversal and the legs either side are longer than the arc's tangent
length.  Where it has not — a reversal (a corner of more than
``MAX_ROUND_DEG``), or the short leg of a tight lawnmower, closer to the
next line than the AUV's turning circle is wide — the AUV does not fly the
plan's corner: it swings a turning circle of its own radius out past the
next line (metres, up to twice its radius) and its line-of-sight guidance
brings it back onto that line over tens of metres.  An arc clamped to fit
is then metres off the AUV for tens of seconds, which the boat would follow.

Here that stretch is the AUV's waypoint guidance simulated over the plan,
from where it leaves the first corner's leg until it is back on a leg,
metres of path for seconds (the path does not depend on the AUV's speed but
through its turning radius):

* each leg is flown by line of sight, ψ_d = ψ_leg − atan(d/Δ), d its offset
  from the leg (m, > 0 to starboard), Δ = ``LOOKAHEAD_M``;
* the course turns towards ψ_d at dψ/dℓ = (ψ_d − ψ)/``HEADING_M`` (rad per
  metre flown), at most 1/R (its turning radius R);
* the next leg starts ``R·tan(min(|θ|, 90°)/2)`` before a corner turning θ
  (the turn anticipated so that a finite-rate turn joins the next line);
* it is back on a leg once within ``ON_LINE_M`` of it and ``ON_LINE_DEG`` of
  its course.

The path coordinate over the stretch is the sharp plan's, from where the
AUV leaves its leg to where it is back on one, mapped onto the simulated
path linearly in metres flown (as an arc's stretch is in angle).
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Sequence
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

#: the AUV's line-of-sight look-ahead (m): how far ahead on its leg it aims
LOOKAHEAD_M = 10.0
#: its heading's response, as metres flown per radian of heading error per
#: radian turned (a heading time constant of about a second at about 1 m/s)
HEADING_M = 1.0
#: the simulation's step (m flown)
STEP_M = 0.25
#: back on a leg: within this of its line (m) and this of its course (deg)
ON_LINE_M = 0.1
ON_LINE_DEG = 1.0
#: a stretch is flown for at most this far (m) before it is taken as back on a leg
MAX_FLOWN_M = 2000.0


class Leg(Protocol):
    """A leg as the simulation flies it (:class:`~.plan_geometry.PlanLeg`):
    its start (NED, m), unit direction, length (m) and the sharp plan's path
    coordinate of its start (m)."""

    @property
    def n0(self) -> float: ...
    @property
    def e0(self) -> float: ...
    @property
    def ux(self) -> float: ...
    @property
    def uy(self) -> float: ...
    @property
    def length_m(self) -> float: ...
    @property
    def s0_m(self) -> float: ...


class Flown:
    """The stretch of the plan between path coordinates ``lo`` and ``hi`` (m)
    as the AUV flies it: a polyline of the simulated positions (NED, m) and
    courses (rad), ``ell`` the metres flown to each point."""

    __slots__ = ("_dx", "_dy", "_ell", "_ell_l", "_len2", "_psi_l", "_x", "_x_l",
                 "_y", "_y_l", "hi", "length_m", "lo", "stretch")

    def __init__(self, lo: float, hi: float, xs: list[float], ys: list[float],
                 psis: list[float]) -> None:
        self._x: NDArray[np.float64] = np.asarray(xs, dtype=float)
        self._y: NDArray[np.float64] = np.asarray(ys, dtype=float)
        psi = np.unwrap(np.asarray(psis, dtype=float))
        # the segments' components and squared lengths (zero-length ones as 1)
        self._dx = np.diff(self._x)
        self._dy = np.diff(self._y)
        steps = np.hypot(self._dx, self._dy)
        self._ell: NDArray[np.float64] = np.concatenate(([0.0], np.cumsum(steps)))
        len2 = self._dx * self._dx + self._dy * self._dy
        self._len2 = np.where(len2 > 0.0, len2, 1.0)
        # the same as lists, for one point at a time (a numpy call costs more)
        self._x_l: list[float] = self._x.tolist()
        self._y_l: list[float] = self._y.tolist()
        self._psi_l: list[float] = psi.tolist()
        self._ell_l: list[float] = self._ell.tolist()
        self.lo = lo
        self.hi = hi
        self.length_m = float(self._ell[-1])
        #: path coordinate per metre flown
        self.stretch = (hi - lo) / self.length_m if self.length_m > 0.0 else 1.0

    def at(self, s: float, cross: float) -> tuple[float, float, float]:
        """(x, y, course) at path coordinate ``s`` in the stretch, ``cross``
        metres to starboard."""
        ell = min(max((s - self.lo) / self.stretch, 0.0), self.length_m)
        e = self._ell_l
        i = self._segment(ell)
        f = (ell - e[i]) / (e[i + 1] - e[i]) if e[i + 1] > e[i] else 0.0
        xs, ys, ps = self._x_l, self._y_l, self._psi_l
        x = xs[i] + f * (xs[i + 1] - xs[i])
        y = ys[i] + f * (ys[i + 1] - ys[i])
        psi = ps[i] + f * (ps[i + 1] - ps[i])
        return x - cross * math.sin(psi), y + cross * math.cos(psi), math.remainder(psi, math.tau)

    def _segment(self, ell: float) -> int:
        """The polyline's segment holding ``ell`` metres flown (clamped to its ends)."""
        return min(max(bisect.bisect_right(self._ell_l, ell) - 1, 0), len(self._ell_l) - 2)

    def nearest(self, x: float, y: float, s_lo: float = -math.inf, s_hi: float = math.inf
                ) -> tuple[float, float, float]:
        """(distance, s, cross) of the point of the stretch between path
        coordinates ``s_lo`` and ``s_hi`` nearest (x, y), cross > 0 to
        starboard of its course there: the foot of the perpendicular along the
        interpolated course (as :meth:`at` offsets), so that ``nearest`` undoes
        ``at``."""
        e_lo = max((s_lo - self.lo) / self.stretch, 0.0)
        e_hi = min((s_hi - self.lo) / self.stretch, self.length_m)
        if e_lo > e_hi:
            return math.inf, self.lo, 0.0
        ell = self._ell
        i0 = max(int(np.searchsorted(ell, e_lo, side="right")) - 1, 0)
        i1 = min(int(np.searchsorted(ell, e_hi, side="left")), len(ell) - 1)
        if i1 <= i0:
            e = e_lo
        else:
            xs, ys = self._x[i0:i1], self._y[i0:i1]
            dx, dy = self._dx[i0:i1], self._dy[i0:i1]
            f = np.clip(((x - xs) * dx + (y - ys) * dy) / self._len2[i0:i1], 0.0, 1.0)
            d2 = (x - xs - f * dx) ** 2 + (y - ys - f * dy) ** 2
            i = int(np.argmin(d2))
            e = float(ell[i0 + i] + f[i] * (ell[i0 + i + 1] - ell[i0 + i]))
        e = min(max(e, e_lo), e_hi)
        # the foot along the interpolated course (as ``at`` offsets): Newton's
        # steps on the offset along the course, g(ℓ) = (P − p(ℓ))·t(ℓ), whose
        # slope is −(1 − κ c) at curvature κ and offset c
        e_l = self._ell_l
        for _ in range(4):
            px, py, psi = self.at(self.lo + e * self.stretch, 0.0)
            cs, sn = math.cos(psi), math.sin(psi)
            g = (x - px) * cs + (y - py) * sn
            c = -(x - px) * sn + (y - py) * cs
            j = self._segment(e)
            kappa = ((self._psi_l[j + 1] - self._psi_l[j]) / (e_l[j + 1] - e_l[j])
                     if e_l[j + 1] > e_l[j] else 0.0)
            slope = 1.0 - kappa * c
            step = g / slope if slope > 0.1 else g
            e = min(max(e + step, e_lo), e_hi)
            if abs(step) < 1e-9:
                break
        px, py, psi = self.at(self.lo + e * self.stretch, 0.0)
        cross = -(x - px) * math.sin(psi) + (y - py) * math.cos(psi)
        return math.hypot(x - px, y - py), self.lo + e * self.stretch, cross


def switch_m(radius: float, turn_rad: float) -> float:
    """How far before a corner turning ``turn_rad`` the AUV starts the next leg (m)."""
    return radius * math.tan(min(abs(turn_rad), math.pi / 2.0) / 2.0)


def fly(legs: Sequence[Leg], k: int, radius: float) -> tuple[Flown, int]:
    """The AUV of turning radius ``radius`` (m) flying the corner at the end
    of leg ``k`` (module docstring), from where it starts the next leg to where
    it is back on one; and the leg it is back on (the corners before it are
    flown in the stretch)."""
    n = len(legs)

    def turn(j: int) -> float:
        if j + 1 >= n:
            return 0.0
        a, b = legs[j], legs[j + 1]
        return math.remainder(math.atan2(b.uy, b.ux) - math.atan2(a.uy, a.ux), math.tau)

    lg = legs[k]
    along0 = max(lg.length_m - switch_m(radius, turn(k)), 0.0)
    x, y = lg.n0 + along0 * lg.ux, lg.e0 + along0 * lg.uy
    psi = math.atan2(lg.uy, lg.ux)
    lo = lg.s0_m + along0
    xs, ys, psis = [x], [y], [psi]
    leg = k + 1
    max_rate = 1.0 / radius
    on_dev = math.radians(ON_LINE_DEG)
    steps = int(MAX_FLOWN_M / STEP_M)
    along = 0.0
    for _ in range(steps):
        cur = legs[leg]
        along = (x - cur.n0) * cur.ux + (y - cur.e0) * cur.uy
        d = -(x - cur.n0) * cur.uy + (y - cur.e0) * cur.ux
        course = math.atan2(cur.uy, cur.ux)
        if leg + 1 < n and cur.length_m - along <= switch_m(radius, turn(leg)):
            leg += 1
            continue
        if (len(xs) > 1 and abs(d) <= ON_LINE_M
                and abs(math.remainder(psi - course, math.tau)) <= on_dev):
            break
        err = math.remainder(course - math.atan(d / LOOKAHEAD_M) - psi, math.tau)
        rate = max(-max_rate, min(max_rate, err / HEADING_M))
        mid = psi + 0.5 * rate * STEP_M
        x += STEP_M * math.cos(mid)
        y += STEP_M * math.sin(mid)
        psi += rate * STEP_M
        xs.append(x)
        ys.append(y)
        psis.append(psi)
    cur = legs[leg]
    along = (x - cur.n0) * cur.ux + (y - cur.e0) * cur.uy
    hi = max(cur.s0_m + along, lo + 1e-6)
    return Flown(lo, hi, xs, ys, psis), leg
