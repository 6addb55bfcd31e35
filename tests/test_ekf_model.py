"""Navigation EKF with the thruster commands as its prediction input: the vessel
model's steady states, the command time line (freshness, late measurements), the
start from rest, and the heading it gives in the whole runtime against the
simulator's truth (the rectangle's first leg, at CI size)."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Any

import pytest

from zarco_core.geodesy import LocalFrame
from zarco_core.localgeo import FastLocalFrame
from zarco_core.messages import (
    FixQuality,
    GpsErrorStats,
    GpsFix,
    GpsVelocity,
    Heading,
    RateOfTurn,
    ThrusterCommand,
)
from zarco_core.thruster_map import ThrusterMap
from zarco_core.vessel import DEFAULT_TABLE_F, DEFAULT_TABLE_U, VesselModel
from zarco_runtime.navigation.ekf import EkfNavigator
from zarco_runtime.navigation.ekf_config import EkfSettings
from zarco_tools.ekf_eval import Case, run
from zarco_tools.scenario import load_scenario
from zarco_tools.simulation import run_scenario

LAT0, LON0 = 41.185, -8.705
FRAME = LocalFrame(LAT0, LON0)
GEO = FastLocalFrame(LAT0, LON0)
TMAP = ThrusterMap.from_table(DEFAULT_TABLE_U, DEFAULT_TABLE_F)
VESSEL = VesselModel()


def nav(**overrides: Any) -> EkfNavigator:
    n = EkfNavigator(dataclasses.replace(EkfSettings(), **overrides), FRAME)
    n.set_vessel(VESSEL, TMAP, TMAP)
    return n


def hdg(t: float, psi: float) -> Heading:
    return Heading(t, "compass", "HDG", psi % math.tau, True, math.degrees(psi) % 360.0)


def commands_only(n: EkfNavigator, u1: float, u2: float, t_end: float, psi: float = 0.0
                  ) -> None:
    """Thruster commands at 20 Hz with a heading and no gyro or GPS: the surge speed
    and yaw rate are the model's alone."""
    k = 0
    while 0.05 * k <= t_end + 1e-9:
        t = 0.05 * k
        n.on_command(ThrusterCommand(t, u1, u2))
        if k == 0:
            n.on_heading(hdg(t, psi))
        k += 1


def test_surge_settles_at_the_models_steady_speed() -> None:
    """Both thrusters at 50: 2·f(50) = X_u u + X_|u|u u² gives the speed through the
    water the prediction settles at (no GPS to correct it)."""
    n = nav()
    commands_only(n, 50.0, 50.0, 15.0)
    f = TMAP.forward(50.0)
    a, b, c = -VESSEL.x_uu, -VESSEL.x_u, -2.0 * f
    u_ss = (-b + math.sqrt(b * b - 4.0 * a * c)) / (2.0 * a)
    st = n.status(15.0)
    assert st.thrust_model
    assert st.state["u_water_mps"] == pytest.approx(u_ss, abs=0.005)
    assert abs(st.state["r_rps"]) < 1e-6  # equal thrusts: no turn


def test_differential_thrust_turns_at_the_models_rate() -> None:
    """40 / 20: the yaw rate settles where N_r r + N_|r|r r² balances b·(F1 − F2)
    (port stronger: clockwise, r > 0)."""
    n = nav()
    commands_only(n, 40.0, 20.0, 15.0)
    moment = VESSEL.b_m * (TMAP.forward(40.0) - TMAP.forward(20.0))
    a, b = -EkfSettings().yaw_damping_quad, -VESSEL.n_r
    r_ss = (-b + math.sqrt(b * b + 4.0 * a * moment)) / (2.0 * a)
    st = n.status(15.0)
    assert st.state["r_rps"] == pytest.approx(r_ss, rel=0.01)
    assert r_ss > 0.05


def test_without_commands_the_model_falls_back() -> None:
    n = nav(command_timeout_s=0.5)
    commands_only(n, 50.0, 50.0, 5.0)
    assert n.status(5.2).thrust_model and not n.status(5.6).thrust_model
    u = n.status(5.6).state["u_water_mps"]
    assert n.status(10.0).state["u_water_mps"] == pytest.approx(u, abs=1e-9)  # held


def _recorded(duration: float) -> list[Any]:
    """Messages of a short simulated run with the pilot's commands, in arrival order."""
    msgs: list[Any] = []

    def keep(m: Any, _t: float) -> Any:
        msgs.append(m)
        return m

    r = run(Case(duration_s=duration, tamper=keep))
    # the commands the pilot gave (ekf_eval hands them straight to the filter)
    cmds = [ThrusterCommand(s.t, s.u1, s.u2) for s in r.samples]
    return sorted(msgs + cmds, key=lambda m: m.t)


HANDLERS = {GpsFix: "on_fix", GpsVelocity: "on_velocity", GpsErrorStats: "on_gst",
            Heading: "on_heading", RateOfTurn: "on_rate", ThrusterCommand: "on_command"}


def _feed(n: EkfNavigator, msgs: list[Any]) -> None:
    for m in msgs:
        name = HANDLERS.get(type(m))
        if name is not None:
            getattr(n, name)(m)


