"""The continuous-discrete EKF core (Balaram 2000 sec. 3) equals a linear Kalman filter on a
linear model, and its discretisation is the exact one."""

import numpy as np
from scipy.linalg import expm

from estimation.fusion import ekf_core


def _linear_kf(x, P, Phi, Qd, H, R, y):
    """The textbook linear Kalman filter, written independently of ekf_core."""
    x = Phi @ x
    P = Phi @ P @ Phi.T + Qd
    S = H @ P @ H.T + R
    K = P @ H.T @ np.linalg.inv(S)
    return x + K @ (y - H @ x), (np.eye(len(x)) - K @ H) @ P


def test_ekf_equals_the_linear_kalman_filter_on_a_linear_model() -> None:
    # A constant-acceleration model: F is nilpotent, so RK4 on f(x) = F x is exact and
    # the EKF's mean must equal exp(F dt) x to rounding.
    rng = np.random.default_rng(7)
    F = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, 0.0]])
    Q = np.diag([0.0, 0.0, 0.3])
    H = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    R = np.diag([0.5, 0.2])
    dt = 0.125
    Phi = expm(F * dt)
    q = Q[2, 2]  # the exact Qd of white jerk noise (Bar-Shalom, Li and Kirubarajan 6.2)
    Qd = q * np.array(
        [
            [dt**5 / 20, dt**4 / 8, dt**3 / 6],
            [dt**4 / 8, dt**3 / 3, dt**2 / 2],
            [dt**3 / 6, dt**2 / 2, dt],
        ]
    )
    x_ekf = x_kf = np.array([1.0, -0.5, 0.2])
    P_ekf = P_kf = np.diag([1.0, 0.5, 0.1])
    for _ in range(40):
        y = rng.normal(size=2)
        x_ekf, P_ekf = ekf_core.propagate(x_ekf, P_ekf, lambda x: F @ x, F, Q, dt)
        x_ekf, P_ekf, _ = ekf_core.update(x_ekf, P_ekf, y - H @ x_ekf, H, R)
        x_kf, P_kf = _linear_kf(x_kf, P_kf, Phi, Qd, H, R, y)
    np.testing.assert_allclose(x_ekf, x_kf, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(P_ekf, P_kf, rtol=1e-9, atol=1e-14)


def _integral_qd(F, Q, dt, n=4000):
    """∫ exp(F s) Q exp(F s)ᵀ ds by the midpoint rule (independent of Van Loan)."""
    s = (np.arange(n) + 0.5) * dt / n
    return sum(expm(F * si) @ Q @ expm(F * si).T for si in s) * dt / n


def test_van_loan_discretisation_matches_the_integral() -> None:
    F = np.array([[-0.5, 1.0], [0.0, -2.0]])
    Q = np.diag([0.1, 0.4])
    Phi, Qd = ekf_core.discretise(F, Q, 0.3)
    np.testing.assert_allclose(Phi, expm(F * 0.3), rtol=1e-13)
    np.testing.assert_allclose(Qd, _integral_qd(F, Q, 0.3), rtol=1e-6)


def test_taylor_exponential_matches_scipy() -> None:
    A = np.random.default_rng(3).normal(size=(12, 12))
    for scale in (1e-3, 0.2, 5.0):
        np.testing.assert_allclose(ekf_core.expm_taylor(A * scale), expm(A * scale), rtol=1e-11)


def test_update_rejects_a_mismatched_jacobian() -> None:
    import pytest

    with pytest.raises(ValueError, match="H must be"):
        ekf_core.update(np.zeros(3), np.eye(3), np.zeros(2), np.zeros((2, 2)), np.eye(2))
