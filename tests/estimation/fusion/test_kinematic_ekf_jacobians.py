"""Every Jacobian of the kinematic EKF (Balaram 2000, eqs. 1-20) against finite differences.

The attitude columns are checked against the *exact* rotation model: perturbing the
reference attitude to ``q0 ⊗ δq(θ)`` (eq. 5, error on the right, body axes), so a sign or
side mistake in the small-angle algebra fails here.
"""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from estimation.fusion.kinematic.attitude_sensors import (
    HEADING_GYRO,
    THREE_AXIS_GYRO,
    gyro_measurement,
    sun_measurement,
)
from estimation.fusion.kinematic.process import Layout, ProcessParams, dynamics, jacobian
from estimation.fusion.kinematic.slip_constraint import JointRates, slip_constraint

EPS = 1e-6


def _fd(fun, x0, eps=EPS):
    cols = []
    for j in range(x0.size):
        e = np.zeros_like(x0)
        e[j] = eps
        cols.append((fun(x0 + e) - fun(x0 - e)) / (2 * eps))
    return np.column_stack(cols)


def _random_state(rng, n_bias=0):
    L = Layout(n_bias)
    X = np.zeros(L.n)
    X[L.THETA] = rng.normal(0.0, 0.01, 3)
    X[L.OMEGA_P] = rng.normal(0.0, 0.05, 3)
    X[L.X] = rng.normal(0.0, 1.0, 3)
    X[L.V_P] = rng.normal(0.0, 0.01, 3)
    X[L.XI] = rng.normal(0.0, 0.2, 6)
    X[L.bias] = rng.normal(0.0, 1e-4, n_bias)
    return X


@pytest.mark.parametrize("n_bias", [0, 3])
def test_process_jacobian(n_bias: int) -> None:
    rng = np.random.default_rng(1)
    X = _random_state(rng, n_bias)
    R0 = Rotation.random(random_state=2).as_matrix()
    v_c, w_c, p = np.array([0.0375, 0.0, 0.0]), np.array([0.0, 0.0, 0.03]), ProcessParams()
    F = jacobian(X, R0, v_c, w_c, p)
    np.testing.assert_allclose(F, _fd(lambda x: dynamics(x, R0, v_c, w_c, p), X), atol=1e-8)


def test_position_rate_follows_the_exact_rotation() -> None:
    # ẋ's θ columns against R(q0 ⊗ δq(θ)) v with θ in body axes (eqs. 1, 5).
    q0 = Rotation.random(random_state=4)
    v = np.array([0.0375, 0.002, -0.001])
    L = Layout()
    X = np.zeros(L.n)
    F = jacobian(X, q0.as_matrix(), v, np.zeros(3), ProcessParams())
    exact = _fd(lambda th: (q0 * Rotation.from_rotvec(th)).apply(v), np.zeros(3))
    np.testing.assert_allclose(F[L.X, L.THETA], exact, atol=1e-9)


@pytest.mark.parametrize("B_g", [HEADING_GYRO, THREE_AXIS_GYRO])
def test_gyro_jacobian(B_g: np.ndarray) -> None:
    rng = np.random.default_rng(5)
    L = Layout(B_g.shape[0])
    X = _random_state(rng, B_g.shape[0])
    X[L.THETA] = 0.0
    q0 = Rotation.random(random_state=6)
    w_c, frame = np.array([0.0, 0.0, 0.03]), np.array([7e-5, 0.0, -2e-5])
    _, H = gyro_measurement(X, q0.as_matrix(), w_c, B_g, frame)
    other = [j for j in range(L.n) if j not in range(3)]
    fd = _fd(lambda x: gyro_measurement(x, q0.as_matrix(), w_c, B_g, frame)[0], X)
    np.testing.assert_allclose(H[:, other], fd[:, other], atol=1e-9)

    def exact(th):
        R = (q0 * Rotation.from_rotvec(th)).as_matrix()
        return gyro_measurement(X, R, w_c, B_g, frame)[0]

    np.testing.assert_allclose(H[:, L.THETA], _fd(exact, np.zeros(3)), atol=1e-11)


def test_sun_sensor_jacobian() -> None:
    L = Layout()
    X = np.zeros(L.n)
    sun_s = np.array([-1.0, 1.0, -1.0]) / np.sqrt(3.0)
    for seed in range(5):
        q0 = Rotation.from_euler("ZYX", [seed * 1.3, 0.1 * seed - 0.2, 0.05 * seed])
        h, H = sun_measurement(X, q0.as_matrix(), sun_s)
        assert np.linalg.norm(h) < 1.0

        def exact(th, q0=q0):
            R = (q0 * Rotation.from_rotvec(th)).as_matrix()
            return sun_measurement(X, R, sun_s)[0]

        np.testing.assert_allclose(H[:, L.THETA], _fd(exact, np.zeros(3)), atol=1e-8)
        assert np.all(H[:, 3:] == 0.0)


def _joints(rng):
    return JointRates(
        gamma_rad=rng.normal(0.0, 0.1, 3),
        gamma_rate_rad_s=rng.normal(0.0, 0.02, 3),
        sigma_rad=np.array([0.3, 0.0, -0.2, 0.1, 0.0, -0.4]),
        sigma_rate_rad_s=np.array([0.01, 0.0, -0.02, 0.0, 0.0, 0.03]),
        psi_rate_rad_s=rng.normal(0.29, 0.02, 6),
    )


def test_slip_constraint_jacobians() -> None:
    rng = np.random.default_rng(9)
    joints = _joints(rng)
    v, w, xi = rng.normal(0, 0.03, 3), rng.normal(0, 0.05, 3), rng.normal(0, 0.3, 6)
    J = slip_constraint(v, w, xi, joints)
    np.testing.assert_allclose(
        J.d_v, _fd(lambda x: slip_constraint(x, w, xi, joints).slip, v), atol=1e-9
    )
    np.testing.assert_allclose(
        J.d_omega, _fd(lambda x: slip_constraint(v, x, xi, joints).slip, w), atol=1e-9
    )
    np.testing.assert_allclose(
        J.d_xi, _fd(lambda x: slip_constraint(v, w, x, joints).slip, xi), atol=1e-9
    )

    def with_rates(gamma_rate=None, psi_rate=None):
        return JointRates(
            joints.gamma_rad,
            joints.gamma_rate_rad_s if gamma_rate is None else gamma_rate,
            joints.sigma_rad,
            joints.sigma_rate_rad_s,
            joints.psi_rate_rad_s if psi_rate is None else psi_rate,
        )

    fd_g = _fd(lambda g: slip_constraint(v, w, xi, with_rates(gamma_rate=g)).slip,
               joints.gamma_rate_rad_s)  # fmt: skip
    fd_p = _fd(lambda p: slip_constraint(v, w, xi, with_rates(psi_rate=p)).slip,
               joints.psi_rate_rad_s)  # fmt: skip
    np.testing.assert_allclose(J.d_gamma_rate, fd_g, atol=1e-9)
    np.testing.assert_allclose(J.d_psi_rate, fd_p, atol=1e-9)
