"""The reference thruster map f of the Zarco's thrusters and its calibration table."""

from __future__ import annotations

import itertools
import math

import pytest

from drivers.sim.params import ThrusterParams
from drivers.sim.thruster_model import nominal_table, nominal_thrust, thruster_thrust
from zarco_core.thruster_map import ThrusterMap

P = ThrusterParams()


def test_deadband() -> None:
    for u in (0.0, 1.0, -1.0, 4.99, -4.99, 5.0, -5.0):
        assert nominal_thrust(u, P) == 0.0
    assert 0.0 < nominal_thrust(5.01, P) < 0.01
    assert -0.01 < nominal_thrust(-5.01, P) < 0.0
    wide = ThrusterParams(deadband=10.0)
    assert nominal_thrust(9.9, wide) == 0.0 and nominal_thrust(10.1, wide) > 0.0


def test_values_at_reference_points() -> None:
    assert nominal_thrust(100.0, P) == pytest.approx(125.0)
    assert nominal_thrust(-100.0, P) == pytest.approx(-75.0)
    # U = 52.5: s = 0.5, g = 0.3·0.5 + 0.7·0.25 = 0.325
    assert nominal_thrust(52.5, P) == pytest.approx(125.0 * 0.325)
    assert nominal_thrust(-52.5, P) == pytest.approx(-75.0 * 0.325)
    assert nominal_thrust(10.0, P) == pytest.approx(2.216, abs=1e-3)


def test_reverse_asymmetry_and_convexity() -> None:
    for u in (6.0, 20.0, 52.5, 80.0, 100.0):
        assert nominal_thrust(-u, P) == pytest.approx(-0.6 * nominal_thrust(u, P))
    # convex on the forward branch: the midpoint lies below the chord
    lo, hi = nominal_thrust(20.0, P), nominal_thrust(100.0, P)
    assert nominal_thrust(60.0, P) < 0.5 * (lo + hi)


def test_clamp_and_non_finite() -> None:
    assert nominal_thrust(150.0, P) == pytest.approx(125.0)
    assert nominal_thrust(-1e9, P) == pytest.approx(-75.0)
    for bad in (math.nan, math.inf, -math.inf):
        assert nominal_thrust(bad, P) == 0.0


def test_mismatch_per_thruster() -> None:
    p = ThrusterParams(mismatch=0.1)
    assert thruster_thrust(100.0, p, 1) == pytest.approx(137.5)
    assert thruster_thrust(100.0, p, 2) == pytest.approx(112.5)
    assert thruster_thrust(-100.0, p, 1) == pytest.approx(-82.5)


def test_table_monotone_with_deadband_edges() -> None:
    us, fs = nominal_table(P)
    assert len(us) == len(fs)
    assert all(b > a for a, b in itertools.pairwise(us))
    assert all(b >= a for a, b in itertools.pairwise(fs))
    for u in (-100.0, -5.0, 0.0, 5.0, 100.0):
        assert u in us
    assert fs[us.index(-5.0)] == fs[us.index(0.0)] == fs[us.index(5.0)] == 0.0
    assert fs[0] == -75.0 and fs[-1] == 125.0
    assert not any(math.copysign(1.0, f) < 0 for f, u in zip(fs, us, strict=True) if u >= 0)
    # the runtime's f / f⁻¹ accepts it and reproduces f at and between the points
    m = ThrusterMap.from_table(us, fs)
    assert m.deadband() == (-5.0, 5.0)
    for u in us:
        assert m.forward(u) == pytest.approx(nominal_thrust(u, P), abs=1e-3)
    assert m.forward(52.5) == pytest.approx(nominal_thrust(52.5, P), rel=0.02)
    assert m.inverse(m.forward(70.0)) == pytest.approx(70.0, abs=1e-6)


def test_table_custom_points_and_precision() -> None:
    us, fs = nominal_table(P, points=[-150.0, 50.0, 50.0, 52.5, math.nan], decimals=None)
    assert us == [-100.0, -5.0, 0.0, 5.0, 50.0, 52.5, 100.0]
    assert fs[5] == nominal_thrust(52.5, P)


def test_table_matches_runtime_default() -> None:
    """The runtime's default table (zarco_runtime.settings) is sampled from this f."""
    from zarco_runtime.settings import DEFAULT_TABLE_F, DEFAULT_TABLE_U

    us, fs = nominal_table(P)
    for u, f in zip(DEFAULT_TABLE_U, DEFAULT_TABLE_F, strict=True):
        assert fs[us.index(u)] == pytest.approx(f, abs=1.5e-3)
