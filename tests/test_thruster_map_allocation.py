"""f/f⁻¹ round trips and deadband; allocation split and saturation."""

from __future__ import annotations

import math

import pytest

from zarco_core.thruster_map import ThrusterMap
from zarco_runtime.control.allocation import allocate
from zarco_runtime.settings import DEFAULT_TABLE_F, DEFAULT_TABLE_U

M = ThrusterMap.from_table(DEFAULT_TABLE_U, DEFAULT_TABLE_F)
B = 0.38


@pytest.mark.parametrize("force", [0.5, 2.0, 10.0, 37.4, 80.0, 124.0, -0.5, -3.0, -30.0, -74.0])
def test_inverse_round_trip(force: float) -> None:
    u = M.inverse(force)
    assert abs(M.forward(u) - force) < 1e-9
    assert abs(u) > 5.0  # outside the deadband


@pytest.mark.parametrize("u", [-100, -63.2, -20, -5.001, 5.001, 12.5, 77.7, 100])
def test_forward_then_inverse(u: float) -> None:
    assert math.isclose(M.inverse(M.forward(u)), u, abs_tol=1e-9)


def test_deadband_and_zero() -> None:
    for u in (-5.0, -2.0, 0.0, 3.0, 5.0):
        assert M.forward(u) == 0.0
    assert M.inverse(0.0) == 0.0
    assert M.deadband() == (-5.0, 5.0)
    # the smallest forward thrust needs a command just above the deadband
    assert 5.0 < M.inverse(1e-6) < 5.01


def test_inverse_clamps_and_rejects_nan() -> None:
    assert M.inverse(1e6) == 100.0
    assert M.inverse(-1e6) == -100.0
    assert M.inverse(math.nan) == 0.0
    assert M.inverse(math.inf) == 0.0
    assert M.saturates(126.0) and M.saturates(-76.0) and not M.saturates(100.0)


def test_non_monotone_table_refused() -> None:
    with pytest.raises(ValueError, match="monotone"):
        ThrusterMap.from_table([-100, 0, 50, 100], [-75, 0, 60, 50])


def test_allocation_split_is_consistent_with_moment() -> None:
    a = allocate(100.0, 10.0, B, M, M)
    assert math.isclose(a.f1_n + a.f2_n, 100.0, abs_tol=1e-9)
    # N_act = b (F1 − F2): the split N/(2b) reproduces the demanded moment
    assert math.isclose(B * (a.f1_n - a.f2_n), 10.0, abs_tol=1e-9)
    assert not a.saturated
    assert a.u1 > a.u2 > 0


def test_saturation_keeps_yaw_and_cuts_surge() -> None:
    # full-speed demand plus a turn: the surge gives way, yaw is honoured
    a = allocate(250.0, 20.0, B, M, M)
    assert a.sat_x == 1 and a.sat_n == 0
    assert math.isclose(B * (a.f1_n - a.f2_n), 20.0, abs_tol=1e-9)
    assert a.f1_n <= 125.0 + 1e-9 and a.u1 == pytest.approx(100.0)
    assert a.x_n < 250.0


def test_moment_beyond_capacity_is_cut_and_flagged() -> None:
    # yaw first: all the pair can give, the surge rising to what that takes
    a = allocate(0.0, -500.0, B, M, M, surge_raise_max_n=math.inf)
    assert a.sat_n == -1
    assert a.f1_n == pytest.approx(-75.0) and a.f2_n == pytest.approx(125.0)
    assert -100.0 <= a.u1 <= 100.0 and -100.0 <= a.u2 <= 100.0


def test_differential_does_not_push_the_boat_ahead() -> None:
    # reverse is weaker than forward: at zero surge demand the full differential
    # would add 50 N ahead; by default the moment is cut instead
    a = allocate(0.0, -500.0, B, M, M)
    assert a.sat_n == -1
    assert a.x_n == pytest.approx(0.0, abs=1e-9)
    assert a.f1_n == pytest.approx(-75.0) and a.f2_n == pytest.approx(75.0)
    # a bounded raise is honoured exactly
    b = allocate(10.0, 500.0, B, M, M, surge_raise_max_n=20.0)
    assert b.sat_n == 1 and b.x_n == pytest.approx(30.0)
    # a moment the pair can give at the demanded surge is not touched
    c = allocate(100.0, 30.0, B, M, M)
    assert c.sat_n == 0 and c.n_nm == pytest.approx(30.0) and c.x_n == pytest.approx(100.0)
    # braking: the differential may bring the surge up to zero, not beyond
    d = allocate(-100.0, 60.0, B, M, M)
    assert d.x_n <= 1e-9 and d.n_nm > 0.0


@pytest.mark.parametrize("x,n", [(math.nan, 0.0), (0.0, math.inf), (-math.inf, math.nan)])
def test_nonfinite_demand_gives_zero(x: float, n: float) -> None:
    a = allocate(x, n, B, M, M)
    assert (a.u1, a.u2) == (0.0, 0.0)
    assert a.fault
