"""RLS on the line model: recovery, conditioning at epoch times, forgetting, turns."""

from __future__ import annotations

import math

import numpy as np
import pytest

from zarco_runtime.tracking.rls import LineRls

EPOCH = 1_780_308_000.0


def _line(t: float, t0: float = 0.0) -> tuple[float, float]:
    """The true line: (120, −40) at t0, moving at (0.6, −0.8) m/s (1 m/s, course −53°)."""
    return 120.0 + 0.6 * (t - t0), -40.0 + -0.8 * (t - t0)


def _times(t_start: float, n: int, seed: int = 0) -> list[float]:
    """Irregular fix times (1.2–4 s apart), as missed cycles make them."""
    rng = np.random.default_rng(seed)
    out = [t_start]
    for _ in range(n - 1):
        out.append(out[-1] + float(rng.uniform(1.2, 4.0)))
    return out


@pytest.mark.parametrize("t_start", [0.0, EPOCH])
def test_noise_free_line_is_recovered_exactly(t_start: float) -> None:
    rls = LineRls(0.98)
    ts = _times(t_start, 40)
    rls.reset(ts[0], *_line(ts[0], t_start), 0.0, 0.0, 1e8, 1e8)  # diffuse start
    for t in ts[1:]:
        rls.update(t, *_line(t, t_start), sigma_m=1.0)
    x, y = _line(ts[-1], t_start)
    assert rls.t0 == ts[-1]  # the origin is re-centred at the last update
    assert rls.x0 == pytest.approx(x, abs=1e-6) and rls.y0 == pytest.approx(y, abs=1e-6)
    assert rls.vx == pytest.approx(0.6, abs=1e-8) and rls.vy == pytest.approx(-0.8, abs=1e-8)


def test_noisy_line_at_epoch_times_matches_the_small_time_fit() -> None:
    """The same data at t ≈ 0 and at t ≈ 1.78e9 s give the same estimate: the
    re-centred origin makes the problem independent of the time offset."""
    rng = np.random.default_rng(7)
    noise = rng.normal(0.0, 1.0, size=(60, 2))
    ests = []
    for t_start in (0.0, EPOCH):
        rls = LineRls(0.97)
        ts = _times(t_start, 60, seed=3)
        for (t, (nx, ny)) in zip(ts, noise, strict=True):
            x, y = _line(t, t_start)
            rls.update(t, x + nx, y + ny, sigma_m=1.0)
        ests.append((rls.x0, rls.y0, rls.vx, rls.vy, rls.p00, rls.p01, rls.p11))
        assert abs(rls.vx - 0.6) < 0.1 and abs(rls.vy + 0.8) < 0.1
        assert math.hypot(rls.x0 - _line(ts[-1], t_start)[0],
                          rls.y0 - _line(ts[-1], t_start)[1]) < 2.0
        # P stays symmetric positive definite and well conditioned
        P = np.array([[rls.p00, rls.p01], [rls.p01, rls.p11]])
        assert np.all(np.linalg.eigvalsh(P) > 0.0) and np.linalg.cond(P) < 1e4
    assert ests[0] == pytest.approx(ests[1], rel=1e-6, abs=1e-6)


def test_raw_epoch_regressor_would_be_singular() -> None:
    """Why the origin is re-centred: with φ = [1, t] at t ≈ 1.78e9 s the normal
    matrix of a few minutes of fixes is numerically singular."""
    ts = np.array(_times(EPOCH, 60))
    phi = np.stack([np.ones_like(ts), ts], axis=1)
    assert np.linalg.cond(phi.T @ phi) > 1e15
    phi_c = np.stack([np.ones_like(ts), ts - ts[-1]], axis=1)
    assert np.linalg.cond(phi_c.T @ phi_c) < 1e5


def test_matches_weighted_batch_least_squares() -> None:
    """With forgetting λ per second the RLS equals batch LS weighted by λ^age
    (a diffuse start makes the prior negligible)."""
    rng = np.random.default_rng(11)
    lam = 0.95
    ts = _times(EPOCH, 30, seed=5)
    pts = [(t, *_line(t, EPOCH)) for t in ts]
    pts = [(t, x + rng.normal(0, 0.5), y + rng.normal(0, 0.5)) for t, x, y in pts]
    rls = LineRls(lam)
    rls.reset(ts[0], pts[0][1], pts[0][2], 0.0, 0.0, 1e8, 1e8, 0.0, 1.0)
    for t, x, y in pts[1:]:
        rls.update(t, x, y, sigma_m=1.0)
    tl = ts[-1]
    w = np.array([lam ** (tl - t) for t, _, _ in pts[1:]])  # the first one is the prior
    A = np.stack([np.ones(len(ts) - 1), np.array(ts[1:]) - tl], axis=1)
    W = np.diag(w)
    for k, est in ((1, (rls.x0, rls.vx)), (2, (rls.y0, rls.vy))):
        b = np.array([p[k] for p in pts[1:]])
        sol = np.linalg.solve(A.T @ W @ A, A.T @ W @ b)
        assert est == pytest.approx(tuple(sol), abs=1e-4)


def test_time_based_forgetting_inflates_by_lambda_power_dt() -> None:
    rls = LineRls(0.9)
    rls.reset(0.0, 0.0, 0.0, 1.0, 0.0, 1.0, 0.25, 0.0, 1.0)
    rls.shift(3.0)
    # P ← A P Aᵀ / λ^Δt with A = [[1, 3], [0, 1]]
    assert rls.p11 == pytest.approx(0.25 / 0.9**3)
    assert rls.p01 == pytest.approx(3 * 0.25 / 0.9**3)
    assert rls.p00 == pytest.approx((1.0 + 9 * 0.25) / 0.9**3)
    assert rls.x0 == pytest.approx(3.0)  # moved along the line


def test_turn_is_detected_and_straight_noisy_lines_are_not() -> None:
    rng = np.random.default_rng(1)
    rls = LineRls(0.97, cusum_drift=2.0, cusum_threshold=8.0, holdoff_s=4.0)
    t = EPOCH
    x = y = 0.0
    sigma = 0.7
    for _ in range(300):  # 10 minutes on a straight line at 1 m/s: no alarm
        t += 2.0
        x += 2.0
        assert not rls.update(t, x + rng.normal(0, sigma), y + rng.normal(0, sigma), sigma)
    # a 90° turn to starboard (east) at 10°/s, then a straight line east
    psi = 0.0
    detected_at = None
    for k in range(30):
        t += 2.0
        psi = min(psi + math.radians(20.0), math.pi / 2)
        x += 2.0 * math.cos(psi)
        y += 2.0 * math.sin(psi)
        if rls.update(t, x + rng.normal(0, sigma), y + rng.normal(0, sigma), sigma):
            detected_at = k
            break
    assert detected_at is not None and detected_at <= 6  # within ~12 s of the turn start


def test_reset_and_covariance_layout() -> None:
    rls = LineRls()
    rls.reset(10.0, 1.0, 2.0, 0.5, -0.5, var_pos=4.0, var_vel=0.01, cov_pv=0.1, sigma_m=2.0)
    cov = rls.covariance()
    assert len(cov) == 16
    m = np.array(cov).reshape(4, 4)
    assert np.allclose(m, m.T)
    assert m[0, 0] == pytest.approx(4.0) and m[2, 2] == pytest.approx(0.01)
    assert m[0, 2] == pytest.approx(0.1) and m[1, 3] == pytest.approx(0.1)
    assert m[0, 1] == 0.0 and m[0, 3] == 0.0
    assert rls.position(12.0) == pytest.approx((2.0, 1.0))
