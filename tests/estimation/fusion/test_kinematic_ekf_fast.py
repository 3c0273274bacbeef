"""The kinematic EKF's fast paths (issue 16) against the straightforward forms they replace,
on random inputs: the slip constraint on plain floats against eq. 17 wheel by wheel with
the contact frame's rotation matrices, the suspension on floats against rotation matrices,
the dynamics on floats against array arithmetic, and the split discretisation against the
whole Van Loan exponential."""

import numpy as np

from estimation.fusion import ekf_core
from estimation.fusion.kinematic.process import (
    Layout,
    ProcessParams,
    dynamics,
    jacobian,
    noise_density,
    skew,
)
from estimation.fusion.kinematic.rover_kinematics import (
    Suspension,
    contact_rotation_b,
    suspension,
)
from estimation.fusion.kinematic.slip_constraint import (
    JointRates,
    deterministic_slip,
    slip_constraint,
)
from estimation.geometry import FLIGHT_GEOMETRY as G

Y = np.array([0.0, 1.0, 0.0])


def _ry(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def reference_suspension(gamma: np.ndarray) -> Suspension:
    """The rocker-bogie's forward kinematics with rotation matrices."""
    pivot = np.array([G.rocker_pivot_x_m, 0.0, G.rocker_pivot_z_m])
    bogie = np.array([G.bogie_pivot_x_m, 0.0, G.bogie_pivot_z_m])
    wheel = [
        np.array([x, 0.0, G.wheel_centre_z_m]) for x in (G.x_front_m, G.x_middle_m, G.x_rear_m)
    ]
    centre, dcentre = np.zeros((6, 3)), np.zeros((6, 3, 3))
    link, dlink = np.zeros(6), np.zeros((6, 3))
    for side, sign in enumerate((1.0, -1.0)):
        f, m, r = 3 * side, 3 * side + 1, 3 * side + 2
        rho, beta = sign * gamma[0], gamma[1 + side]
        bogie_pivot = pivot + _ry(rho) @ (bogie - pivot)
        centre[f] = pivot + _ry(rho) @ (wheel[0] - pivot)
        centre[m] = bogie_pivot + _ry(rho + beta) @ (wheel[1] - bogie)
        centre[r] = bogie_pivot + _ry(rho + beta) @ (wheel[2] - bogie)
        for i in (f, m, r):
            dcentre[i, :, 0] = sign * np.cross(Y, centre[i] - pivot)
            link[i], dlink[i, 0] = rho, sign
        for i in (m, r):
            dcentre[i, :, 1 + side] = np.cross(Y, centre[i] - bogie_pivot)
            link[i], dlink[i, 1 + side] = rho + beta, 1.0
        centre[(f, m, r), 1] = (-0.5 if side == 0 else 0.5) * G.track_m
    return Suspension(centre, dcentre, link, dlink)


def reference_slip(
    v: np.ndarray, w: np.ndarray, xi: np.ndarray, joints: JointRates
) -> list[np.ndarray]:
    """Eq. 17 wheel by wheel: the slip (24,) and its Jacobians, as the module states them."""
    s = reference_suspension(joints.gamma_rad)
    r = G.wheel_radius_m
    out = [np.zeros(24), np.zeros((24, 3)), np.zeros((24, 3)), np.zeros((24, 6))]
    out += [np.zeros((24, 3)), np.zeros((24, 6))]
    slip, d_v, d_w, d_xi, d_g, d_psi = out
    for i in range(6):
        rows = slice(4 * i, 4 * i + 4)
        C = contact_rotation_b(s.link_rad[i], joints.sigma_rad[i], xi[i])
        t, a, d = C[:, 0], C[:, 1], C[:, 2]
        link_z = _ry(s.link_rad[i])[:, 2]
        omega_w = w + (s.dlink_dgamma[i] @ joints.gamma_rate_rad_s) * Y
        omega_w = omega_w + joints.sigma_rate_rad_s[i] * link_z - joints.psi_rate_rad_s[i] * a
        u = v + np.cross(w, s.centre_b[i]) + s.dcentre_dgamma[i] @ joints.gamma_rate_rad_s
        u = u + r * np.cross(omega_w, d)
        slip[rows] = [t @ u, a @ u, d @ u, d @ omega_w]
        d_v[rows] = np.stack([t, a, d, np.zeros(3)])
        P = skew(s.centre_b[i] + r * d)
        d_w[rows] = np.stack([P @ t, P @ a, P @ d, d])
        d_xi[rows, i] = [-(d @ u), r * (omega_w @ d), t @ u - r * (omega_w @ a), t @ omega_w]
        for j in range(3):
            du = s.dcentre_dgamma[i][:, j] + s.dlink_dgamma[i, j] * r * np.cross(Y, d)
            d_g[rows, j] = [t @ du, a @ du, d @ du, s.dlink_dgamma[i, j] * d[1]]
        d_psi[4 * i, i] = -r
    return out


def _random_joints(rng: np.random.Generator) -> JointRates:
    sigma = np.zeros(6)
    sigma[[0, 2, 3, 5]] = rng.uniform(-0.6, 0.6, 4)
    return JointRates(
        rng.uniform(-0.3, 0.3, 3),
        rng.normal(0.0, 0.05, 3),
        sigma,
        rng.normal(0.0, 0.1, 6) * (sigma != 0.0),
        rng.normal(0.0, 0.3, 6),
    )


def test_the_suspension_on_floats_is_the_rotation_matrices() -> None:
    rng = np.random.default_rng(16)
    for _ in range(50):
        gamma = rng.uniform(-0.5, 0.5, 3)
        fast, ref = suspension(gamma), reference_suspension(gamma)
        for name in ("centre_b", "dcentre_dgamma", "link_rad", "dlink_dgamma"):
            np.testing.assert_allclose(getattr(fast, name), getattr(ref, name), atol=1e-15)


def test_the_slip_constraint_on_floats_is_eq_17_wheel_by_wheel() -> None:
    rng = np.random.default_rng(17)
    for _ in range(50):
        v, w, xi = rng.normal(0.0, 0.05, 3), rng.normal(0.0, 0.05, 3), rng.uniform(-1.2, 1.2, 6)
        joints = _random_joints(rng)
        J = slip_constraint(v, w, xi, joints)
        got = [J.slip, J.d_v, J.d_omega, J.d_xi, J.d_gamma_rate, J.d_psi_rate]
        for fast, ref in zip(got, reference_slip(v, w, xi, joints), strict=True):
            np.testing.assert_allclose(fast, ref, atol=1e-15)


def test_the_deterministic_slip_is_the_no_slip_rolling_of_eq_17() -> None:
    rng = np.random.default_rng(18)
    zero3, zero6 = np.zeros(3), np.zeros(6)
    for _ in range(20):
        v, w = rng.normal(0.0, 0.05, 3), rng.normal(0.0, 0.05, 3)
        j = _random_joints(rng)
        still = JointRates(zero3, zero3, j.sigma_rad, j.sigma_rate_rad_s, zero6)
        rolling = reference_slip(v, w, zero6, still)[0][0::4] / G.wheel_radius_m
        nominal = JointRates(zero3, zero3, j.sigma_rad, j.sigma_rate_rad_s, rolling)
        expected = reference_slip(v, w, zero6, nominal)[0]
        got = deterministic_slip(v, w, j.sigma_rad, j.sigma_rate_rad_s)
        np.testing.assert_allclose(got, expected, atol=1e-15)


def test_the_dynamics_on_floats_are_the_array_arithmetic() -> None:
    rng = np.random.default_rng(19)
    p = ProcessParams()
    for n_bias in (0, 1, 3):
        L = Layout(n_bias)
        X = rng.normal(0.0, 0.1, L.n)
        R0 = np.linalg.qr(rng.normal(size=(3, 3)))[0]
        v_c, w_c = rng.normal(0.0, 0.05, 3), rng.normal(0.0, 0.05, 3)
        omega, v = w_c + X[L.OMEGA_P], v_c + X[L.V_P]
        expected = np.zeros(L.n)
        expected[L.THETA] = omega - 0.5 * np.cross(omega, X[L.THETA])
        expected[L.OMEGA_P] = -X[L.OMEGA_P] / p.tau_omega_s
        expected[L.X] = R0 @ (v + np.cross(X[L.THETA], v))
        expected[L.V_P] = -X[L.V_P] / p.tau_v_s
        expected[L.XI] = -X[L.XI] / p.tau_xi_s
        np.testing.assert_allclose(dynamics(X, R0, v_c, w_c, p), expected, atol=1e-16)


def test_the_split_discretisation_is_the_whole_van_loan_exponential() -> None:
    rng = np.random.default_rng(20)
    p = ProcessParams()
    for n_bias in (0, 3):
        L = Layout(n_bias)
        X = rng.normal(0.0, 0.1, L.n)
        R0 = np.linalg.qr(rng.normal(size=(3, 3)))[0]
        F = jacobian(X, R0, rng.normal(0.0, 0.05, 3), rng.normal(0.0, 0.05, 3), p)
        Q = noise_density(L, p)
        A = rng.normal(size=(L.n, L.n))
        P = A @ A.T * 1e-4

        def f(x: np.ndarray, F: np.ndarray = F) -> np.ndarray:
            out: np.ndarray = F @ x
            return out

        for dt in (0.0625, 0.5, 3.0):
            whole = ekf_core.propagate(X, P, f, F, Q, dt)
            split = ekf_core.propagate(X, P, f, F, Q, dt, n_coupled=L.UNCOUPLED_FROM)
            np.testing.assert_allclose(split[0], whole[0], rtol=0.0, atol=0.0)
            np.testing.assert_allclose(split[1], whole[1], rtol=1e-12, atol=1e-18)


def test_the_reference_rotation_on_floats_is_scipys() -> None:
    from scipy.spatial.transform import Rotation

    from estimation.fusion.kinematic.ekf import KinematicEkf

    rng = np.random.default_rng(21)
    for _ in range(50):
        q = rng.normal(size=4)
        q *= (1.0 + rng.uniform(-9e-7, 9e-7)) / np.linalg.norm(q)  # within the 1e-6 accepted
        ekf = KinematicEkf(q, np.zeros(3))
        np.testing.assert_allclose(ekf._R0(), Rotation.from_quat(q).as_matrix(), atol=1e-15)


def test_the_update_solves_by_cholesky_as_scipy_does() -> None:
    from scipy.linalg import cho_factor, cho_solve

    rng = np.random.default_rng(22)
    for m in (1, 3, 24):
        A = rng.normal(size=(18, 18))
        P = A @ A.T * 1e-3
        H, R = rng.normal(size=(m, 18)), np.diag(rng.uniform(1e-6, 1e-4, m))
        x, r = rng.normal(size=18), rng.normal(0.0, 1e-3, m)
        S = H @ P @ H.T + R
        factor = cho_factor(0.5 * (S + S.T))
        K = cho_solve(factor, H @ P).T
        I_KH = np.eye(18) - K @ H
        P_ref = I_KH @ P @ I_KH.T + K @ R @ K.T
        x_new, P_new, nis = ekf_core.update(x, P, r, H, R)
        np.testing.assert_allclose(x_new, x + K @ r, rtol=1e-13, atol=1e-16)
        np.testing.assert_allclose(P_new, 0.5 * (P_ref + P_ref.T), rtol=1e-12, atol=1e-18)
        assert abs(nis - float(r @ cho_solve(factor, r))) <= 1e-12 * nis


def test_the_interval_rates_of_all_windows_at_once_are_the_window_by_window_slopes() -> None:
    from estimation.fusion.kinematic.encoder_rates import interval_rates

    rng = np.random.default_rng(23)
    for n in (2, 3, 4, 5, 60):
        for shape in ((), (3,), (2, 3)):
            t = np.cumsum(rng.uniform(0.1, 0.2, n))
            a = rng.normal(size=(n, *shape))
            expected = np.diff(a, axis=0) / np.diff(t).reshape((-1,) + (1,) * len(shape))
            for k in range(1, n - 2):  # the least-squares slope through four samples
                tt = t[k - 1 : k + 3] - 0.5 * (t[k] + t[k + 1])
                w = (tt - tt.mean()) / np.sum((tt - tt.mean()) ** 2)
                expected[k] = np.tensordot(w, a[k - 1 : k + 3], axes=1)
            np.testing.assert_allclose(interval_rates(a, t), expected, rtol=0.0, atol=1e-14)


def test_the_jacobian_on_floats_is_the_block_arithmetic() -> None:
    rng = np.random.default_rng(24)
    p = ProcessParams(tau_omega_s=0.7, tau_v_s=1.3, tau_xi_s=3.0)
    for n_bias in (0, 1, 3):
        L = Layout(n_bias)
        X = rng.normal(0.0, 0.1, L.n)
        R0 = np.linalg.qr(rng.normal(size=(3, 3)))[0]
        v_c, w_c = rng.normal(0.0, 0.05, 3), rng.normal(0.0, 0.05, 3)
        omega, v, I3 = w_c + X[L.OMEGA_P], v_c + X[L.V_P], np.eye(3)
        expected = np.zeros((L.n, L.n))
        expected[L.THETA, L.THETA] = -0.5 * skew(omega)
        expected[L.THETA, L.OMEGA_P] = I3 + 0.5 * skew(X[L.THETA])
        expected[L.OMEGA_P, L.OMEGA_P] = -I3 / p.tau_omega_s
        expected[L.X, L.THETA] = -R0 @ skew(v)
        expected[L.X, L.V_P] = R0 @ (I3 + skew(X[L.THETA]))
        expected[L.V_P, L.V_P] = -I3 / p.tau_v_s
        expected[L.XI, L.XI] = -np.eye(6) / p.tau_xi_s
        np.testing.assert_allclose(jacobian(X, R0, v_c, w_c, p), expected, rtol=0.0, atol=1e-15)
