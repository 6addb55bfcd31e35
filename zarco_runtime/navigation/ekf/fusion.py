"""One time of validity's measurements into the EKF: a prediction, then the updates.

Measurements that share a time of validity (an epoch's GGA and RMC, a compass
epoch's HDG and ROT) share one prediction; their plain measurements (GPS
velocity, heading, ROT: no initialisation or fault handling due) are fused in
one joint update, each block within its own gate; the rest, and any block
beyond its gate, one by one afterwards.  The order does not depend on their
arrival, so a replay gives what in-order arrival gives.
"""

from __future__ import annotations

import numpy as np

from zarco_core.angles import wrap
from zarco_runtime.navigation.ekf.gps import GpsFusion
from zarco_runtime.navigation.ekf.heading import HeadingFusion
from zarco_runtime.navigation.ekf.layout import (
    IBC,
    IBG,
    IPSI,
    IR,
    K_COMPASS,
    K_POS,
    K_ROT,
    K_SOG,
    K_TRUE_HDG,
    K_VEL,
    FilterState,
    Measurement,
    kind_of,
)
from zarco_runtime.navigation.ekf.model import Prediction
from zarco_runtime.navigation.ekf.updates import spd_inverse


class Fusion:
    """Applies groups of measurements of one time of validity to a :class:`FilterState`."""

    def __init__(self, prediction: Prediction, gps: GpsFusion, heading: HeadingFusion) -> None:
        self.prediction = prediction
        self.gps = gps
        self.heading = heading

    def apply(self, c: FilterState, group: list[Measurement]) -> None:
        """Fuse one time of validity's measurements, in an order that does not
        depend on their arrival (a replay gives what in-order arrival gives)."""
        self.prediction.predict(c, group[0].tov)
        if len(group) > 1:
            group.sort(key=kind_of)
            if self._fuse_joint(c, group):
                return
        for m in group:
            self._fuse(c, m)

    def _fuse(self, c: FilterState, m: Measurement) -> None:
        kind = m.kind
        if kind == K_POS:
            self.gps.fuse_pos(c, m)
        elif kind in (K_VEL, K_SOG):
            self.gps.fuse_vel(c, m)
        elif kind == K_ROT:
            self.heading.fuse_rot(c, m)
        else:
            self.heading.fuse_heading(c, m)

    def _fuse_joint(self, c: FilterState, group: list[Measurement]) -> bool:
        """One joint update of a group's plain measurements (GPS velocity, heading,
        ROT: no initialisation or fault handling due), each block within its own
        gate; the rest (and any block beyond its gate) is fused alone, afterwards.
        False: nothing joint to do (the caller fuses the group one by one)."""
        noise = self.heading.noise
        gates = noise.gates
        rows: list[np.ndarray] = []
        nus: list[float] = []
        rs: list[float] = []
        blocks: list[tuple[Measurement, int]] = []  # measurement, its first row
        rest: list[Measurement] = []
        x = c.x
        for m in group:
            k = m.kind
            if k == K_VEL and c.hdg_init and c.vel_init:
                vn, ve, H = self.gps.ground_velocity(x)
                blocks.append((m, len(nus)))
                rows += (H[0], H[1])
                nus += (m.z1 - vn, m.z2 - ve)
                rs += (m.r1, m.r2)
            elif k in (K_COMPASS, K_TRUE_HDG) and c.hdg_init and not c.hdg_course:
                compass = k == K_COMPASS
                blocks.append((m, len(nus)))
                rows.append(noise.h_compass if compass else noise.h_true)
                nus.append(wrap(m.z1 - x[IPSI] - (x[IBC] if compass else 0.0)))
                rs.append(m.r1)
            elif k == K_ROT:
                blocks.append((m, len(nus)))
                rows.append(noise.h_rot)
                nus.append(m.z1 - (x[IR] + x[IBG]))
                rs.append(m.r1)
            else:
                rest.append(m)
        n = len(nus)
        if n < 2:
            return False
        H = np.array(rows)
        P = c.P
        pht = P.dot(H.T)
        S = H.dot(pht)
        S.flat[:: n + 1] += rs
        sl = S.tolist()
        keep: list[int] = []
        for m, i in blocks:
            if m.kind == K_VEL:
                a, b, d = sl[i][i], sl[i][i + 1], sl[i + 1][i + 1]
                det = a * d - b * b
                n1, n2 = nus[i], nus[i + 1]
                ok = det > 0.0 and (n1 * (d * n1 - b * n2) + n2 * (a * n2 - b * n1)) <= (
                    gates[K_VEL] * det)
                if ok:
                    keep += (i, i + 1)
            else:
                ok = nus[i] * nus[i] <= gates[m.kind] * sl[i][i]
                if ok:
                    keep.append(i)
            if not ok:
                rest.append(m)
        if keep:
            if len(keep) < n:
                sl = [[sl[i][j] for j in keep] for i in keep]
                pht = pht[:, keep]
                nus = [nus[i] for i in keep]
            K = pht.dot(np.array(spd_inverse(sl)))
            x[:] = [a_ + b_ for a_, b_ in zip(x, K.dot(np.array(nus)).tolist(), strict=True)]
            x[IPSI] = wrap(x[IPSI])
            P -= K.dot(pht.T)
            for m, _i in blocks:
                if m not in rest:
                    self._joint_accepted(c, m)
        for m in rest:
            self._fuse(c, m)
        return True

    def _joint_accepted(self, c: FilterState, m: Measurement) -> None:
        k = m.kind
        self.heading.accepted(c, k)
        if k == K_VEL:
            c.t_vel = m.tov
        elif k == K_ROT:
            c.t_rot = m.tov
        else:
            c.t_hdg = m.tov
