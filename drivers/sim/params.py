"""Parameters of the simulated world; these dataclasses are also the ``[world]``
schema of scenario files (``zarco_core.config`` walks them).

Conventions (shared with ``zarco_runtime.settings``):

* ``@dataclass(slots=True)``, mutable; every field has a type among
  float / int / bool / str / list[float] / list[str] / nested dataclass, and a
  default;
* ``metadata`` carries ``unit``, ``doc`` and, when bounded, the inclusive
  range ``min``/``max`` (or ``choices`` for enumerated strings);
* angles are degrees at this edge, with ``_deg`` in the name; the models
  convert to radians inside;
* frames as everywhere in the project: local NED (x north, y east) about the
  origin, heading clockwise from north, body x forward / y starboard, r
  positive clockwise.

Defaults are the Zarco catamaran's reference values: a hull model derived from
published small-USV models (Fossen's Otter, Clearpath Heron/Kingfisher, the
VRX WAM-V) and scaled so that full thrust (250 N) gives about 1.6 m/s, and the
noise of typical RTK receivers and calibrated marine compasses; each field's
``doc`` gives the range the tests vary it over where that matters.
Cross-field checks live in ``validate()`` methods, which raise
``ValueError("key: reason")`` as the config loader expects.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from datetime import datetime
from typing import Any

from zarco_core.config import spec

#: GPS fix modes a scenario may ask for (each has its own noise below)
FIX_MODES = ("none", "single", "dgps", "rtk_float", "rtk_fixed")
#: Sentences the simulated GPS can send at its full rate; GST and ZDA have their own rates.
GPS_RATE_SENTENCES = ("GGA", "RMC", "VTG")


def _md(unit: str, doc: str, *, lo: float | None = None, hi: float | None = None,
        choices: list[str] | None = None) -> dict[str, Any]:
    """Config metadata of a field (min/max omitted when unbounded)."""
    md: dict[str, Any] = {"unit": unit, "doc": doc}
    if lo is not None:
        md["min"] = lo
    if hi is not None:
        md["max"] = hi
    if choices is not None:
        md["choices"] = choices
    return md


def _p(default: float | int | bool | str, unit: str, doc: str, *, lo: float | None = None,
       hi: float | None = None, choices: list[str] | None = None) -> Any:
    """A scalar field with a default and config metadata (:func:`zarco_core.config.spec`)."""
    return spec(default, unit, doc, **{k: v for k, v in
                                       (("min", lo), ("max", hi), ("choices", choices))
                                       if v is not None})


@dataclass(slots=True)
class VesselParams:
    """3-DOF rigid body + hydrodynamics of the paper's model (section III).

    Hydrodynamic derivatives follow SNAME/Fossen notation and sign: added-mass
    and damping coefficients are negative, so that e.g. ``X_u u`` opposes the
    surge speed.  Defaults: the Zarco reference hull (scaled from Otter, Heron,
    WAM-V so that 250 N gives 1.60 m/s: 25 u + 82 u² = 250 at u = 1.60).
    """

    m_kg: float = _p(45.0, "kg", "mass (70 with payload)", lo=1.0, hi=500.0)
    iz_kgm2: float = _p(9.0, "kg m²", "yaw moment of inertia", lo=0.01, hi=1000.0)
    x_udot: float = _p(-4.5, "kg", "surge added mass X_u'", lo=-1000.0, hi=0.0)
    y_vdot: float = _p(-67.5, "kg", "sway added mass Y_v'", lo=-1000.0, hi=0.0)
    n_rdot: float = _p(-15.3, "kg m²", "yaw added inertia N_r'",
                       lo=-1000.0, hi=0.0)
    x_u: float = _p(-25.0, "N s/m", "linear surge damping X_u", lo=-1e4, hi=0.0)
    x_uu: float = _p(-82.0, "N s²/m²", "quadratic surge damping X_|u|u",
                     lo=-1e4, hi=0.0)
    y_v: float = _p(-112.5, "N s/m", "linear sway damping Y_v", lo=-1e4, hi=0.0)
    y_vv: float = _p(-150.0, "N s²/m²", "quadratic sway damping Y_|v|v",
                     lo=-1e4, hi=0.0)
    n_r: float = _p(-24.3, "N m s", "linear yaw damping N_r", lo=-1e4, hi=0.0)
    n_rr: float = _p(-250.0, "N m s²", "quadratic yaw damping N_|r|r",
                     lo=-1e4, hi=0.0)
    b_m: float = _p(0.38, "m", "lateral offset ±b of the thrusters from the centre line",
                    lo=0.01, hi=5.0)
    l_m: float = _p(0.65, "m", "distance l of the thrusters aft of the centre of mass",
                    lo=0.0, hi=5.0)


@dataclass(slots=True)
class ThrusterParams:
    """Thruster map f, its per-thruster deviations, lag and status model.

    f(U), the reference thrust curve: 0 for |U| ≤ deadband, otherwise with
    s = (|U| − deadband)/(100 − deadband), g = 0.3 s + 0.7 s²,
    F = fwd_max_n g (U > 0) or −rev_max_n g (U < 0).  Thruster i gives
    f1 = (1 + mismatch) f, f2 = (1 − mismatch) f, pointing φ_i to starboard of
    the body x axis.
    """

    fwd_max_n: float = _p(125.0, "N", "forward thrust per thruster at U=+100",
                          lo=0.0, hi=5000.0)
    rev_max_n: float = _p(75.0, "N", "reverse thrust magnitude per thruster at U=−100",
                          lo=0.0, hi=5000.0)
    deadband: float = _p(5.0, "%", "command deadband |U| ≤ this gives no thrust",
                         lo=0.0, hi=50.0)
    lag_s: float = _p(0.15, "s", "first-order thrust time constant (0.1–0.2 s for such thrusters); "
                      "≥ 0.02 s keeps RK4 at dt ≤ 0.01 s accurate and stable", lo=0.02, hi=5.0)
    phi1_deg: float = _p(0.0, "deg", "port thruster misalignment, positive to starboard "
                         "(0 nominal, ±3° in tests)", lo=-15.0, hi=15.0)
    phi2_deg: float = _p(0.0, "deg", "starboard thruster misalignment, positive to starboard",
                         lo=-15.0, hi=15.0)
    mismatch: float = _p(0.0, "", "Δf as a fraction of f: f1 = (1+Δ) f, f2 = (1−Δ) f "
                         "(0 nominal, up to 0.1 in tests)", lo=-0.5, hi=0.5)
    rpm_max: float = _p(3000.0, "rpm", "propeller speed at full thrust (status only)",
                        lo=1.0, hi=1e5)
    amps_max_a: float = _p(20.0, "A", "motor current at full thrust (status only)",
                           lo=0.0, hi=1000.0)


@dataclass(slots=True)
class CurrentParams:
    """Constant, uniform water current (0–0.5 m/s where the Zarco works, constant over a run)."""

    speed_mps: float = _p(0.0, "m/s", "current speed", lo=0.0, hi=3.0)
    direction_deg: float = _p(0.0, "deg", "direction the water flows TOWARDS, clockwise "
                              "from north (90 = flowing east)", lo=-360.0, hi=360.0)


@dataclass(slots=True)
class DisturbanceParams:
    """Wind gusts and chop as first-order Gauss–Markov body-frame forces.

    Each component is an independent stationary process with 1σ given here
    and correlation time ``tau_s``, held constant over each integration step.
    """

    enabled: bool = _p(True, "", "apply the disturbance forces")
    surge_n: float = _p(0.0, "N", "1σ surge force", lo=0.0, hi=1000.0)
    sway_n: float = _p(5.0, "N", "1σ sway force", lo=0.0, hi=1000.0)
    yaw_nm: float = _p(2.0, "N m", "1σ yaw moment", lo=0.0, hi=1000.0)
    tau_s: float = _p(2.0, "s", "correlation time", lo=0.01, hi=1e5)


@dataclass(slots=True)
class GpsParams:
    """RTK GNSS receiver (NMEA 0183).  Noise 1σ per horizontal axis.

    Position error = white noise with the fix mode's σ plus, for ``single`` and
    ``rtk_float``, a slowly drifting Gauss–Markov bias.  Both biases evolve all
    the time, whatever the mode, so a fix-type change shows as a position jump.
    """

    fix: str = _p("rtk_fixed", "", "fix mode", choices=list(FIX_MODES))
    rate_hz: float = _p(10.0, "Hz", "rate of the position sentences", lo=0.1, hi=100.0)
    sentences: list[str] = field(
        default_factory=lambda: ["GGA", "RMC"],
        metadata=_md("", "sentences at rate_hz, among GGA, RMC, VTG (GST/ZDA have their "
                     "own rates)"))
    gst_rate_hz: float = _p(1.0, "Hz", "GST rate (0 disables)", lo=0.0, hi=100.0)
    zda_rate_hz: float = _p(1.0, "Hz", "ZDA rate (0 disables)", lo=0.0, hi=100.0)
    talker: str = _p("GN", "", "talker id (GN multi-constellation, GP GPS only)")
    sigma_rtk_fixed_m: float = _p(0.015, "m", "white noise, RTK fixed (0.01–0.02 m)",
                                  lo=0.0, hi=100.0)
    sigma_rtk_float_m: float = _p(0.3, "m", "white noise, RTK float (0.2–0.5 m)",
                                  lo=0.0, hi=100.0)
    sigma_dgps_m: float = _p(0.5, "m", "white noise, DGPS", lo=0.0, hi=100.0)
    sigma_single_m: float = _p(1.5, "m", "white noise, single point",
                               lo=0.0, hi=100.0)
    single_bias_m: float = _p(1.5, "m", "1σ drifting bias, single point",
                              lo=0.0, hi=100.0)
    single_bias_tau_s: float = _p(300.0, "s", "correlation time of the single-point bias",
                                  lo=1.0, hi=1e6)
    float_bias_m: float = _p(0.2, "m", "1σ drifting bias, RTK float", lo=0.0, hi=100.0)
    float_bias_tau_s: float = _p(60.0, "s", "correlation time of the RTK-float bias",
                                 lo=1.0, hi=1e6)
    speed_sigma_mps: float = _p(0.05, "m/s", "white noise on each of the N/E velocity "
                                "components behind SOG/COG", lo=0.0, hi=10.0)
    alt_m: float = _p(0.0, "m", "antenna altitude reported in GGA", lo=-1000.0, hi=10000.0)
    num_sats: int = _p(14, "", "satellites in use (GGA)", lo=0, hi=99)
    hdop: float = _p(0.7, "", "horizontal dilution of precision (GGA)", lo=0.0, hi=99.9)

    def validate(self) -> None:
        for s in self.sentences:
            if s not in GPS_RATE_SENTENCES:
                raise ValueError(f"sentences: unknown sentence {s!r}, expected among "
                                 f"{list(GPS_RATE_SENTENCES)} (GST/ZDA: use gst_rate_hz, "
                                 "zda_rate_hz)")
        if len(self.talker) != 2 or not self.talker.isalpha() or not self.talker.isupper():
            raise ValueError(f"talker: must be two upper-case letters, got {self.talker!r}")


@dataclass(slots=True)
class CompassParams:
    """Magnetic compass with gyro and pitch/roll (NMEA HDG, ROT, XDR).

    Typical of a calibrated marine compass and MEMS gyro: 0.5–1° noise and 1–3° bias after
    calibration; gyro noise density 3.4e-4 rad/s/√Hz, turn-on bias 0.5 °/s.
    """

    rate_hz: float = _p(20.0, "Hz", "rate of HDG and ROT", lo=0.1, hi=200.0)
    xdr_every: int = _p(4, "", "send XDR pitch/roll every Nth epoch (4: 5 Hz at 20 Hz; "
                        "the runtime's control does not use attitude)", lo=1, hi=1000)
    noise_deg: float = _p(1.0, "deg", "1σ white heading noise", lo=0.0, hi=45.0)
    bias_deg: float = _p(1.0, "deg", "residual heading bias after calibration (signed, "
                         "added to the magnetic heading)", lo=-45.0, hi=45.0)
    variation_deg: float = _p(-2.0, "deg", "magnetic variation, east positive (HDG carries "
                              "it; ≈ −2° at Leixões)", lo=-90.0, hi=90.0)
    gyro_noise_density_rps_rthz: float = _p(3.4e-4, "rad/s/√Hz", "gyro white-noise density "
                                            "(one-sided)", lo=0.0, hi=1.0)
    gyro_bias_dps: float = _p(0.5, "deg/s", "turn-on gyro bias magnitude, fixed per run, "
                              "sign drawn from the run's random seed", lo=0.0, hi=100.0)
    pitch_noise_deg: float = _p(0.2, "deg", "1σ white pitch noise", lo=0.0, hi=45.0)
    roll_noise_deg: float = _p(0.2, "deg", "1σ white roll noise", lo=0.0, hi=45.0)


@dataclass(slots=True)
class WorldParams:
    """Everything the simulator simulates (the ``[world]`` table of a scenario)."""

    vessel: VesselParams = field(default_factory=VesselParams,
                                 metadata=_md("", "hydrodynamic model"))
    thrusters: ThrusterParams = field(default_factory=ThrusterParams,
                                      metadata=_md("", "thruster map, lag, deviations"))
    current: CurrentParams = field(default_factory=CurrentParams,
                                   metadata=_md("", "water current"))
    disturbance: DisturbanceParams = field(default_factory=DisturbanceParams,
                                           metadata=_md("", "gusts and chop"))
    gps: GpsParams = field(default_factory=GpsParams,
                           metadata=_md("", "GNSS receiver"))
    compass: CompassParams = field(default_factory=CompassParams,
                                   metadata=_md("", "compass / gyro / pitch-roll"))
    dt_s: float = _p(0.025, "s", "fixed RK4 integration step (25 ms divides the 50 ms and "
                     "100 ms device and control periods)", lo=1e-4, hi=0.05)
    origin_lat_deg: float = _p(41.185, "deg", "latitude of the local NED origin (Leixões)",
                               lo=-90.0, hi=90.0)
    origin_lon_deg: float = _p(-8.705, "deg", "longitude of the local NED origin",
                               lo=-180.0, hi=180.0)
    start_utc: str = _p("2026-06-01T10:00:00Z", "", "UTC at simulation time 0 (ISO 8601)")
    x_m: float = _p(0.0, "m", "initial north position", lo=-1e6, hi=1e6)
    y_m: float = _p(0.0, "m", "initial east position", lo=-1e6, hi=1e6)
    heading_deg: float = _p(0.0, "deg", "initial heading, clockwise from north",
                            lo=-360.0, hi=360.0)
    u_mps: float = _p(0.0, "m/s", "initial surge speed through the water", lo=-3.0, hi=5.0)

    def validate(self) -> None:
        start_epoch_s(self.start_utc, key="start_utc")
        if self.dt_s > self.thrusters.lag_s / 2.0:
            raise ValueError(f"dt_s: {self.dt_s} s must be ≤ half the thruster lag "
                             f"({self.thrusters.lag_s} s) for an accurate RK4 step")


def start_epoch_s(text: str, key: str = "start_utc") -> float:
    """Seconds since 1970-01-01 UTC of an ISO-8601 time that states its zone."""
    try:
        dt = datetime.fromisoformat(text)
    except ValueError:
        raise ValueError(f"{key}: not an ISO-8601 time: {text!r}") from None
    if dt.tzinfo is None:
        raise ValueError(f"{key}: must state its time zone (e.g. a trailing Z): {text!r}")
    return dt.timestamp()
