"""Measurement-update algebra of the EKF and the gate bookkeeping its sensors share.

Heading and ROT are scalar updates; GPS position and velocity are 2-D updates
(2×2 inverse by hand) so that their gate is the joint χ²₂.  The update is
P − K·(PHᵀ)ᵀ.  Measurements that share a time of validity can be fused in one
joint update (:func:`spd_inverse` inverts its few rows in closed form).

Gates: NIS χ²₁ / χ²₂ at 99.9 % per measurement; a sensor rejected continuously
for ``reset_after_s`` re-initialises its part of the state (the caller does,
when :meth:`Gatekeeping.rejected` says so).
"""

from __future__ import annotations

import math

import numpy as np

from zarco_core.angles import wrap
from zarco_runtime.navigation.ekf.layout import (
    IPSI,
    OK_KEYS,
    REJECTED_KEYS,
    RESET_KEYS,
    Counters,
    FilterState,
)
from zarco_runtime.navigation.ekf.noise import SensorNoise
from zarco_runtime.navigation.ekf_config import EkfSettings


def update1(c: FilterState, h: np.ndarray, nu: float, r: float, gate: float) -> bool:
    """Scalar update with row ``h``, innovation ``nu``, variance ``r``; False if gated."""
    P = c.P
    pht = P.dot(h)
    s = h.dot(pht).item() + r
    if nu * nu > gate * s:
        return False
    k = pht * (1.0 / s)
    x = c.x
    x[:] = [a + b for a, b in zip(x, (k * nu).tolist(), strict=True)]
    x[IPSI] = wrap(x[IPSI])
    P -= np.multiply.outer(k, pht)
    return True


def update2(c: FilterState, H: np.ndarray, nu1: float, nu2: float, r1: float, r2: float,
            gate: float) -> bool:
    """2-D update (rows ``H``, 2×NX), independent noises ``r1``, ``r2``; False if gated."""
    P = c.P
    pht = P.dot(H.T)
    (a, b), (_b, d) = H.dot(pht).tolist()
    a += r1
    d += r2
    det = a * d - b * b
    if det <= 0.0:
        return False
    ia, ib, id_ = d / det, -b / det, a / det
    nis = nu1 * (ia * nu1 + ib * nu2) + nu2 * (ib * nu1 + id_ * nu2)
    if nis > gate:
        return False
    k = pht.dot(np.array(((ia, ib), (ib, id_))))
    x = c.x
    x[:] = [a_ + b_ for a_, b_ in
            zip(x, k.dot(np.array((nu1, nu2))).tolist(), strict=True)]
    x[IPSI] = wrap(x[IPSI])
    P -= k.dot(pht.T)
    return True


def reset_block(c: FilterState, idx: tuple[int, ...], var: tuple[float, ...]) -> None:
    """Decorrelate states ``idx`` from the rest and give them variances ``var``."""
    P = c.P
    for i, v in zip(idx, var, strict=True):
        P[i, :] = 0.0
        P[:, i] = 0.0
        P[i, i] = v


class Gatekeeping:
    """What every sensor's fusion shares: the settings, the noise, the counters, and
    the accepted / rejected bookkeeping of the gates."""

    def __init__(self, cfg: EkfSettings, noise: SensorNoise, counters: Counters) -> None:
        self.cfg = cfg
        self.noise = noise
        self.counters = counters
        self.gates = noise.gates

    def rejected(self, c: FilterState, kind: int, tov: float) -> bool:
        """Note a gate rejection; True when the sensor has now been rejected for
        ``reset_after_s`` (the caller re-initialises)."""
        self.counters.count(REJECTED_KEYS[kind])
        start = c.rej[kind]
        if math.isnan(start):
            c.rej[kind] = tov
            return False
        if tov - start >= self.cfg.reset_after_s:
            c.rej[kind] = math.nan
            self.counters.count(RESET_KEYS[kind])
            return True
        return False

    def accepted(self, c: FilterState, kind: int) -> None:
        c.rej[kind] = math.nan
        self.counters.count(OK_KEYS[kind])


def _inv2(p: float, q: float, r: float) -> tuple[float, float, float]:
    """Inverse (a, b, d) of the symmetric 2×2 matrix [[p, q], [q, r]]."""
    det = p * r - q * q
    return r / det, -q / det, p / det


def spd_inverse(a: list[list[float]]) -> list[list[float]]:
    """Inverse of a small symmetric positive-definite matrix (nested lists): 1–4 rows in
    closed form by 2×2 blocks (more: numpy): a joint update's few rows cost less so than
    any numpy.linalg call.  S = [[A, B], [Bᵀ, D]], M = A⁻¹ B, W = (D − Bᵀ M)⁻¹:
    S⁻¹ = [[A⁻¹ + M W Mᵀ, −M W], [−W Mᵀ, W]]."""
    n = len(a)
    if n == 1:
        return [[1.0 / a[0][0]]]
    if n > 4:  # more measurements of one instant than the closed forms cover
        inv: list[list[float]] = np.linalg.inv(np.array(a)).tolist()
        return inv
    r0, r1 = a[0], a[1]
    ia, ib, id_ = _inv2(r0[0], r0[1], r1[1])
    if n == 2:
        return [[ia, ib], [ib, id_]]
    b0, b1 = r0[2], r1[2]  # first column of B
    m00, m10 = ia * b0 + ib * b1, ib * b0 + id_ * b1  # first column of M
    if n == 3:
        w = 1.0 / (a[2][2] - (b0 * m00 + b1 * m10))
        x0, x1 = m00 * w, m10 * w
        return [[ia + x0 * m00, ib + x0 * m10, -x0],
                [ib + x1 * m00, id_ + x1 * m10, -x1],
                [-x0, -x1, w]]
    c0, c1 = r0[3], r1[3]  # second column of B
    m01, m11 = ia * c0 + ib * c1, ib * c0 + id_ * c1
    wa, wb, wd = _inv2(a[2][2] - (b0 * m00 + b1 * m10), a[2][3] - (b0 * m01 + b1 * m11),
                       a[3][3] - (c0 * m01 + c1 * m11))
    x00, x01 = m00 * wa + m01 * wb, m00 * wb + m01 * wd  # M W
    x10, x11 = m10 * wa + m11 * wb, m10 * wb + m11 * wd
    e00 = ia + x00 * m00 + x01 * m01
    e01 = ib + x00 * m10 + x01 * m11
    e11 = id_ + x10 * m10 + x11 * m11
    return [[e00, e01, -x00, -x01], [e01, e11, -x10, -x11],
            [-x00, -x10, wa, wb], [-x01, -x11, wb, wd]]
