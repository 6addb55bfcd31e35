"""Simulated hardware: vessel physics, disturbances, NMEA emitters, the world."""

from __future__ import annotations

import dataclasses
import itertools
import math
import typing

import numpy as np
import pymap3d
import pynmea2
import pytest

from drivers.nmea import nmea_checksum
from drivers.sim.disturbance import GaussMarkov, NormalStream
from drivers.sim.params import (
    CurrentParams,
    DisturbanceParams,
    ThrusterParams,
    VesselParams,
    WorldParams,
)
from drivers.sim.sensors import (
    NedToGeodetic,
    SimThrusterController,
    format_lat,
    format_lon,
    utc_fields,
)
from drivers.sim.vessel import Vessel, VesselState
from drivers.sim.world import SimWorld

LAT0, LON0 = 41.185, -8.705


def _run(v: Vessel, seconds: float, u1: float, u2: float, dt: float = 0.01,
         dist: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> None:
    for _ in range(round(seconds / dt)):
        v.step(dt, u1, u2, dist)


def _quiet_world(**kw: typing.Any) -> WorldParams:
    p = WorldParams(**kw)
    p.disturbance.enabled = False
    return p


# ------------------------------------------------------------------ physics


def test_full_thrust_steady_surge() -> None:
    v = Vessel(VesselParams(), ThrusterParams())
    _run(v, 30.0, 100.0, 100.0)
    s = v.state
    assert s.u_mps == pytest.approx(1.60, abs=0.03)
    assert s.f1_n == pytest.approx(125.0) and s.f2_n == pytest.approx(125.0)
    assert s.v_mps == 0.0 and s.r_rps == 0.0 and s.psi_rad == 0.0
    assert s.y_m == 0.0 and s.x_m > 40.0  # heading north: all motion along x


def test_thrust_lag_first_order() -> None:
    v = Vessel(VesselParams(), ThrusterParams(lag_s=0.15))
    _run(v, 0.15, 100.0, 100.0, dt=0.001)
    assert v.state.f1_n == pytest.approx(125.0 * (1.0 - math.exp(-1.0)), rel=1e-6)


@pytest.mark.parametrize("u1,u2,sign", [(100.0, 50.0, 1.0), (50.0, 100.0, -1.0)])
def test_differential_thrust_turn_direction(u1: float, u2: float, sign: float) -> None:
    """F1 > F2 (port pushes harder) → N > 0 → r > 0: clockwise, heading increases."""
    v = Vessel(VesselParams(), ThrusterParams())
    psis = []
    for _ in range(20):
        _run(v, 0.1, u1, u2)
        psis.append(v.state.psi_rad)
    assert sign * v.state.r_rps > 0.0
    assert all(sign * (b - a) > 0.0 for a, b in itertools.pairwise(psis))
    # heading north and turning to starboard moves the boat east
    assert sign * v.state.y_m > 0.0


@pytest.mark.parametrize("phi_deg", [3.0, -3.0])
def test_misalignment_lateral_drift(phi_deg: float) -> None:
    """φ1 = φ2 = φ: Y_act = (F1+F2) φ pushes to starboard for φ > 0 (v > 0), and
    N_act = −l Y_act yaws the bow the other way."""
    tp = ThrusterParams(phi1_deg=phi_deg, phi2_deg=phi_deg)
    v = Vessel(VesselParams(), tp)
    _run(v, 3.0, 100.0, 100.0)
    sign = math.copysign(1.0, phi_deg)
    assert sign * v.state.v_mps > 0.0
    assert sign * v.state.r_rps < 0.0
    _run(v, 30.0, 100.0, 100.0)  # steady circle: sway stays on the same side
    assert sign * v.state.v_mps > 0.0


def test_current_adds_to_ground_velocity() -> None:
    cur = CurrentParams(speed_mps=0.3, direction_deg=90.0)  # flowing east
    v = Vessel(VesselParams(), ThrusterParams(), cur)
    _run(v, 10.0, 0.0, 0.0)
    assert v.state.u_mps == 0.0 and v.state.v_mps == 0.0
    assert v.state.x_m == pytest.approx(0.0, abs=1e-12)
    assert v.state.y_m == pytest.approx(3.0)
    assert v.ground_velocity_ned() == pytest.approx((0.0, 0.3))
    _run(v, 30.0, 100.0, 100.0)  # heading north at full thrust
    vn, ve = v.ground_velocity_ned()
    assert vn == pytest.approx(v.state.u_mps) and ve == pytest.approx(0.3)
    # a north-flowing current at heading 90°: adds along x
    v2 = Vessel(VesselParams(), ThrusterParams(), CurrentParams(0.2, 0.0),
                VesselState(psi_rad=math.pi / 2, u_mps=1.0))
    vn, ve = v2.ground_velocity_ned()
    assert vn == pytest.approx(0.2) and ve == pytest.approx(1.0)


def test_rk4_step_size_convergence() -> None:
    tp = ThrusterParams(phi1_deg=2.0, phi2_deg=-1.0, mismatch=0.05)
    cur = CurrentParams(speed_mps=0.3, direction_deg=45.0)
    coarse = Vessel(VesselParams(), tp, cur)
    fine = Vessel(VesselParams(), tp, cur)
    dist = (3.0, -4.0, 1.5)
    _run(coarse, 20.0, 100.0, 40.0, dt=0.01, dist=dist)
    _run(fine, 20.0, 100.0, 40.0, dt=0.001, dist=dist)
    a, b = coarse.state, fine.state
    assert math.hypot(a.x_m - b.x_m, a.y_m - b.y_m) < 1e-4
    assert abs(a.psi_rad - b.psi_rad) < 1e-5
    assert abs(a.psi_rad) > 3.0  # it really turned


# ------------------------------------------------------------ disturbances


def test_gauss_markov_stationary_std_and_correlation() -> None:
    sigma, tau, dt = 5.0, 2.0, 0.01
    gm = GaussMarkov(sigma, tau, NormalStream(np.random.default_rng(7)))
    n = 600_000
    xs = np.empty(n)
    for i in range(n):
        xs[i] = gm.step(dt)
    assert xs.std() == pytest.approx(sigma, rel=0.10)
    assert abs(xs.mean()) < 0.3 * sigma
    lag = round(tau / dt)
    rho = np.corrcoef(xs[:-lag], xs[lag:])[0, 1]
    assert rho == pytest.approx(math.exp(-1.0), abs=0.1)


def test_gauss_markov_starts_stationary_and_handles_any_step() -> None:
    # the first values across many independent processes already have std σ
    starts = [GaussMarkov(2.0, 10.0, NormalStream(np.random.default_rng(s))).value
              for s in range(4000)]
    assert float(np.std(starts)) == pytest.approx(2.0, rel=0.10)
    # irregular steps keep the variance (exact discretisation)
    gm = GaussMarkov(2.0, 1.0, NormalStream(np.random.default_rng(3)))
    steps = np.random.default_rng(4).uniform(0.001, 3.0, 50_000)
    xs = [gm.step(float(h)) for h in steps]
    assert float(np.std(xs)) == pytest.approx(2.0, rel=0.10)
    assert gm.step(0.0) == gm.value  # no time, no change


def test_normal_stream_blocks_are_seamless() -> None:
    a = NormalStream(np.random.default_rng(11), block=7)
    got = [a.next() for _ in range(30)]
    ref = []
    rng = np.random.default_rng(11)
    for _ in range(5):
        ref.extend(rng.standard_normal(7).tolist())
    assert got == ref[:30]


# ----------------------------------------------------------------- devices


def test_thruster_controller_watchdog() -> None:
    c = SimThrusterController(ThrusterParams())
    assert c.outputs(0.0) == (0.0, 0.0)  # nothing received yet
    assert c.on_command(1.0, 50.0, -120.0)
    assert c.outputs(1.0) == (50.0, -100.0)  # clamped
    assert c.outputs(1.49) == (50.0, -100.0)
    assert c.outputs(1.5) == (0.0, 0.0)  # 0.5 s without a valid command
    assert not c.on_command(1.6, math.nan, 10.0)  # invalid: ignored, does not feed the watchdog
    assert c.outputs(1.6) == (0.0, 0.0)
    assert c.on_command(2.0, 10.0, 10.0) and c.outputs(2.2) == (10.0, 10.0)


def test_world_stops_boat_without_commands() -> None:
    w = SimWorld(_quiet_world(), seed=1)
    for k in range(41):  # 2 s of commands at 20 Hz
        w.command(k * 0.05, 80.0, 80.0)
    w.advance_to(2.0 + 0.49)
    assert w.truth().u1_cmd == 80.0
    w.advance_to(2.0 + 0.5)
    assert w.truth().u1_cmd == 0.0
    w.advance_to(10.0)
    t = w.truth()
    assert abs(t.f1_n) < 1e-6 and abs(t.f2_n) < 1e-6 and t.u_mps < 0.2
    status = w.thruster_status_bytes(10.0).decode()
    assert status.startswith("$PZTHS,0.0,0.0,0,0,0.0,0.0*")


def test_thruster_status_model() -> None:
    c = SimThrusterController(ThrusterParams())
    c.on_command(0.0, 100.0, -100.0)
    line = c.status_sentence(0.1, 125.0, -75.0).decode().strip()
    body, cs = line[1:].split("*")
    assert int(cs, 16) == nmea_checksum(body)
    assert body == "PZTHS,100.0,-100.0,3000,-3000,20.0,20.0"
    line = c.status_sentence(0.1, 31.25, 0.0).decode()
    assert ",1500,0,2.5,0.0*" in line  # √(1/4)·3000 rpm, (1/4)^1.5·20 A


def _check(line: str) -> pynmea2.NMEASentence:
    assert line.startswith("$") and line[-3] == "*"
    body, cs = line[1:].split("*")
    assert int(cs, 16) == nmea_checksum(body)
    return pynmea2.parse(line, check=True)


def _lines(data: bytes) -> list[str]:
    assert data.endswith(b"\r\n")
    return data.decode("ascii").split("\r\n")[:-1]


@pytest.mark.parametrize("fix", ["rtk_fixed", "rtk_float", "dgps", "single"])
def test_gps_sentences_valid_and_within_5_sigma(fix: str) -> None:
    p = _quiet_world()
    p.gps.fix = fix
    p.gps.sentences = ["GGA", "RMC", "VTG"]
    p.current = CurrentParams(0.2, 90.0)
    w = SimWorld(p, seed=3)
    sigma = w.gps.sigma_m()
    n_gga = 0
    seen = set()
    for k in range(1, 301):  # 30 s at 10 Hz, turning at speed
        t = k * 0.1
        w.command(t, 90.0, 60.0)
        data = w.gps_bytes(t)
        truth = w.truth()
        for line in _lines(data):
            msg = _check(line)
            seen.add(msg.sentence_type)
            if msg.sentence_type == "GGA":
                n_gga += 1
                q = {"rtk_fixed": 4, "rtk_float": 5, "dgps": 2, "single": 1}[fix]
                assert msg.gps_qual == q
                assert len(msg.lat.split(".")[1]) == 8 and len(msg.lon.split(".")[1]) == 8
                n, e, _ = pymap3d.geodetic2ned(msg.latitude, msg.longitude, 0.0,
                                               LAT0, LON0, 0.0)
                assert abs(n - truth.x_m) < 5 * sigma and abs(e - truth.y_m) < 5 * sigma
                hh, mm, ss = msg.timestamp.hour, msg.timestamp.minute, msg.timestamp.second
                assert (hh, mm) == (10, 0) and ss == int(t)
            elif msg.sentence_type == "RMC":
                assert msg.status == "A" and msg.datestamp.isoformat() == "2026-06-01"
                sog = float(msg.spd_over_grnd) * 1852.0 / 3600.0
                assert abs(sog - math.hypot(truth.vn_mps, truth.ve_mps)) < 5 * 0.05 * 1.5
    assert n_gga == 300
    assert seen == {"GGA", "RMC", "VTG", "GST", "ZDA"}


def test_gps_precision_and_fix_jumps() -> None:
    p = _quiet_world()
    w = SimWorld(p, seed=5)
    # RTK fixed: mm-level scatter survives the 8-decimal minutes
    errs = []
    for k in range(1, 201):
        t = k * 0.1
        for line in _lines(w.gps_bytes(t)):
            if "GGA" in line:
                m = _check(line)
                n, _e, _ = pymap3d.geodetic2ned(m.latitude, m.longitude, 0.0, LAT0, LON0, 0.0)
                errs.append(n - w.truth().x_m)
    assert float(np.std(errs)) == pytest.approx(0.015, rel=0.25)
    # losing the fix: quality 0, empty position, RMC void
    w.set_fix("none")
    gga, rmc = _lines(w.gps_bytes(20.1))[:2]
    m = _check(gga)
    assert m.gps_qual == 0 and m.lat == "" and m.lon == ""
    assert _check(rmc).status == "V"
    # single point: the drifting bias shows as a jump away from the RTK scatter
    w.set_fix("single")
    w.gps_bytes(20.2)
    assert math.hypot(*w.gps.last_error_ne) > 0.1
    with pytest.raises(ValueError):
        w.set_fix("rtk_perfect")


def test_compass_sentences() -> None:
    p = _quiet_world()
    p.compass.xdr_every = 1  # XDR with every epoch, to check all three sentences
    w = SimWorld(p, seed=9)
    cp = p.compass
    bias_rot = math.degrees(w.compass.gyro_bias_rps) * 60.0
    assert abs(bias_rot) == pytest.approx(0.5 * 60.0)
    sig_rot = math.degrees(w.compass.gyro_sigma_rps) * 60.0
    assert sig_rot == pytest.approx(math.degrees(3.4e-4 * math.sqrt(10.0)) * 60.0)
    for k in range(1, 401):  # 20 s at 20 Hz
        t = k * 0.05
        w.command(t, 100.0, 30.0)
        hdg, rot, xdr = (_check(x) for x in _lines(w.compass_bytes(t)))
        truth = w.truth()
        assert hdg.sentence_type == "HDG" and hdg.talker == "HC"
        assert (float(hdg.variation), hdg.var_dir) == (2.0, "W")
        true_deg = float(hdg.heading) + (-2.0)  # true = magnetic + variation (east +)
        err = (true_deg - math.degrees(truth.psi_rad) - cp.bias_deg + 180.0) % 360.0 - 180.0
        assert abs(err) < 5 * cp.noise_deg + 0.05
        assert rot.talker == "TI" and rot.status == "A"
        err_rot = float(rot.rate_of_turn) - math.degrees(truth.r_rps) * 60.0 - bias_rot
        assert abs(err_rot) < 5 * sig_rot + 0.01
        assert xdr.talker == "YX"
        assert xdr.data[3] == "PTCH" and xdr.data[7] == "ROLL"
        assert abs(float(xdr.data[1])) < 5 * cp.pitch_noise_deg + 0.05
    assert math.degrees(w.truth().r_rps) > 5.0  # it turned clockwise the whole time


# ---------------------------------------------------------------- the world


def _script(w: SimWorld, seconds: float = 60.0) -> tuple[list[bytes], list[typing.Any]]:
    """Drive a world like the backend does: commands and compass at 20 Hz, GPS
    and thruster status at 10 Hz, a fix change, and a silence of the runtime."""
    out: list[bytes] = []
    truth = []
    for k in range(1, round(seconds * 20) + 1):
        t = k * 0.05
        if not 30.0 < t < 32.0:  # the runtime goes quiet for 2 s
            w.command(t, 70.0 + 30.0 * math.sin(0.1 * t), 70.0 - 30.0 * math.cos(0.07 * t))
        if k == 400:
            w.set_fix("rtk_float")
        if k == 800:
            w.set_fix("single")
        out.append(w.compass_bytes(t))
        if k % 2 == 0:
            out.append(w.gps_bytes(t))
            out.append(w.thruster_status_bytes(t))
            truth.append(w.truth())
    return out, truth


def test_determinism_same_seed_bit_identical() -> None:
    a_bytes, a_truth = _script(SimWorld(WorldParams(), seed=42))
    b_bytes, b_truth = _script(SimWorld(WorldParams(), seed=42))
    assert a_bytes == b_bytes
    assert a_truth == b_truth
    c_bytes, c_truth = _script(SimWorld(WorldParams(), seed=43))
    assert c_bytes != a_bytes
    assert c_truth != a_truth


def test_component_streams_are_independent() -> None:
    """Changing the GPS (fix mode, sentences) shifts neither the physics nor the
    compass; disabling the disturbance does not shift the sensors' noise."""
    base = WorldParams()
    other = WorldParams()
    other.gps.fix = "single"
    other.gps.sentences = ["GGA"]
    a, b = SimWorld(base, seed=1), SimWorld(other, seed=1)
    for k in range(1, 201):
        t = k * 0.05
        for w in (a, b):
            w.command(t, 60.0, 50.0)
            w.gps_bytes(t)
        assert a.compass_bytes(t) == b.compass_bytes(t)
        assert a.truth() == b.truth()
    calm = SimWorld(_quiet_world(), seed=1)
    windy = SimWorld(WorldParams(), seed=1)
    assert calm.compass.gyro_bias_rps == windy.compass.gyro_bias_rps
    assert calm.gps.last_error_ne == windy.gps.last_error_ne
    calm.gps_bytes(0.1)
    windy.gps_bytes(0.1)
    assert calm.gps.last_error_ne == windy.gps.last_error_ne


def test_advance_to_grid() -> None:
    p = _quiet_world()
    p.dt_s = 0.01
    w = SimWorld(p, seed=0)
    w.advance_to(0.3)
    assert w.k == 30  # 0.3 / 0.01 is 29.999… in floating point
    w.advance_to(0.355)
    assert w.k == 35 and w.truth().t_s == pytest.approx(0.35)
    w.advance_to(0.1)  # the past: no-op
    assert w.k == 35
    assert w.utc_epoch_s(0.0) == 1780308000.0  # 2026-06-01T10:00:00Z


def test_world_initial_state_from_params() -> None:
    p = _quiet_world(x_m=10.0, y_m=-5.0, heading_deg=90.0, u_mps=1.0)
    t = SimWorld(p, seed=0).truth()
    assert (t.x_m, t.y_m) == (10.0, -5.0)
    assert t.psi_rad == pytest.approx(math.pi / 2)
    assert t.ve_mps == pytest.approx(1.0) and t.vn_mps == pytest.approx(0.0, abs=1e-12)


# ------------------------------------------------------------ formatting


def test_ned_to_geodetic_matches_pymap3d() -> None:
    conv = NedToGeodetic(LAT0, LON0)
    for n, e, d in [(0.0, 0.0, 0.0), (1234.5, -987.6, 0.0), (-4000.0, 3000.0, -2.0),
                    (0.001, 0.001, 0.0)]:
        lat, lon, h = conv(n, e, d)
        rl, ro, rh = pymap3d.ned2geodetic(n, e, d, LAT0, LON0, 0.0)
        assert lat == pytest.approx(float(rl), abs=1e-11)
        assert lon == pytest.approx(float(ro), abs=1e-11)
        assert h == pytest.approx(float(rh), abs=1e-6)


def test_lat_lon_and_time_formatting() -> None:
    assert format_lat(41.185) == ("4111.10000000", "N")
    assert format_lat(-0.5) == ("0030.00000000", "S")
    assert format_lat(41.99999999999999) == ("4200.00000000", "N")  # carry into degrees
    assert format_lon(-8.705) == ("00842.30000000", "W")
    assert format_lon(179.0 + 59.999999994 / 60) == ("17959.99999999", "E")
    assert format_lon(179.0 + 59.999999996 / 60) == ("18000.00000000", "E")
    assert utc_fields(1780308000.0) == ("100000.00", utc_fields(1780308000.0)[1])
    tm, day = utc_fields(1780271999.996)  # 23:59:59.996 rounds into the next day
    assert tm == "000000.00" and day.isoformat() == "2026-06-01"


def test_world_params_schema_convention() -> None:
    """Every field: a default, a type the config loader walks, unit and doc; ranges
    contain the default."""
    allowed = {float, int, bool, str, list[float], list[str]}

    def walk(cls: type) -> None:
        hints = typing.get_type_hints(cls)
        obj = cls()
        for f in dataclasses.fields(cls):
            tp = hints[f.name]
            if dataclasses.is_dataclass(tp):
                assert f.default_factory is tp
                walk(tp)  # type: ignore[arg-type]
                continue
            assert tp in allowed, (cls.__name__, f.name, tp)
            assert "unit" in f.metadata and f.metadata["doc"], (cls.__name__, f.name)
            val = getattr(obj, f.name)
            if "min" in f.metadata:
                assert val >= f.metadata["min"], (cls.__name__, f.name)
            if "max" in f.metadata:
                assert val <= f.metadata["max"], (cls.__name__, f.name)
            if "choices" in f.metadata:
                assert val in f.metadata["choices"]
        validate = getattr(obj, "validate", None)
        if validate is not None:
            validate()

    walk(WorldParams)
    assert DisturbanceParams().tau_s == 2.0
    bad = WorldParams(start_utc="2026-06-01 10:00")
    with pytest.raises(ValueError, match="start_utc"):
        bad.validate()
