"""The slip constraint (Balaram 2000, eqs. 17-20) is zero for a rover rolling without slip on
flat ground, and the whole filter on surface eq. 22 beats the averaged wheel odometry."""

import math
from datetime import UTC, datetime

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from bench.fusion_kinematic import run_once
from estimation.fusion.kinematic.ekf import KinematicEkf
from estimation.fusion.kinematic.rover_kinematics import steer_per_wheel
from estimation.fusion.kinematic.slip_constraint import (
    JointRates,
    deterministic_slip,
    slip_constraint,
)
from sim.loop.rover_sim import RoverSim

START = datetime(2004, 4, 14, 12, 0, 0, tzinfo=UTC)


def _slips_along(segment, v_c, w_c):
    """Slip residual ``t - t_nominal`` (K, 24) with the truth motion and ξ = 0."""
    truth = segment.truth
    R = Rotation.from_quat(truth.q_s_b)
    out = []
    for k in range(len(truth) - 1):
        dt = truth.t_s[k + 1] - truth.t_s[k]
        half = R[k] * Rotation.from_rotvec(0.5 * (R[k].inv() * R[k + 1]).as_rotvec())
        v_b = half.inv().apply(truth.p_s[k + 1] - truth.p_s[k]) / dt
        w_b = (R[k].inv() * R[k + 1]).as_rotvec() / dt
        g0 = np.r_[truth.rocker_rad[k], truth.bogie_rad[k]]
        g1 = np.r_[truth.rocker_rad[k + 1], truth.bogie_rad[k + 1]]
        s0, s1 = steer_per_wheel(truth.steer_rad[k]), steer_per_wheel(truth.steer_rad[k + 1])
        joints = JointRates(
            0.5 * (g0 + g1),
            (g1 - g0) / dt,
            0.5 * (s0 + s1),
            (s1 - s0) / dt,
            (truth.wheel_angle_rad[k + 1] - truth.wheel_angle_rad[k]) / dt,
        )
        t = slip_constraint(v_b, w_b, np.zeros(6), joints).slip
        out.append(t - deterministic_slip(v_c, w_c, joints.sigma_rad, joints.sigma_rate_rad_s))
    return np.array(out)


def test_slip_is_zero_driving_straight_on_flat_ground() -> None:
    sim = RoverSim("flat", 1, START, slip=False)
    seg = sim.drive_straight(0.5)
    slips = _slips_along(seg, np.array([0.0375, 0.0, 0.0]), np.zeros(3))
    assert np.max(np.abs(slips)) < 1e-9  # m/s and rad/s
    # ... and a wheel that does slip shows up in its rolling row.
    seg2 = RoverSim("flat", 1, START, slip=True).drive_straight(0.5)
    assert np.max(np.abs(_slips_along(seg2, np.array([0.0375, 0.0, 0.0]), np.zeros(3)))) > 1e-4


def test_turn_in_place_slip_is_the_deterministic_spin() -> None:
    sim = RoverSim("flat", 2, START, slip=False)
    seg = sim.turn_in_place(math.radians(30.0))
    rate = math.radians(2.1)
    slips = _slips_along(seg, np.zeros(3), np.array([0.0, 0.0, rate]))
    moving = slice(1, -1)  # the first interval steers, the last stops mid-interval
    assert np.max(np.abs(slips[moving])) < 1e-9
    # Sec. 2.3.4: every wheel spins about the vertical at the yaw rate; unsteered wheels
    # off the turn axis also slip sideways (the corners at x = ±0.7 m, at 0.7 m x rate).
    straight = deterministic_slip(np.zeros(3), np.array([0.0, 0.0, rate]), np.zeros(6), np.zeros(6))
    assert np.allclose(straight[3::4], rate)
    np.testing.assert_allclose(straight[1::4], rate * np.array([0.7, 0, -0.7, 0.7, 0, -0.7]))
    steered = steer_per_wheel(seg.truth.steer_rad[-1])
    nominal = deterministic_slip(np.zeros(3), np.array([0.0, 0.0, rate]), steered, np.zeros(6))
    np.testing.assert_allclose(nominal[1::4], 0.0, atol=1e-15)


def test_estimate_reports_its_frames() -> None:
    q = Rotation.from_euler("ZYX", [0.3, 0.02, -0.01]).as_quat()
    ekf = KinematicEkf(q, [1.0, 2.0, 0.0])
    est = ekf.estimate()
    assert (Rotation.from_quat(est.q_b_s) * Rotation.from_quat(est.q_s_b)).magnitude() < 1e-15
    assert est.P.shape == (18, 18) and est.p_s.tolist() == [1.0, 2.0, 0.0]
    with pytest.raises(ValueError, match="gyro must be"):
        KinematicEkf(q, [0.0, 0.0, 0.0], gyro="two")
    with pytest.raises(ValueError, match="omega_m: must be"):
        ekf.update_gyro([0.0, 0.0])


def test_ekf_beats_averaged_odometry_over_eq22() -> None:
    # Balaram 2000 sec. 4.1.1: over eq. 22 the averaged odometry over-counts (paper 2 %), the
    # kinematic EKF corrects the internal kinematics and contact angles (paper 0.3 %).
    r = run_once("straight", 1)
    odometry_pct = 100 * abs(r.distance_odometry_m - r.distance_true_m) / r.distance_true_m
    ekf_pct = 100 * abs(r.distance_ekf_m - r.distance_true_m) / r.distance_true_m
    assert odometry_pct > 1.0
    assert ekf_pct < 0.3
    assert np.degrees(np.max(r.attitude_err_rad)) < 1.0
