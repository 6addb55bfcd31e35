"""The water observer: current, speed through the water and thruster mismatch
from commands and ground velocity, against a hull that is not its model."""

from __future__ import annotations

import math

import numpy as np
import pytest

from zarco_core.messages import FixQuality, NavState
from zarco_core.vessel import VesselModel
from zarco_runtime.control.water_observer import WaterObserver

VM = VesselModel()
DT = 0.05


def _nav(t: float, vn: float, ve: float, psi: float, r: float) -> NavState:
    return NavState(t, 0.0, 0.0, vn, ve, psi, r, 0.0, 0.0, 41.0, -8.0, FixQuality.RTK_FIXED,
                    True, True)


def _run(current: tuple[float, float], mismatch: float, hull: float, seconds: float,
         seed: int = 1) -> tuple[WaterObserver, list[float]]:
    """A hull whose mass and damping are ``hull`` times the model's, with the
    thrusters mismatched by ``mismatch``, weaving along a square at ~0.5 m/s
    through ``current`` (NED, m/s), gusts on surge and sway and GPS velocity noise."""
    rng = np.random.default_rng(seed)
    ob = WaterObserver(VM, VM.thruster_lag_s)
    m_u = (VM.m_kg - VM.x_udot) * hull
    m_v = (VM.m_kg - VM.y_vdot) * hull
    u = v = 0.0
    x_act = n_act = 0.0
    gx = gy = 0.0
    a_g = math.exp(-DT / 2.0)
    err_u: list[float] = []
    t = 0.0
    while t < seconds:
        leg = int(t // 60.0)
        psi = leg * math.pi / 2.0 + 0.3 * math.sin(0.7 * t)   # tracking weave
        r = 0.3 * 0.7 * math.cos(0.7 * t)
        x_c = 30.0
        n_c = 25.0 * math.sin(0.7 * t + 1.0)                  # steering moments
        # the thrusters really give (1 ± Δ) f, through their lag
        x_real = x_c + mismatch * n_c / VM.b_m
        n_real = n_c + mismatch * VM.b_m * x_c
        x_act += (x_real - x_act) * DT / VM.thruster_lag_s
        n_act += (n_real - n_act) * DT / VM.thruster_lag_s
        gx = a_g * gx + 5.0 * math.sqrt(1 - a_g * a_g) * rng.standard_normal()
        gy = a_g * gy + 5.0 * math.sqrt(1 - a_g * a_g) * rng.standard_normal()
        u += DT * (hull * (VM.x_u * u + VM.x_uu * abs(u) * u) + x_act + gx) / m_u
        v += DT * (hull * VM.y_v * v - VM.m_kg * hull * u * r + gy) / m_v
        vn = u * math.cos(psi) - v * math.sin(psi) + current[0] + 0.02 * rng.standard_normal()
        ve = u * math.sin(psi) + v * math.cos(psi) + current[1] + 0.02 * rng.standard_normal()
        ob.step(_nav(t, vn, ve, psi, r), x_c, n_c, DT)
        if t > seconds - 60.0:
            err_u.append(ob.u_w - u)
        t += DT
    return ob, err_u


@pytest.mark.parametrize("hull", [0.75, 1.25])
def test_current_and_mismatch_against_a_hull_that_is_not_the_model(hull: float) -> None:
    ob, err_u = _run((0.25, -0.25), 0.1, hull, 240.0)
    assert ob.cn == pytest.approx(0.25, abs=0.04)
    assert ob.ce == pytest.approx(-0.25, abs=0.04)
    assert ob.mismatch == pytest.approx(0.1, abs=0.03)
    # the speed through the water within 15 % of 0.5 m/s over the last leg
    assert float(np.sqrt(np.mean(np.square(err_u)))) < 0.075


def test_no_mismatch_is_not_invented() -> None:
    ob, _ = _run((0.0, 0.3), 0.0, 1.0, 240.0, seed=2)
    assert abs(ob.mismatch) < 0.03
    assert math.hypot(ob.cn, ob.ce - 0.3) < 0.04


def test_commands_through_the_inverse_give_what_was_asked() -> None:
    ob = WaterObserver(VM, VM.thruster_lag_s)
    ob.x[4] = 0.12  # Δ
    for x, n in [(50.0, 20.0), (5.0, -40.0), (-30.0, 10.0)]:
        xa, na = ob.actual(*ob.command_for(x, n))
        assert xa == pytest.approx(x) and na == pytest.approx(n)
    # and a mismatch turns a pure yaw command into surge: X = Δ N / b
    assert ob.actual(0.0, 38.0)[0] == pytest.approx(0.12 * 38.0 / VM.b_m)


def test_invalid_navigation_only_predicts() -> None:
    ob = WaterObserver(VM, VM.thruster_lag_s)
    bad = NavState(0.0, 0.0, 0.0, math.nan, math.nan, math.nan, 0.0, 0.0, 0.0, 41.0, -8.0,
                   FixQuality.NONE, False, False)
    for _ in range(100):
        ob.step(bad, 50.0, 0.0, DT)
    assert ob.updates == 0
    assert all(math.isfinite(float(x)) for x in ob.x)
    assert ob.u_w > 0.1  # the model alone accelerated it
