"""The radio + terrain-matching EKF's flight code (Jiang, Li et al. 2014): Jacobians, update, RK4,
inputs."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from estimation.fusion.ekf_core import joseph_update, rk4
from estimation.fusion.radio import models as rm
from estimation.fusion.radio.ekf import RadioEkf, RadioEkfTuning

FloatArray = NDArray[np.float64]

LAT, LON = math.radians(-1.95), math.radians(354.47)
X = np.array([LAT, LON, 0.04, -0.03])
STATE_STEP = np.array([1e-8, 1e-8, 1e-5, 1e-5])  # ~3 cm in position, 10 µm/s


def numeric_jacobian(fn: Callable[[FloatArray], FloatArray], x: FloatArray) -> FloatArray:
    """Central differences, one state component at a time."""
    cols = []
    for i in range(x.shape[0]):
        dx = np.zeros_like(x)
        dx[i] = STATE_STEP[i] if x.shape[0] == 4 else 1e-2  # metres for a landmark
        cols.append((fn(x + dx) - fn(x - dx)) / (2.0 * dx[i]))
    return np.stack(cols, axis=-1)


def test_euler_rotation_is_scipys_zyx_sequence() -> None:
    roll, pitch, yaw = 0.1, -0.2, 2.5
    expected = Rotation.from_euler("ZYX", [yaw, pitch, roll]).as_matrix()
    R = rm.R_ll_b_from_euler(roll, pitch, yaw)
    np.testing.assert_allclose(R, expected, atol=1e-15)
    np.testing.assert_allclose(rm.euler_from_R_ll_b(R), (roll, pitch, yaw), atol=1e-12)


def test_geodetic_position_is_on_the_ellipsoid_and_its_normal_is_ll_down() -> None:
    r = rm.position_mf_m(LAT, LON, 0.0)
    a, b = rm.MARS_EQUATORIAL_RADIUS_M, rm.MARS_POLAR_RADIUS_M
    assert (r[0] ** 2 + r[1] ** 2) / a**2 + r[2] ** 2 / b**2 == pytest.approx(1.0, abs=1e-12)
    up = rm.position_mf_m(LAT, LON, 100.0) - r  # 100 m up the normal
    np.testing.assert_allclose(rm.R_ll_mf(LAT, LON) @ up, [0.0, 0.0, -100.0], atol=1e-6)


def test_dynamics_jacobian_matches_finite_differences() -> None:
    a_ne = np.array([0.01, -0.02])
    x = np.array([math.radians(40.0), LON, 0.3, -0.2])  # away from the equator: dM/dL != 0
    F = rm.dynamics_jacobian(x, 150.0)
    F_num = numeric_jacobian(lambda s: rm.dynamics(s, a_ne, 150.0), x)
    np.testing.assert_allclose(F, F_num, rtol=1e-6, atol=1e-14)


def test_range_jacobian_matches_finite_differences() -> None:
    beacon = rm.position_mf_m(LAT + 0.05, LON - 0.08, 400e3)
    _, H = rm.beacon_range(X, -1500.0, beacon)
    H_num = numeric_jacobian(lambda s: np.array([rm.beacon_range(s, -1500.0, beacon)[0]]), X)
    np.testing.assert_allclose(H, H_num, rtol=1e-6, atol=1e-9)


def test_yaw_rate_jacobian_matches_finite_differences() -> None:
    a_ne = np.array([0.002, 0.003])
    _, H = rm.yaw_rate(X, a_ne)
    H_num = numeric_jacobian(lambda s: np.array([rm.yaw_rate(s, a_ne)[0]]), X)
    np.testing.assert_allclose(H, H_num, rtol=1e-6, atol=1e-12)


def _pixel_setup() -> tuple[FloatArray, FloatArray, FloatArray]:
    landmark_mf = rm.position_mf_m(LAT + 4e-6, LON + 5e-6, -2.0)  # ~14 m N, 17 m E
    R_ll_b = rm.R_ll_b_from_euler(0.02, -0.03, 0.7)
    R_cam_ll = rm.R_cam_b(0.2) @ R_ll_b.T
    offset_ll = R_ll_b @ np.array([0.45, -0.3, -1.3])
    return landmark_mf, R_cam_ll, offset_ll


def test_pixel_jacobians_match_finite_differences() -> None:
    landmark_mf, R_cam_ll, offset_ll = _pixel_setup()
    f = 1236.0

    def pixels(s: FloatArray) -> FloatArray:
        return rm.landmark_pixels(s, 0.0, landmark_mf, R_cam_ll, offset_ll, f)[0]

    _, H, d_pix_d_ll, depth = rm.landmark_pixels(X, 0.0, landmark_mf, R_cam_ll, offset_ll, f)
    assert depth > 0.0
    np.testing.assert_allclose(H, numeric_jacobian(pixels, X), rtol=1e-5, atol=1e-3)
    R_mf_ll = rm.R_ll_mf(LAT, LON).T  # a landmark moved along LL axes

    def pixels_of_landmark(d_ll: FloatArray) -> FloatArray:
        moved = landmark_mf + R_mf_ll @ d_ll
        return rm.landmark_pixels(X, 0.0, moved, R_cam_ll, offset_ll, f)[0]

    d_num = numeric_jacobian(pixels_of_landmark, np.zeros(3))
    np.testing.assert_allclose(d_pix_d_ll, d_num, rtol=1e-5, atol=1e-5)


def test_rk4_is_fourth_order_on_the_harmonic_oscillator() -> None:
    def oscillator(s: FloatArray) -> FloatArray:
        return np.array([s[1], -s[0]])

    def error(h: float) -> float:
        s = np.array([1.0, 0.0])
        n = round(10.0 / h)
        for _ in range(n):
            s = rk4(oscillator, s, h)
        return float(np.hypot(s[0] - math.cos(10.0), s[1] + math.sin(10.0)))

    coarse, fine = error(0.1), error(0.05)
    assert coarse < 2e-5  # analytic solution cos t
    assert 14.0 < coarse / fine < 18.0  # halving the step: 2^4 less error


def test_joseph_update_equals_information_form_kalman_filter() -> None:
    """A linear model run through predict/update: the Joseph form (eq. 30) gives the same
    state and covariance as the information filter, an independent formulation."""
    rng = np.random.default_rng(3)
    Phi = np.array([[1.0, 0.0, 1.0, 0.0], [0.0, 1.0, 0.0, 1.0], [0, 0, 1, 0], [0, 0, 0, 1]])
    Q = np.diag([0.01, 0.01, 0.001, 0.001])
    x = np.zeros(4)
    P = np.diag([100.0, 100.0, 1.0, 1.0])
    x_info, P_info = x.copy(), P.copy()
    for _ in range(20):
        x, P = Phi @ x, Phi @ P @ Phi.T + Q  # eqs. 26-27
        x_info, P_info = Phi @ x_info, Phi @ P_info @ Phi.T + Q
        H = rng.normal(size=(3, 4))
        R = np.diag(rng.uniform(0.1, 2.0, 3))
        y = rng.normal(size=3) * 3.0
        x, P = joseph_update(x, P, y - H @ x, H, R)
        info = np.linalg.inv(P_info) + H.T @ np.linalg.solve(R, H)
        P_new = np.linalg.inv(info)
        x_info = P_new @ (np.linalg.solve(P_info, x_info) + H.T @ np.linalg.solve(R, y))
        P_info = P_new
    np.testing.assert_allclose(x, x_info, rtol=1e-8, atol=1e-9)
    np.testing.assert_allclose(P, P_info, rtol=1e-8, atol=1e-12)


def test_radio_ekf_range_update_is_the_kalman_update_of_its_linearisation() -> None:
    ekf = RadioEkf(LAT, LON, 0.04, -0.03, height_m=-1500.0)
    x0, P0 = ekf.estimate()
    beacon = rm.position_mf_m(LAT + 0.05, LON - 0.08, 400e3)
    predicted = rm.beacon_range(x0, -1500.0, beacon)[0]
    H = numeric_jacobian(lambda s: np.array([rm.beacon_range(s, -1500.0, beacon)[0]]), x0)
    measured = predicted + 7.0
    innovation = ekf.update_range(measured, beacon, -1500.0, 2.0)
    assert innovation == pytest.approx(7.0, abs=1e-6)
    S = H @ P0 @ H.T + 4.0
    K = P0 @ H.T / S
    x1, P1 = ekf.estimate()
    np.testing.assert_allclose(x1, x0 + (K * 7.0).ravel(), rtol=1e-6, atol=1e-15)
    np.testing.assert_allclose(P1, P0 - K @ H @ P0, rtol=1e-5, atol=1e-20)
    # the new range prediction moved towards the measurement
    assert abs(measured - rm.beacon_range(x1, -1500.0, beacon)[0]) < 7.0


def test_propagation_moves_the_rover_by_its_velocity() -> None:
    ekf = RadioEkf(LAT, LON, 0.1, 0.2, tuning=RadioEkfTuning(q_position_m2_per_s=1e-6))
    level_rest = np.array([0.0, 0.0, -3.711])  # specific force of a level rover: up
    for _ in range(100):
        ekf.propagate(1.0, level_rest, (0.0, 0.0, 0.3), 0.0)
    x, P = ekf.estimate()
    M, N, _, _ = rm.radii_of_curvature_m(LAT)
    assert (x[0] - LAT) * M == pytest.approx(10.0, rel=1e-6)
    assert (x[1] - LON) * N * math.cos(LAT) == pytest.approx(20.0, rel=1e-4)
    np.testing.assert_allclose(x[2:], [0.1, 0.2], atol=1e-12)
    assert P[0, 0] * M**2 > 100.0  # the 10 m start uncertainty grew with the velocity's


def test_zero_velocity_update_is_the_kalman_update_of_a_direct_velocity_measurement() -> None:
    """The velocity update's gain against the textbook K = P Hᵀ (H P Hᵀ + R)⁻¹ with
    H = [0 I]; the position moves too, through the covariance propagation built up."""
    ekf = RadioEkf(LAT, LON, 0.04, -0.03)
    for _ in range(5):
        ekf.propagate(1.0, (0.0, 0.0, -3.711), (0.0, 0.0, 0.0), 0.0)
    x0, P0 = ekf.estimate()
    H = np.hstack([np.zeros((2, 2)), np.eye(2)])
    R = 1e-6 * np.eye(2)
    innovation = ekf.update_velocity((0.0, 0.0), 1e-3)
    np.testing.assert_allclose(innovation, -x0[2:], atol=1e-15)
    K = P0 @ H.T @ np.linalg.inv(H @ P0 @ H.T + R)
    x1, P1 = ekf.estimate()
    np.testing.assert_allclose(x1, x0 + K @ innovation, rtol=1e-9, atol=1e-18)
    np.testing.assert_allclose(P1, (np.eye(4) - K @ H) @ P0, rtol=1e-6, atol=1e-20)
    assert np.all(np.abs(x1[2:]) < 1e-5) and x1[0] != x0[0]


def test_horizontal_sigma_is_the_initial_ten_metres_per_axis() -> None:
    # P0 = diag(10² I, I): Jiang, Li et al. 2014
    ekf = RadioEkf(LAT, LON, 0.0, 0.0, height_m=-1500.0)
    assert ekf.horizontal_sigma_m(-1500.0) == pytest.approx(math.hypot(10.0, 10.0), rel=1e-12)


def test_landmark_behind_the_camera_is_left_out() -> None:
    ekf = RadioEkf(LAT, LON, 0.0, 0.0)
    landmark_mf, _, _ = _pixel_setup()
    x0, _ = ekf.estimate()
    innovation = ekf.update_landmarks(
        [[0.0, 0.0]],
        [landmark_mf],
        [math.pi + 0.9],
        (0.0, 0.0, 0.0),
        0.0,
        (0, 0, 0),
        1236.0,
        1.2,
        1.0,
    )
    assert np.all(np.isnan(innovation))
    np.testing.assert_array_equal(ekf.estimate()[0], x0)


@pytest.mark.parametrize(
    ("call", "name"),
    [
        (lambda: RadioEkf(float("nan"), LON, 0.0, 0.0), "lat_rad"),
        (lambda: RadioEkf(LAT, LON, 50.0, 0.0), "v_north_m_s"),
        (lambda: RadioEkfTuning(q_position_m2_per_s=-1.0), "q_position_m2_per_s"),
        (lambda: RadioEkf(LAT, LON, 0, 0).propagate(0.0, (0, 0, -3.7), (0, 0, 0), 0.0), "dt_s"),
        (
            lambda: RadioEkf(LAT, LON, 0, 0).propagate(1.0, (0, 0), (0, 0, 0), 0.0),
            "specific_force_b",
        ),
        (lambda: RadioEkf(LAT, LON, 0, 0).propagate(1.0, (0, 0, 1), (0, 0), 0.0), "euler_rad"),
        (lambda: RadioEkf(LAT, LON, 0, 0).update_range(1e6, (1e7, 0, 0), 0.0, 0.0), "sigma_m"),
        (lambda: RadioEkf(LAT, LON, 0, 0).update_range(1e6, (1e7, 0), 0.0, 1.0), "beacon_mf_m"),
        (lambda: RadioEkf(LAT, LON, 0, 0).update_range(1e6, (1e7, 0, 0), 1e6, 1.0), "height_m"),
        (lambda: RadioEkf(LAT, LON, 0, 0).update_yaw_rate(float("inf")), "yaw_rate_rad_s"),
        (lambda: RadioEkf(LAT, LON, 0, 0).update_velocity((0.0,), 0.01), "v_ne_m_s"),
        (lambda: RadioEkf(LAT, LON, 0, 0).update_velocity((0.0, 0.0), 0.0), "sigma_m_s"),
        (
            lambda: RadioEkf(LAT, LON, 0, 0).update_landmarks(
                [[0.0, 0.0]], [[1e6, 0, 0], [1, 2, 3]], [0.0], (0, 0, 0), 0.0, (0, 0, 0), 1e3, 1, 1
            ),
            "landmarks_mf_m",
        ),
        (
            lambda: joseph_update(np.zeros(2), np.eye(2), np.zeros(1), np.ones((1, 2)), np.eye(2)),
            "R",
        ),
        (lambda: rk4(lambda s: s, np.zeros(1), float("nan")), "dt_s"),
    ],
)
def test_bad_inputs_raise_value_error_naming_them(call: Callable[[], object], name: str) -> None:
    with pytest.raises(ValueError, match=name):
        call()
