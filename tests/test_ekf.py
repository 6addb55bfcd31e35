"""Navigation EKF, unit level: geodesy, settings, interface, measurement handling,
time of validity, gating, speed.  Simulator-driven figures are in
``test_ekf_sim.py``, the real captures in ``test_ekf_real.py``."""

from __future__ import annotations

import dataclasses
import inspect
import math
import random
from typing import Any

import numpy as np
import pytest

from zarco_core.bus import Bus
from zarco_core.clock import Clock
from zarco_core.config import ConfigError, build
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
)
from zarco_runtime.navigation import task as nav_task
from zarco_runtime.navigation.ekf import EkfNavigator
from zarco_runtime.navigation.ekf_config import EkfSettings
from zarco_runtime.navigation.simple import SimpleNavigator
from zarco_runtime.settings import RuntimeConfig
from zarco_tools.ekf_eval import Case, run

LAT0, LON0 = 41.185, -8.705
FRAME = LocalFrame(LAT0, LON0)
GEO = FastLocalFrame(LAT0, LON0)


def nav(**overrides: Any) -> EkfNavigator:
    return EkfNavigator(dataclasses.replace(EkfSettings(), **overrides), FRAME)


def fix(t: float, n: float, e: float, q: FixQuality = FixQuality.RTK_FIXED,
        sentence: str = "GGA") -> GpsFix:
    lat, lon, _h = GEO.to_geodetic(n, e)
    return GpsFix(t, "gps", sentence, "GN", q, lat, lon, 0.0, utc_s=36000.0 + t, num_sats=14)


def vel(t: float, vn: float, ve: float, sentence: str = "RMC") -> GpsVelocity:
    return GpsVelocity(t, "gps", sentence, math.hypot(vn, ve), math.atan2(ve, vn) % math.tau,
                       36000.0 + t)


def hdg(t: float, psi_rad: float, source: str = "compass", sentence: str = "HDG",
        true: bool = True, raw_deg: float | None = None) -> Heading:
    raw = math.degrees(psi_rad) % 360.0 if raw_deg is None else raw_deg
    return Heading(t, source, sentence, psi_rad % math.tau, true, raw)


def drive(n: EkfNavigator, t_end: float, speed: float = 1.0, psi: float = 0.0,
          gyro_bias: float = 0.0, t0: float = 0.0, seed: int = 1,
          velocity: bool = True) -> None:
    """Straight line at ``speed`` (m/s) on heading ``psi`` (rad): GPS at 10 Hz
    (RMC velocity unless ``velocity`` is false), compass + ROT at 20 Hz, small noise."""
    rng = random.Random(seed)
    k = round(t0 / 0.05)
    while k * 0.05 <= t_end + 1e-9:
        t = k * 0.05
        n.on_heading(hdg(t, psi + math.radians(rng.gauss(0.0, 0.5)),
                         raw_deg=round(math.degrees(psi) + rng.gauss(0.0, 0.5), 1)))
        n.on_rate(RateOfTurn(t, "compass", gyro_bias + rng.gauss(0.0, 0.001)))
        if k % 2 == 0:
            d = speed * t
            n.on_fix(fix(t, d * math.cos(psi) + rng.gauss(0.0, 0.01),
                         d * math.sin(psi) + rng.gauss(0.0, 0.01)))
            if velocity:
                n.on_velocity(vel(t, speed * math.cos(psi) + rng.gauss(0.0, 0.03),
                                  speed * math.sin(psi) + rng.gauss(0.0, 0.03)))
        k += 1


# ------------------------------------------------------------------ geodesy


def test_fast_frame_agrees_with_pymap3d() -> None:
    rng = random.Random(5)
    for _ in range(50):
        n, e = rng.uniform(-5000.0, 5000.0), rng.uniform(-5000.0, 5000.0)
        lat, lon, _h = FRAME.to_geodetic(n, e)
        fn, fe = GEO.to_ned(lat, lon)
        pn, pe = FRAME.to_ned(lat, lon)
        assert abs(fn - pn) < 1e-6 and abs(fe - pe) < 1e-6
        glat, glon, _ = GEO.to_geodetic(n, e)
        assert abs(glat - lat) < 1e-10 and abs(glon - lon) < 1e-10