def test_late_gps_with_commands_gives_the_in_order_result() -> None:
    """GPS 0.3 s late (its latency configured) among commands and compass readings
    that come in time: the same estimate as in-order arrival, to rounding; the
    commands, an input, are never re-run."""
    msgs = _recorded(30.0)
    gps = (GpsFix, GpsVelocity, GpsErrorStats)
    late = sorted((dataclasses.replace(m, t=m.t + 0.3) if isinstance(m, gps) else m
                   for m in msgs), key=lambda m: m.t)
    a, b = nav(), nav(gps_latency_s=0.3)
    _feed(a, msgs)
    _feed(b, late)
    t = late[-1].t
    sa, sb = a.state(t), b.state(t)
    assert b.counters["replays"] > 200 and "late_dropped" not in b.counters
    for f in ("x_m", "y_m", "vn_mps", "ve_mps", "psi_rad", "r_rps"):
        assert getattr(sb, f) == pytest.approx(getattr(sa, f), abs=1e-9), f
    assert sb.cov == pytest.approx(sa.cov, rel=1e-9, abs=1e-15)


def test_a_boat_at_rest_measures_the_current() -> None:
    """Thrusters stopped, the GPS says 0.3 m/s east: with the thrust model that is the
    water carrying the boat (a current), not the boat's own speed."""
    n = nav()
    for k in range(20):
        t = 0.05 * k
        n.on_command(ThrusterCommand(t, 0.0, 0.0))
        n.on_heading(hdg(t, 0.0))
        n.on_rate(RateOfTurn(t, "compass", 0.0))
        if k % 2 == 0:
            lat, lon, _h = GEO.to_geodetic(0.0, 0.3 * t)
            n.on_fix(GpsFix(t, "gps", "GGA", "GN", FixQuality.RTK_FIXED, lat, lon, 0.0,
                            utc_s=36000.0 + t, num_sats=14))
            n.on_velocity(GpsVelocity(t, "gps", "RMC", 0.3, math.pi / 2, 36000.0 + t))
    st = n.status(0.95)
    assert st.state["current_e_mps"] == pytest.approx(0.3, abs=0.03)
    assert st.sigma["current_e_mps"] < 0.05 and st.sigma["current_n_mps"] < 0.06
    assert abs(st.state["u_water_mps"]) < 0.03
    # without the thrust model the same data leave the along-heading current open
    m = EkfNavigator(EkfSettings(), FRAME)
    for k in range(20):
        t = 0.05 * k
        m.on_heading(hdg(t, 0.0))
        m.on_rate(RateOfTurn(t, "compass", 0.0))
        if k % 2 == 0:
            m.on_velocity(GpsVelocity(t, "gps", "RMC", 0.3, math.pi / 2, 36000.0 + t))
    assert m.status(0.95).sigma["current_n_mps"] > 2.0 * st.sigma["current_n_mps"]


RECT = "config/scenarios/rectangle.toml"
#: the first leg (100 m north) of the rectangle at 1 m/s, current 0.3 m/s across it,
#: thrusters misaligned ±3° and mismatched by 10 %, on a seed nobody tuned on
FIRST_LEG = ["mission.speed_mps=1.0", "scenario.max_duration_s=95",
             "world.current.speed_mps=0.3", "world.thrusters.phi1_deg=3.0",
             "world.thrusters.phi2_deg=-3.0", "world.thrusters.mismatch=0.1"]


@pytest.mark.parametrize("seed", [11])
def test_heading_on_the_first_leg_from_rest(seed: int) -> None:
    """The runtime on the rectangle's first leg from rest, in a cross current: the
    EKF with the thruster commands holds the heading within 1.0° RMS (the filter
    without them, the first estimate's problem case, is clearly worse), and its
    covariance is not overconfident (NEES of 5 dof about 5, well under χ²₅'s tail)."""
    root = Path(__file__).resolve().parents[1]
    rep = run_scenario(load_scenario(root / RECT, FIRST_LEG, seed)).report
    off = run_scenario(load_scenario(root / RECT, [*FIRST_LEG, "runtime.ekf.thrust_model=false"],
                                     seed)).report
    assert rep["nav_heading_first_leg_rms_deg"] <= 1.0
    assert off["nav_heading_first_leg_rms_deg"] > 1.5 * rep["nav_heading_first_leg_rms_deg"]
    assert 1.5 <= rep["nav_nees_mean"] <= 12.0
    assert rep["xtrack_rms_m"] < 0.06


def test_the_joint_update_inverse_handles_any_number_of_rows() -> None:
    """Five or more measurement rows of one instant (GPS position, velocity and a
    heading together) fall back from the closed forms to a general inverse."""
    import numpy as np

    from zarco_runtime.navigation.ekf.updates import spd_inverse as _spd_inverse

    rng = np.random.default_rng(3)
    for n in range(1, 8):
        m = rng.normal(size=(n, n))
        a = m @ m.T + n * np.eye(n)
        inv = np.array(_spd_inverse(a.tolist()))
        assert np.allclose(inv @ a, np.eye(n), atol=1e-9), n
