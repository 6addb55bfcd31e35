"""The plain-Python constant-velocity Kalman filter against a numpy reference."""

from __future__ import annotations

import math

import numpy as np
import pytest

from zarco_runtime.tracking.kalman import CvKalman

EPOCH = 1_780_308_000.0


def _ref_predict(x: np.ndarray, P: np.ndarray, q: float, dt: float) -> tuple[np.ndarray, ...]:
    F = np.eye(4)
    F[0, 2] = F[1, 3] = dt
    Q = q * np.array([[dt**3 / 3, 0, dt**2 / 2, 0], [0, dt**3 / 3, 0, dt**2 / 2],
                      [dt**2 / 2, 0, dt, 0], [0, dt**2 / 2, 0, dt]])
    return F @ x, F @ P @ F.T + Q


def _ref_update(x: np.ndarray, P: np.ndarray, H: np.ndarray, z: np.ndarray,
                R: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    S = H @ P @ H.T + R
    nu = z - H @ x
    K = P @ H.T @ np.linalg.inv(S)
    return x + K @ nu, P - K @ S @ K.T, float(nu @ np.linalg.solve(S, nu))


def _state(kf: CvKalman) -> tuple[np.ndarray, np.ndarray]:
    return np.array(kf.x), np.array(kf.P)


@pytest.mark.parametrize("m", [1, 2])
def test_matches_numpy_reference(m: int) -> None:
    rng = np.random.default_rng(m)
    kf = CvKalman(0.01)
    kf.init(EPOCH, 10.0, -5.0, 0.8, 0.3, 9.0, 0.5)
    x, P = _state(kf)
    t = EPOCH
    for _ in range(50):
        dt = float(rng.uniform(0.5, 4.0))
        t += dt
        kf.predict(t)
        x, P = _ref_predict(x, P, 0.01, dt)
        assert kf.t == t
        H = rng.normal(size=(m, 2))
        H /= np.linalg.norm(H, axis=1, keepdims=True)
        Hf = np.hstack([H, np.zeros((m, 2))])
        z = Hf @ x + rng.normal(0.0, 0.7, size=m)
        var = list(rng.uniform(0.2, 2.0, size=m))
        ok, d2 = kf.update([tuple(r) for r in H], list(z), var)
        x, P, d2_ref = _ref_update(x, P, Hf, z, np.diag(var))
        assert ok and d2 == pytest.approx(d2_ref, rel=1e-6, abs=1e-6)
        got_x, got_P = _state(kf)
        assert got_x == pytest.approx(x, rel=1e-6, abs=1e-6)
        assert got_P == pytest.approx(P, rel=1e-5, abs=1e-8)
        assert np.allclose(got_P, got_P.T)


def test_predicted_matches_predict_and_changes_nothing() -> None:
    kf = CvKalman(0.02)
    kf.init(EPOCH, 1.0, 2.0, 0.5, -0.25, 4.0, 0.3)
    px, py, pxx, pxy, pyy = kf.predicted(EPOCH + 3.0)
    assert kf.t == EPOCH and kf.x == [1.0, 2.0, 0.5, -0.25]
    kf.predict(EPOCH + 3.0)
    assert (px, py) == pytest.approx((kf.x[0], kf.x[1]))
    assert (pxx, pxy, pyy) == pytest.approx((kf.P[0][0], kf.P[0][1], kf.P[1][1]))
    kf.predict(EPOCH + 1.0)  # backwards: a no-op
    assert kf.t == EPOCH + 3.0


def test_gate_refuses_and_soft_gate_down_weights() -> None:
    def fresh() -> CvKalman:
        kf = CvKalman(0.01)
        kf.init(EPOCH, 0.0, 0.0, 0.0, 0.0, 1.0, 0.1)
        return kf

    rows = [(1.0, 0.0), (0.0, 1.0)]
    kf = fresh()
    ok, d2 = kf.update(rows, [10.0, 0.0], [1.0, 1.0], gate_chi2=16.0)
    assert not ok and d2 == pytest.approx(50.0) and kf.x == [0.0, 0.0, 0.0, 0.0]
    hard, soft = fresh(), fresh()
    hard.update(rows, [3.0, 0.0], [1.0, 1.0], gate_chi2=16.0)
    ok, d2 = soft.update(rows, [3.0, 0.0], [1.0, 1.0], gate_chi2=16.0, soft_chi2=4.0)
    assert ok and d2 == pytest.approx(4.5)
    assert 0.0 < soft.x[0] < hard.x[0]  # the outlier moves the state less
    # the soft update is the plain one with the variance scaled by d²/4
    ref = fresh()
    ref.update(rows, [3.0, 0.0], [4.5 / 4.0, 4.5 / 4.0])
    assert soft.x == pytest.approx(ref.x)


def test_degenerate_rows_are_refused_not_raised() -> None:
    kf = CvKalman(0.01)
    kf.init(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    ok, d2 = kf.update([(0.0, 0.0)], [1.0], [0.0])
    assert not ok and math.isinf(d2)
    with pytest.raises(ValueError):
        kf.update([(1.0, 0.0)] * 3, [0.0] * 3, [1.0] * 3)