# ----------------------------------------------------------------- settings


def test_settings_build_validate_and_name_the_key() -> None:
    cfg = build(EkfSettings, {"gps_latency_s": 0.1, "true_heading_sources": ["gps", "gnss2"]},
                "zarco.toml", "navigation.ekf")
    assert cfg.gps_latency_s == 0.1 and cfg.true_heading_sources == ["gps", "gnss2"]
    with pytest.raises(ConfigError, match=r"navigation\.ekf\.gate_1d"):
        build(EkfSettings, {"gate_1d": 0.0}, "zarco.toml", "navigation.ekf")
    with pytest.raises(ConfigError, match="bias_rtk_float_m"):
        build(EkfSettings, {"bias_rtk_float_m": 5.0}, "zarco.toml", "navigation.ekf")
    for f in dataclasses.fields(EkfSettings):
        assert f.metadata.get("doc"), f.name


# ---------------------------------------------------------------- interface


def test_same_interface_as_the_first_estimator() -> None:
    for name in ("on_fix", "on_velocity", "on_heading", "on_rate", "has_gyro", "state"):
        a = inspect.signature(getattr(SimpleNavigator, name))
        b = inspect.signature(getattr(EkfNavigator, name))
        assert list(a.parameters) == list(b.parameters), name
    assert list(inspect.signature(SimpleNavigator).parameters)[1:] == \
        list(inspect.signature(EkfNavigator).parameters)[1:]


def test_drop_in_behind_the_navigation_task(monkeypatch: pytest.MonkeyPatch) -> None:
    """The bus wiring of navigation/task.py runs unchanged with the EKF in place."""
    monkeypatch.setattr(nav_task, "SimpleNavigator",
                        lambda _cfg, frame, var: EkfNavigator(EkfSettings(), frame, var))
    bus = Bus()
    out: list[NavState] = []
    bus.listen(NavState, out.append)
    task = nav_task.Navigation(RuntimeConfig(), bus, Clock(utc_offset_s=0.0))
    assert isinstance(task.nav, EkfNavigator)
    for k in range(40):
        t = 0.05 * k
        bus.publish(hdg(t, 0.3))
        bus.publish(RateOfTurn(t, "compass", 0.0))
        if k % 2 == 0:
            bus.publish(fix(t, 1.0 * t * math.cos(0.3), 1.0 * t * math.sin(0.3)))
            bus.publish(vel(t, math.cos(0.3), math.sin(0.3)))
    last = out[-1]
    assert last.pos_valid and last.heading_valid
    assert abs(last.psi_rad - 0.3) < math.radians(3.0)
    assert math.hypot(last.vn_mps - math.cos(0.3), last.ve_mps - math.sin(0.3)) < 0.1


def test_no_data_yet_is_invalid_and_finite_where_it_matters() -> None:
    n = nav()
    s = n.state(0.0)
    assert not s.pos_valid and not s.heading_valid and s.fix is FixQuality.NONE
    assert math.isnan(s.lat_deg) and len(s.cov) == 25
    n.on_heading(hdg(0.0, 1.0))
    s = n.state(0.2)
    assert s.heading_valid and not s.pos_valid


def test_navstate_fields_and_covariance() -> None:
    n = nav()
    drive(n, 20.0, psi=math.radians(40.0))
    s = n.state(20.0)
    assert s.fix is FixQuality.RTK_FIXED and s.pos_valid and s.heading_valid
    assert math.hypot(s.x_m - 20 * math.cos(0.698), s.y_m - 20 * math.sin(0.698)) < 0.05
    assert abs(s.u_mps - 1.0) < 0.05 and abs(s.v_mps) < 0.05
    lat, lon, _ = GEO.to_geodetic(s.x_m, s.y_m)
    assert (s.lat_deg, s.lon_deg) == pytest.approx((lat, lon), abs=1e-12)
    P = np.array(s.cov).reshape(5, 5)
    assert np.allclose(P, P.T, atol=1e-12)
    assert np.linalg.eigvalsh(P).min() > 0.0
    assert math.sqrt(P[0, 0]) < 0.02 and math.sqrt(P[2, 2]) < 0.05


