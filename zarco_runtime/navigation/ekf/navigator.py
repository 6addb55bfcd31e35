"""The navigation EKF as a navigator: messages in, NavState and health out.

Measurements, each at its time of validity (arrival − configured latency):
GPS position (σ from GST when fresh, else from the fix type), GPS velocity
(SOG/COG as N/E components; SOG alone from a VTG without course), true heading
(HDT/THS from a dual-antenna source, unbiased), compass heading (magnetic +
variation, biased), ROT (biased), and the thruster commands, the prediction's
input.  One measurement per GPS epoch: GGA's position (RMC's when no GGA
comes) and RMC's velocity (VTG's when no RMC comes).

NavState reports the ground velocity ``R(ψ)·(u, v) + c`` as (vn, ve), and as
(u, v) rotated into the body frame (ground relative, as the first estimator
did), with the covariance of (x, y, vn, ve, ψ) obtained through that Jacobian.
``state(t)`` at the filter's own time does not predict.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from zarco_core.angles import wrap
from zarco_core.geodesy import LocalFrame
from zarco_core.localgeo import FastLocalFrame
from zarco_core.messages import (
    FixQuality,
    GpsErrorStats,
    GpsFix,
    GpsVelocity,
    Heading,
    NavState,
    RateOfTurn,
    ThrusterCommand,
)
from zarco_core.thruster_map import ThrusterMap
from zarco_core.vessel import VesselModel
from zarco_runtime.navigation.ekf.fusion import Fusion
from zarco_runtime.navigation.ekf.gps import GpsFusion
from zarco_runtime.navigation.ekf.heading import HeadingFusion
from zarco_runtime.navigation.ekf.history import History
from zarco_runtime.navigation.ekf.layout import (
    ICE,
    ICN,
    IPSI,
    IR,
    IU,
    IV,
    IX,
    IY,
    K_COMPASS,
    K_POS,
    K_ROT,
    K_SOG,
    K_TRUE_HDG,
    K_VEL,
    NX,
    SAME_TIME_S,
    STATE_NAMES,
    Counters,
    FilterState,
    Measurement,
    initial_state,
    tov,
)
from zarco_runtime.navigation.ekf.model import Prediction
from zarco_runtime.navigation.ekf.monitors import HeadingMonitors, Validity
from zarco_runtime.navigation.ekf.noise import SensorNoise
from zarco_runtime.navigation.ekf_config import EkfSettings

#: sentences that carry a true heading measured by a dual-antenna receiver
TRUE_HEADING_SENTENCES = frozenset({"HDT", "THS"})
#: a GpsVelocity from VTG (or a GpsFix from RMC) is ignored while RMC velocities
#: (GGA fixes) arrived within this (s): one measurement per epoch
PREFERRED_WITHIN_S = 2.0

# entries of the output Jacobian (x, y, vn, ve, ψ) filled per state() call
_J_IDX = np.ravel_multi_index(np.array([
    (2, IU), (2, IV), (2, IPSI), (3, IU), (3, IV), (3, IPSI)]).T, (5, NX))


@dataclass(slots=True)
class EkfStatus:
    """Health of the estimator at ``t`` (s), for the supervisor and telemetry.

    ``gps_age_s``: time since the last fused GPS position (inf: never);
    ``pos_sigma_m`` / ``heading_sigma_deg``: 1σ of the estimate (worse position
    axis); ``compass_frozen`` / ``compass_jumping``: a compass is being
    rejected by its fault detector (sources in ``compass_faults``);
    ``counters``: ``<kind>_ok`` / ``<kind>_rejected`` per measurement kind
    (pos, vel, sog, compass, true_heading, rot), ``late_dropped``, ``replays``,
    ``fix_changes``, ``resets_<kind>``, ``compass_frozen`` / ``compass_jumping``
    (events), ``compass_rejected_fault``, ``vel_manoeuvre``, ``pos_manoeuvre``,
    ``heading_from_course``, ``commands``.  ``state`` is the full mean (see
    :data:`~zarco_runtime.navigation.ekf.layout.STATE_NAMES`), ``sigma`` its 1σ.
    ``thrust_model``: the thruster commands are a prediction input at ``t``.
    """

    t: float
    pos_valid: bool
    heading_valid: bool
    gps_age_s: float
    pos_sigma_m: float
    heading_sigma_deg: float
    compass_frozen: bool
    compass_jumping: bool
    compass_faults: tuple[str, ...]
    fix: FixQuality
    counters: dict[str, int]
    state: dict[str, float]
    sigma: dict[str, float]
    #: what the published position still has to glide after a fix upgrade (m)
    glide_m: float = 0.0
    thrust_model: bool = False


class EkfNavigator:
    """GPS + GST + true heading + compass + gyro (+ thruster commands) → NavState,
    by an EKF in local NED.

    A drop-in replacement for :class:`~zarco_runtime.navigation.simple.SimpleNavigator`
    (same ``on_fix``, ``on_velocity``, ``on_heading``, ``on_rate``, ``has_gyro``,
    ``state``), plus ``on_gst``, ``on_command`` and :meth:`status`.

    ``frame`` is the local NED frame (its origin is used through the scalar
    :class:`~zarco_core.localgeo.FastLocalFrame`);
    ``variation_deg`` (east positive) is added to headings that arrive magnetic
    (``Heading.true`` false), as :class:`SimpleNavigator` does.  The thrust
    model needs :meth:`set_vessel` (the navigation task does it from the
    runtime's ``[vessel]`` and ``[thrusters]``).
    """

    def __init__(self, cfg: EkfSettings, frame: LocalFrame,
                 variation_deg: float | None = None) -> None:
        self.cfg = cfg
        self.frame = frame
        self.geo = FastLocalFrame(frame.lat0, frame.lon0, frame.h0)
        self.variation_deg = variation_deg
        self.min_fix = FixQuality.from_label(cfg.min_fix)
        self.noise = SensorNoise(cfg)
        self._true_sources = frozenset(cfg.true_heading_sources)
        self._J = np.zeros((5, NX))
        self._J[0, IX] = self._J[1, IY] = self._J[4, IPSI] = 1.0
        self._J[2, ICN] = self._J[3, ICE] = 1.0
        self._validity = Validity(cfg)
        self._prediction = Prediction(cfg, self.noise)
        self.reset()

    def set_vessel(self, vessel: VesselModel, port: ThrusterMap, stbd: ThrusterMap) -> None:
        """The vessel model and the thrusters' maps f (command → N) that turn thruster
        commands into the prediction's input (see
        :mod:`~zarco_runtime.navigation.ekf.model`).  Without it, or with
        ``thrust_model`` off, commands are ignored."""
        self._prediction.set_vessel(vessel, port, stbd)

    # ------------------------------------------------------------ set-up
    def reset(self) -> None:
        """Forget everything (state, history, detectors, counters)."""
        cfg = self.cfg
        c = initial_state(cfg)
        self._counters = counters = Counters()
        self._prediction.reset()
        noise = self.noise
        self._gps = GpsFusion(cfg, noise, counters, self._prediction)
        fusion = Fusion(self._prediction, self._gps, HeadingFusion(cfg, noise, counters))
        self._history = History(c, fusion.apply, counters, cfg.history_s)
        #: fuse a measurement at its time of validity (the history's entry point)
        self._process = self._history.process
        self._monitors = HeadingMonitors(cfg, counters)
        self.fix = FixQuality.NONE  # last fix quality received (any), for NavState
        self.lat = math.nan
        self.lon = math.nan
        self._fix_key: tuple[str, float] | None = None
        self._t_gga = -math.inf
        self._t_rmc_vel = -math.inf
        self._gst: tuple[float, float, float, FixQuality] | None = None  # t, σn, σe, fix
        self._t_rot_rx = -math.inf

    @property
    def counters(self) -> dict[str, int]:
        """Event counters (see :class:`EkfStatus`), with every measurement received fused."""
        self._history.flush()
        return self._counters.counts

    def _count(self, key: str) -> None:
        self._counters.count(key)

    # ------------------------------------------------------ message input
    def handler(self, m: object) -> Callable[[Any], object] | None:
        """The ``on_*`` method that takes message ``m`` (None: a message it does not use)."""
        if isinstance(m, GpsFix):
            return self.on_fix
        if isinstance(m, GpsVelocity):
            return self.on_velocity
        if isinstance(m, GpsErrorStats):
            return self.on_gst
        if isinstance(m, Heading):
            return self.on_heading
        if isinstance(m, RateOfTurn):
            return self.on_rate
        if isinstance(m, ThrusterCommand):
            return self.on_command
        return None

    def on_fix(self, m: GpsFix) -> bool:
        """A GPS position (GGA, or RMC when no GGA comes): one per receiver epoch.
        Returns whether it was taken (False: another sentence of the epoch carries it)."""
        cfg = self.cfg
        if m.sentence == "GGA":
            self._t_gga = m.t
        elif m.t - self._t_gga < PREFERRED_WITHIN_S:
            return False  # the GGA of this epoch carries it, with the RTK quality
        self.fix = m.fix
        if m.lat_deg is None or m.lon_deg is None or m.fix is FixQuality.NONE:
            return True
        if m.fix < self.min_fix:
            self._count("pos_below_min_fix")
            return True
        if not (math.isfinite(m.lat_deg) and math.isfinite(m.lon_deg)):
            self._count("pos_invalid")
            return True
        if m.utc_s is not None:
            key = (m.sentence, m.utc_s)
            if key == self._fix_key:
                return False  # the same epoch again
            self._fix_key = key
        self.lat, self.lon = m.lat_deg, m.lon_deg
        n, e = self.geo.to_ned(m.lat_deg, m.lon_deg)
        r1 = r2 = self.noise.sigma_white.get(m.fix, self.cfg.sigma_single_m) ** 2
        g = self._gst
        if g is not None and m.t - g[0] <= self.cfg.gst_max_age_s and g[3] == m.fix:
            sb2 = self.noise.bias_sigma[m.fix] ** 2
            floor2 = self.cfg.gst_floor_m**2
            r1 = max(floor2, g[1] * g[1] - sb2)
            r2 = max(floor2, g[2] * g[2] - sb2)
        self._process(Measurement(K_POS, tov(m.t, cfg.gps_latency_s), n, e, r1, r2,
                                          m.fix))
        return True

    def on_gst(self, m: GpsErrorStats) -> None:
        """GST error statistics: per-axis 1σ (m), used for the next fixes of the same type.

        GST's σ is the receiver's total error; the filter's slowly varying
        offset state takes ``bias_*_m`` of it, the rest is white noise."""
        s_n, s_e = m.std_lat_m, m.std_lon_m
        if s_n is None or s_e is None or not (math.isfinite(s_n) and math.isfinite(s_e)):
            return
        self._gst = (m.t, s_n, s_e, self.fix)

    def on_velocity(self, m: GpsVelocity) -> None:
        """GPS speed and course over ground (RMC preferred over VTG)."""
        if m.sentence == "RMC":
            self._t_rmc_vel = m.t
        elif m.t - self._t_rmc_vel < PREFERRED_WITHIN_S:
            return
        sog = m.sog_mps
        if not math.isfinite(sog):
            self._count("vel_invalid")
            return
        t = tov(m.t, self.cfg.gps_latency_s)
        r_vel = self.noise.r_vel
        if m.cog_rad is None or not math.isfinite(m.cog_rad):
            self._process(Measurement(K_SOG, t, sog, 0.0, r_vel))
            return
        self._process(Measurement(K_VEL, t, sog * math.cos(m.cog_rad),
                                          sog * math.sin(m.cog_rad), r_vel, r_vel))

    def on_heading(self, m: Heading) -> None:
        """A heading: true (HDT/THS from a ``true_heading_sources`` device) or compass."""
        cfg = self.cfg
        z = m.heading_rad
        if not m.true and self.variation_deg is not None:
            z += math.radians(self.variation_deg)
        if not math.isfinite(z):
            self._count("heading_invalid")
            return
        z = wrap(z)
        is_true = (m.true and m.sentence in TRUE_HEADING_SENTENCES
                   and m.source in self._true_sources)
        if is_true:
            meas = Measurement(K_TRUE_HDG, tov(m.t, cfg.gps_latency_s), z, 0.0,
                               self.noise.r_true)
        else:
            meas = Measurement(K_COMPASS, tov(m.t, cfg.compass_latency_s), z, 0.0,
                               self.noise.r_compass)
        c = self._history.core
        psi = wrap(c.x[IPSI] + c.x[IR] * (meas.tov - c.t)) if c.hdg_init else math.nan
        if not self._monitors.ok(m, z, meas.tov, psi, self.has_gyro(m.t)):
            return
        self._gps.heading_sensor_seen = True
        self._process(meas)

    def on_rate(self, m: RateOfTurn) -> None:
        """Rate of turn (rad/s, clockwise), biased."""
        if not math.isfinite(m.rate_rps):
            self._count("rot_invalid")
            return
        self._t_rot_rx = m.t
        self._process(Measurement(K_ROT, tov(m.t, self.cfg.gyro_latency_s),
                                          m.rate_rps, 0.0, self.noise.r_rot))

    def on_command(self, m: ThrusterCommand) -> None:
        """A thruster command (−100..100, port and starboard) as control sent it at
        ``m.t``: from then on the prediction's input (ignored without a vessel model)."""
        if self._prediction.model is None:
            return
        u1 = m.u1 if math.isfinite(m.u1) else 0.0
        u2 = m.u2 if math.isfinite(m.u2) else 0.0
        self._count("commands")
        self._prediction.add_command(m.t, u1, u2)

    def has_gyro(self, t: float) -> bool:
        """True while yaw-rate measurements are arriving."""
        return t - self._t_rot_rx < self.cfg.sensor_timeout_s

    def thrust_model_active(self, t: float) -> bool:
        """True while the thruster commands are a prediction input (at time ``t``, s)."""
        return self._prediction.active(t)

    # ------------------------------------------------------------- output
    def _at(self, t: float) -> FilterState:
        h = self._history
        h.flush()
        c = h.core
        if t - c.t <= SAME_TIME_S or not math.isfinite(c.t):
            return c
        c = c.copy()
        self._prediction.predict(c, t)
        return c

    def state(self, t: float) -> NavState:
        """The estimate predicted to time ``t`` (s); ``cov`` is that of (x, y, vn, ve, ψ)."""
        c = self._at(t)
        x, P = c.x, c.P
        psi = x[IPSI]
        s, co = math.sin(psi), math.cos(psi)
        u, v = x[IU], x[IV]
        vn = u * co - v * s + x[ICN]
        ve = u * s + v * co + x[ICE]
        J = self._J
        J.flat[_J_IDX] = (co, -s, -(u * s + v * co), s, co, u * co - v * s)
        cov = J.dot(P).dot(J.T)
        pos_valid, hdg_valid = self._validity(c, t)
        pn, pe = x[IX], x[IY]
        if c.glide is not None:
            gn, ge = self._gps.glide_offset(c, t)
            pn += gn
            pe += ge
            cov[0, 0] += gn * gn
            cov[0, 1] += gn * ge
            cov[1, 0] += gn * ge
            cov[1, 1] += ge * ge
        if c.pos_init:
            lat, lon, _h = self.geo.to_geodetic(pn, pe)
        else:
            lat = lon = math.nan
        return NavState(
            t=t, x_m=pn, y_m=pe, vn_mps=vn, ve_mps=ve, psi_rad=psi, r_rps=x[IR],
            u_mps=co * vn + s * ve, v_mps=-s * vn + co * ve, lat_deg=lat, lon_deg=lon,
            fix=self.fix, pos_valid=pos_valid, heading_valid=hdg_valid,
            cov=tuple(cov.ravel().tolist()),
            gps_age_s=t - c.t_pos if c.pos_init else math.inf,
            current_n_mps=x[ICN], current_e_mps=x[ICE],
        )

    def status(self, t: float) -> EkfStatus:
        """Health, flags, counters and the full state at ``t`` (s)."""
        c = self._at(t)
        pos_valid, hdg_valid = self._validity(c, t)
        sig = np.sqrt(np.maximum(np.diag(c.P), 0.0)).tolist()
        frozen, jumping = self._monitors.faults()
        return EkfStatus(
            t=t, pos_valid=pos_valid, heading_valid=hdg_valid,
            gps_age_s=t - c.t_pos if c.pos_init else math.inf,
            pos_sigma_m=max(sig[IX], sig[IY]), heading_sigma_deg=math.degrees(sig[IPSI]),
            compass_frozen=bool(frozen), compass_jumping=bool(jumping),
            compass_faults=tuple(sorted(set(frozen + jumping))), fix=self.fix,
            counters=dict(self.counters),
            state=dict(zip(STATE_NAMES, c.x, strict=True)),
            sigma=dict(zip(STATE_NAMES, sig, strict=True)),
            glide_m=math.hypot(*self._gps.glide_offset(c, t)),
            thrust_model=self.thrust_model_active(t),
        )

