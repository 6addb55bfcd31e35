"""LQR design of the line-tracking steering gains, scheduled on speed.

The paper (III.B) notes that the linearised steering system is controllable
for u0 ≠ 0 and that gains k_y, k_l, k_ψ, k_r can be chosen to stabilise it;
we choose them by discrete LQR on that model at each speed of a grid, with
the thruster lag added, and interpolate at run time.

State z = [d, l, e, r, v, Nt, w] (cross-track error m, its integral m s,
heading error rad, yaw rate rad/s, sway m/s, applied yaw moment N m, sway
force of gusts and chop N), input the commanded yaw moment N_cmd (N m):

    d' = U e + v                 l' = d              e' = r
    (m − Y_v') v' = Y_v v − m U r + w                  (from m(v' + u r) = Y)
    (Iz − N_r') r' = N_r r + Nt
    Nt' = (N_cmd − Nt) / τ_thr
    w' = −w / τ_w                                      (a Gauss–Markov force)

w cannot be controlled, only countered: its gain is the feedforward that
turns the bow against a gust before the gust has moved the boat, which is
what holds the line at low speed through the water (at 0.15 m/s a 5 N gust
needs some 20° of heading).  The observer estimates w
(:class:`~zarco_runtime.control.water_observer.WaterObserver`).

Discretised with a zero-order hold at the control period; the discrete
algebraic Riccati equation is solved by the structured doubling algorithm
(quadratic convergence, ~20 iterations of 7×7 matrices).

A schedule (eleven designs) takes some 20 ms to solve, too long for a
control tick, so schedules are cached per configuration (the vessel's
steering model, the thruster lag, the control period and the LQR weights):
:func:`design_schedule` solves one (or returns it from the cache) and
:func:`cached_schedule` only looks; the control task designs at start and,
after a weight changes, off the tick.
"""

from __future__ import annotations

import bisect
import math
import threading
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np

from zarco_core.vessel import VesselModel
from zarco_runtime.control.settings import Control

STATE = ("d", "l", "e", "r", "v", "nt", "w")
#: correlation time of the sway gust force (s) the design assumes
GUST_TAU_S = 2.0


def expm(a: np.ndarray) -> np.ndarray:
    """Matrix exponential by scaling and squaring of a Taylor series (small, well-scaled A)."""
    norm = float(np.linalg.norm(a, ord=np.inf))
    s = max(0, math.ceil(math.log2(norm)) + 1) if norm > 0.5 else 0
    x = a / (2.0**s)
    term = np.eye(a.shape[0])
    out = np.eye(a.shape[0])
    for k in range(1, 20):
        term = term @ x / k
        out = out + term
    for _ in range(s):
        out = out @ out
    return out