def test_non_finite_inputs_are_refused_and_counted() -> None:
    n = nav()
    drive(n, 5.0)
    before = n.state(5.0)
    n.on_heading(hdg(5.05, math.nan))
    n.on_rate(RateOfTurn(5.05, "compass", math.inf))
    n.on_velocity(GpsVelocity(5.05, "gps", "RMC", math.nan, 0.0))
    bad = fix(5.1, 0.0, 0.0)
    bad.lat_deg = math.nan
    n.on_fix(bad)
    after = n.state(5.1)
    assert all(math.isfinite(v) for v in (after.x_m, after.psi_rad, after.vn_mps))
    assert math.hypot(after.x_m - before.x_m, after.y_m - before.y_m) < 0.2
    c = n.counters
    assert c["heading_invalid"] == c["rot_invalid"] == c["vel_invalid"] == c["pos_invalid"] == 1


# --------------------------------------------------------- GPS measurements


def test_one_position_per_epoch_gga_preferred() -> None:
    n = nav()
    for k in range(10):
        t = 0.1 * k
        n.on_fix(fix(t, 0.0, 0.0))
        n.on_fix(fix(t, 0.0, 0.0, FixQuality.SINGLE, sentence="RMC"))  # same epoch
        n.on_fix(fix(t, 0.0, 0.0))  # a repeated GGA
    assert n.counters.get("pos_ok", 0) == 9  # the first initialises
    assert n.state(1.0).fix is FixQuality.RTK_FIXED  # RMC's mode letter did not win


def test_fixes_below_min_fix_count_as_no_gps() -> None:
    n = nav(min_fix="rtk_float", dr_max_s=2.0)
    drive(n, 5.0)
    for k in range(1, 40):
        n.on_fix(fix(5.0 + 0.1 * k, 5.0 + 0.1 * k, 0.0, FixQuality.SINGLE))
    assert n.counters["pos_below_min_fix"] == 39
    assert not n.state(9.0).pos_valid


def test_gst_sigma_is_used_for_fixes_of_the_same_type(monkeypatch: pytest.MonkeyPatch) -> None:
    n = nav()
    fused: list[Any] = []
    monkeypatch.setattr(n, "_process", fused.append)
    n.on_fix(fix(0.0, 0.0, 0.0, FixQuality.RTK_FLOAT))
    n.on_gst(GpsErrorStats(0.05, "gps", 0.25, 0.30, 0.5))  # total σ under RTK float
    n.on_fix(fix(0.1, 0.0, 0.0, FixQuality.RTK_FLOAT))
    n.on_fix(fix(0.2, 0.0, 0.0, FixQuality.SINGLE))  # another fix type: not this GST
    n.on_fix(fix(3.0, 0.0, 0.0, FixQuality.SINGLE))
    n.on_gst(GpsErrorStats(3.05, "gps", 1.6, 1.6, 3.0))  # under SINGLE
    n.on_fix(fix(3.1, 0.0, 0.0, FixQuality.SINGLE))
    n.on_fix(fix(6.0, 0.0, 0.0, FixQuality.SINGLE))  # the GST is stale by now
    r = [(m.r1, m.r2) for m in fused]
    assert r[0] == pytest.approx((0.35**2, 0.35**2))  # the fix-type σ
    assert r[1] == pytest.approx((0.25**2 - 0.2**2, 0.30**2 - 0.2**2))  # GST less the offset
    assert r[2] == r[3] == pytest.approx((1.5**2, 1.5**2))
    assert r[4] == pytest.approx((1.6**2 - 1.5**2, 1.6**2 - 1.5**2))
    assert r[5] == pytest.approx((1.5**2, 1.5**2))


def test_vtg_only_without_rmc_and_speed_alone() -> None:
    n = nav()
    drive(n, 3.0)
    ok = n.counters["vel_ok"]
    n.on_velocity(vel(3.05, 1.0, 0.0, sentence="VTG"))  # RMC velocities are coming
    assert n.counters["vel_ok"] == ok
    # later, a VTG without course (speed only) while everything else goes on
    for k in range(61, 200):
        t = 0.05 * k
        n.on_heading(hdg(t, 0.0))
        n.on_rate(RateOfTurn(t, "compass", 0.0))
        if k % 2 == 0:
            n.on_fix(fix(t, t, 0.0))
            n.on_velocity(GpsVelocity(t, "gps", "VTG", 1.0, None))
    assert n.counters["sog_ok"] > 40  # VTG taken once RMC has been silent for 2 s
    assert "sog_rejected" not in n.counters
    assert abs(n.state(10.0).u_mps - 1.0) < 0.02


def test_position_only_speed_change_is_followed() -> None:
    """A GGA-only receiver (no velocity sentence) and a sudden speed change: the
    RTK fixes, beyond their gate, are taken as a manoeuvre, not rejected."""
    n = nav()
    drive(n, 3.0, velocity=False)
    x = 3.0
    for k in range(61, 200):
        t = 0.05 * k
        n.on_heading(hdg(t, 0.0))
        n.on_rate(RateOfTurn(t, "compass", 0.0))
        if k % 2 == 0:
            x += 0.15  # 1.5 m/s from 3 s on
            n.on_fix(fix(t, x, 0.0))
    s = n.state(9.95)  # the last fix was at 9.9 s
    assert n.counters.get("pos_manoeuvre", 0) >= 1
    assert n.counters.get("pos_rejected", 0) <= 3 and "resets_pos" not in n.counters
    assert abs(s.x_m - (x + 0.075)) < 0.02 and abs(s.u_mps - 1.5) < 0.05


def test_heading_from_course_when_there_is_no_heading_sensor() -> None:
    n = nav()
    course = math.radians(-60.0)
    for k in range(100):
        t = 0.1 * k
        n.on_fix(fix(t, 1.2 * t * math.cos(course), 1.2 * t * math.sin(course)))
        n.on_velocity(vel(t, 1.2 * math.cos(course), 1.2 * math.sin(course)))
    s = n.state(9.9)
    assert n.counters["heading_from_course"] == 1
    assert abs(math.remainder(s.psi_rad - course, math.tau)) < math.radians(5.0)
    assert s.pos_valid and not s.heading_valid  # a course is not a heading
    assert math.hypot(s.x_m - 11.88 * math.cos(course), s.y_m - 11.88 * math.sin(course)) < 0.1


# ------------------------------------------------------------------ heading


def test_magnetic_heading_gets_the_variation() -> None:
    n = EkfNavigator(EkfSettings(), FRAME, variation_deg=-2.0)
    for k in range(20):
        n.on_heading(hdg(0.05 * k, math.radians(100.0), true=False, raw_deg=100.0))
    assert math.degrees(n.state(1.0).psi_rad) == pytest.approx(98.0, abs=0.01)


def test_true_heading_only_from_the_configured_sources() -> None:
    def after(source: str) -> EkfNavigator:
        n = nav()
        for k in range(20):
            n.on_heading(hdg(0.05 * k, 1.0, source=source, sentence="HDT"))
            n.on_rate(RateOfTurn(0.05 * k, "compass", 0.0))
        return n

    dual = after("gps")  # a dual-antenna receiver: unbiased
    comp = after("compass")  # a compass that happens to say HDT: biased
    assert dual.counters["true_heading_ok"] == 19 and "compass_ok" not in dual.counters
    assert comp.counters["compass_ok"] == 19 and "true_heading_ok" not in comp.counters
    assert dual.status(1.0).heading_sigma_deg < 0.3
    assert comp.status(1.0).heading_sigma_deg > 2.0  # its bias is not known yet


def test_gyro_bias_is_learned_and_has_gyro() -> None:
    n = nav()
    bias = math.radians(0.5)
    drive(n, 60.0, gyro_bias=bias)
    st = n.status(60.0)
    assert st.state["gyro_bias_rps"] == pytest.approx(bias, abs=math.radians(0.02))
    assert abs(st.state["r_rps"]) < math.radians(0.2)  # ROT noise is 0.06°/s per sample
    assert n.has_gyro(60.0) and not n.has_gyro(62.0)