def c2d(a: np.ndarray, b: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Zero-order-hold discretisation."""
    n, m = b.shape
    blk = np.zeros((n + m, n + m))
    blk[:n, :n] = a
    blk[:n, n:] = b
    e = expm(blk * dt)
    return e[:n, :n], e[:n, n:]


def dare(a: np.ndarray, b: np.ndarray, q: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Stabilising solution of the discrete algebraic Riccati equation (SDA)."""
    n = a.shape[0]
    ak = a.copy()
    gk = b @ np.linalg.solve(r, b.T)
    hk = q.copy()
    eye = np.eye(n)
    for _ in range(100):
        w = eye + gk @ hk
        w_inv_a = np.linalg.solve(w, ak)
        w_inv_g = np.linalg.solve(w, gk)
        a_next = ak @ w_inv_a
        g_next = gk + ak @ w_inv_g @ ak.T
        h_next = hk + ak.T @ hk @ w_inv_a
        if float(np.linalg.norm(h_next - hk)) <= 1e-10 * max(1.0, float(np.linalg.norm(h_next))):
            out: np.ndarray = h_next
            return out
        ak, gk, hk = a_next, g_next, h_next
    raise ArithmeticError("DARE did not converge")


def steering_model(u_mps: float, vm: VesselModel, lag_s: float,
                   gust_tau_s: float = GUST_TAU_S) -> tuple[np.ndarray, np.ndarray]:
    """Continuous-time (A, B) of the linearised steering model at speed ``u_mps``."""
    mv = vm.m_kg - vm.y_vdot
    jr = vm.iz_kgm2 - vm.n_rdot
    a = np.zeros((7, 7))
    a[0, 2] = u_mps
    a[0, 4] = 1.0
    a[1, 0] = 1.0
    a[2, 3] = 1.0
    a[3, 3] = vm.n_r / jr
    a[3, 5] = 1.0 / jr
    a[4, 3] = -vm.m_kg * u_mps / mv
    a[4, 4] = vm.y_v / mv
    a[4, 6] = 1.0 / mv
    a[5, 5] = -1.0 / lag_s
    a[6, 6] = -1.0 / gust_tau_s
    b = np.zeros((7, 1))
    b[5, 0] = 1.0 / lag_s
    return a, b


@dataclass(frozen=True, slots=True)
class SteeringGains:
    """State-feedback gains N_cmd = −K z for z = [d, l, e, r, v, Nt, w]."""

    u_mps: float
    k: tuple[float, float, float, float, float, float, float]


def design(u_mps: float, vm: VesselModel, ctl: Control, lag_s: float, dt: float) -> SteeringGains:
    """LQR gains at speed ``u_mps`` (Bryson's rule on the configured scales)."""
    a, b = steering_model(u_mps, vm, lag_s)
    ad, bd = c2d(a, b, dt)
    scales = [ctl.lqr_d_m, ctl.lqr_int_ms, math.radians(ctl.lqr_psi_deg),
              math.radians(ctl.lqr_r_dps), ctl.lqr_v_mps, 1e3, 1e6]
    q = np.diag([1.0 / s**2 for s in scales])
    r = np.array([[1.0 / ctl.lqr_n_nm**2]])
    p = dare(ad, bd, q * dt, r * dt)
    k = np.linalg.solve(r * dt + bd.T @ p @ bd, bd.T @ p @ ad)[0]
    return SteeringGains(u_mps, tuple(float(x) for x in k))  # type: ignore[arg-type]


#: the speeds (m/s) of the schedule's designs
SPEEDS = (0.2, 0.3, 0.4, 0.5, 0.6, 0.8, 1.0, 1.2, 1.4, 1.6, 1.8)
#: schedules kept (a few configurations: the one running and those tried)
CACHE_SIZE = 16


class GainSchedule:
    """LQR gains on a speed grid, linearly interpolated at run time."""

    def __init__(self, vm: VesselModel, ctl: Control, lag_s: float, dt: float,
                 speeds: tuple[float, ...] = SPEEDS) -> None:
        self.speeds = speeds
        self.gains = [design(u, vm, ctl, lag_s, dt) for u in speeds]

    @staticmethod
    def key(vm: VesselModel, ctl: Control, lag_s: float, dt: float,
            speeds: tuple[float, ...] = SPEEDS) -> tuple[float, ...]:
        """Everything a schedule depends on (two configurations with the same key
        have the same gains)."""
        return (vm.m_kg, vm.y_vdot, vm.iz_kgm2, vm.n_rdot, vm.n_r, vm.y_v, lag_s, dt,
                ctl.lqr_d_m, ctl.lqr_int_ms, ctl.lqr_psi_deg, ctl.lqr_r_dps, ctl.lqr_v_mps,
                ctl.lqr_n_nm, *speeds)

    def at(self, u_mps: float) -> tuple[float, ...]:
        """Gains K at speed ``u_mps`` (clamped to the grid)."""
        sp = self.speeds
        if u_mps <= sp[0]:
            return self.gains[0].k
        if u_mps >= sp[-1]:
            return self.gains[-1].k
        i = bisect.bisect_right(sp, u_mps)
        w = (u_mps - sp[i - 1]) / (sp[i] - sp[i - 1])
        k0, k1 = self.gains[i - 1].k, self.gains[i].k
        return tuple([a + w * (b - a) for a, b in zip(k0, k1, strict=True)])


_cache: OrderedDict[tuple[float, ...], GainSchedule] = OrderedDict()
_cache_lock = threading.Lock()  # designs may finish on a worker thread


def cached_schedule(vm: VesselModel, ctl: Control, lag_s: float,
                    dt: float) -> GainSchedule | None:
    """The schedule of this configuration if it was designed already (no solving)."""
    key = GainSchedule.key(vm, ctl, lag_s, dt)
    with _cache_lock:
        s = _cache.get(key)
        if s is not None:
            _cache.move_to_end(key)
        return s


def design_schedule(vm: VesselModel, ctl: Control, lag_s: float,
                    dt: float) -> GainSchedule:
    """The schedule of this configuration: from the cache, or solved now (~20 ms)
    and cached."""
    s = cached_schedule(vm, ctl, lag_s, dt)
    if s is not None:
        return s
    key = GainSchedule.key(vm, ctl, lag_s, dt)
    s = GainSchedule(vm, ctl, lag_s, dt)
    with _cache_lock:
        _cache[key] = s
        while len(_cache) > CACHE_SIZE:
            _cache.popitem(last=False)
    return s