# --------------------------------------------------------- time of validity


def _recorded(duration: float = 40.0) -> list[Any]:
    """Messages of a short simulated run (rectangle start, every sensor), in arrival order."""
    msgs: list[Any] = []

    def keep(m: Any, _t: float) -> Any:
        msgs.append(m)
        return m

    run(Case(duration_s=duration, tamper=keep))
    return msgs


HANDLERS = {GpsFix: "on_fix", GpsVelocity: "on_velocity", GpsErrorStats: "on_gst",
            Heading: "on_heading", RateOfTurn: "on_rate"}


def _feed(n: EkfNavigator, msgs: list[Any]) -> None:
    for m in msgs:
        name = HANDLERS.get(type(m))
        if name is not None:
            getattr(n, name)(m)


def test_late_gps_is_rerun_in_order_and_gives_the_in_order_result() -> None:
    """GPS arriving 0.3 s late (after 6 compass epochs) with its latency configured
    gives exactly what in-order arrival gives; unconfigured, it does not."""
    msgs = _recorded()
    gps_types = (GpsFix, GpsVelocity, GpsErrorStats)
    late = [dataclasses.replace(m, t=m.t + 0.3) if isinstance(m, gps_types) else m
            for m in msgs]
    late.sort(key=lambda m: m.t)  # arrival order (stable: compass first within a time)
    a = nav()
    _feed(a, msgs)
    b = nav(gps_latency_s=0.3)
    _feed(b, late)
    c = nav()
    _feed(c, late)
    t_end = late[-1].t
    sa, sb, sc = a.state(t_end), b.state(t_end), c.state(t_end)
    assert b.counters["replays"] > 300 and "late_dropped" not in b.counters
    # the same sequence of operations: equal (to rounding, should BLAS kernels differ)
    for f in ("x_m", "y_m", "vn_mps", "ve_mps", "psi_rad", "r_rps"):
        assert getattr(sb, f) == pytest.approx(getattr(sa, f), abs=1e-9), f
    assert sb.cov == pytest.approx(sa.cov, rel=1e-9, abs=1e-15)
    # without the latency the late fixes look 0.3 m behind the boat
    assert math.hypot(sc.x_m - sa.x_m, sc.y_m - sa.y_m) > 0.05


def test_measurement_older_than_the_history_is_dropped() -> None:
    n = nav(history_s=0.5)
    drive(n, 10.0)
    before = n.state(10.0)
    n.on_fix(fix(8.0, 50.0, 50.0))  # 2 s old, and wildly off: must not touch the state
    after = n.state(10.0)
    assert n.counters["late_dropped"] == 1
    assert (after.x_m, after.y_m) == (before.x_m, before.y_m)
    n.on_fix(fix(9.75, 9.75, 0.0))  # within the history: fused by re-running
    assert n.counters["replays"] == 1


# --------------------------------------------------------------- gating


def test_a_gps_outlier_is_gated_and_a_persistent_shift_reinitialises() -> None:
    n = nav()
    drive(n, 10.0)
    n.on_fix(fix(10.05, 10.05 + 5.0, 0.0))  # one 5 m outlier
    s = n.state(10.1)
    assert n.counters["pos_rejected"] == 1 and abs(s.x_m - 10.1) < 0.05
    # the receiver really moved its solution by 2 m (same fix type): after
    # reset_after_s of rejections the filter follows it instead of dead-reckoning forever
    for k in range(1, 50):
        t = 10.1 + 0.1 * k
        n.on_fix(fix(t, t + 2.0, 0.0))
        n.on_velocity(vel(t, 1.0, 0.0))
    assert n.counters["resets_pos"] == 1
    assert n.state(15.0).x_m == pytest.approx(17.0, abs=0.1)


def test_compass_outlier_is_gated() -> None:
    n = nav()
    drive(n, 10.0)
    n.on_heading(hdg(10.025, math.radians(30.0)))
    assert n.counters["compass_rejected"] >= 1
    assert abs(math.degrees(n.state(10.03).psi_rad)) < 1.0


# ------------------------------------------------------------------ speed
