"""LN-200 IMU model: Mars rotation at rest, noise statistics, exact aggregation, frames."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from estimation.mars_constants import MARS_GRAVITY_M_S2, MARS_ROTATION_RATE_RAD_S
from sim.errors import InputError
from sim.rover.truth import CONTROL_DT_S
from sim.sensors.imu import (
    DEG_PER_H_TO_RAD_S,
    DEG_PER_SQRT_H_TO_RAD_PER_SQRT_S,
    STANDARD_GRAVITY_M_S2,
    Ln200Imu,
    Ln200Params,
)

GUSEV_LAT_RAD = math.radians(-14.57)  # Spirit's landing site (planetographic)
YAW_PITCH_ROLL_DEG = (123.0, 7.0, -11.0)  # a tilted rover on a slope
Q_TILTED_LL_B = Rotation.from_euler("ZYX", YAW_PITCH_ROLL_DEG, degrees=True).as_quat()


def mars_rotation_ll(lat_rad: float) -> NDArray[np.float64]:
    """Mars' spin vector in LL (North, East, Down): along the local north-pole direction."""
    return MARS_ROTATION_RATE_RAD_S * np.array([math.cos(lat_rad), 0.0, -math.sin(lat_rad)])


def at_rest(
    duration_s: float, q_ll_b: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    n = round(duration_s / CONTROL_DT_S)
    t = np.arange(n + 1, dtype=np.float64) * CONTROL_DT_S
    return t, np.tile(q_ll_b, (n + 1, 1))


def test_noise_free_rover_at_rest_integrates_exactly_to_mars_rotation() -> None:
    omega_ll = mars_rotation_ll(GUSEV_LAT_RAD)
    t, q = at_rest(3600.0, Q_TILTED_LL_B)
    imu = Ln200Imu(Ln200Params.noise_free(), np.random.default_rng(0))
    out = imu.measure(t, q, omega_ll)
    expected_b = Rotation.from_quat(Q_TILTED_LL_B).inv().apply(omega_ll * 3600.0)
    # 14.6 deg of Mars rotation in an hour, to a nanoradian.
    assert np.linalg.norm(expected_b) == pytest.approx(math.radians(14.62), abs=1e-3)
    np.testing.assert_allclose(out.delta_angle_b.sum(axis=0), expected_b, rtol=0, atol=1e-9)
    assert len(out) == 28_800
    np.testing.assert_allclose(out.t_s, t[1:])


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_rover_at_rest_reads_mars_rotation_within_bias_and_noise(seed: int) -> None:
    p = Ln200Params()
    omega_ll = mars_rotation_ll(GUSEV_LAT_RAD)
    duration_s = 3600.0
    t, q = at_rest(duration_s, Q_TILTED_LL_B)
    imu = Ln200Imu(p, np.random.default_rng(seed))
    turn_on_rad_s = imu.gyro_turn_on_bias_rad_s
    total_b = imu.measure(t, q, omega_ll).delta_angle_b.sum(axis=0)
    expected_b = Rotation.from_quat(Q_TILTED_LL_B).inv().apply(omega_ll * duration_s)
    # What remains after the known turn-on bias: ARW plus the integrated Gauss-Markov
    # bias, whose stationary variance is 2 sigma^2 tau^2 (x - 1 + e^-x), x = T / tau.
    sigma_gm = p.gyro_bias_instability_deg_per_h * DEG_PER_H_TO_RAD_S
    tau = p.gyro_bias_corr_time_s
    x = duration_s / tau
    var_gm = 2.0 * sigma_gm**2 * tau**2 * (x - 1.0 + math.exp(-x))
    var_arw = (p.gyro_arw_deg_per_sqrt_h * DEG_PER_SQRT_H_TO_RAD_PER_SQRT_S) ** 2 * duration_s
    sigma_rest = math.sqrt(var_gm + var_arw)  # ~0.28 deg
    residual = total_b - expected_b - turn_on_rad_s * duration_s
    assert np.all(np.abs(residual) < 4.0 * sigma_rest)
    # And the whole error is what a 1 deg/h-class gyro allows over an hour.
    sigma_on = p.gyro_bias_turn_on_deg_per_h * DEG_PER_H_TO_RAD_S * duration_s
    assert np.all(np.abs(total_b - expected_b) < 4.0 * math.hypot(sigma_on, sigma_rest))


def test_per_sample_gyro_noise_matches_angle_random_walk() -> None:
    p = Ln200Params()
    t, q = at_rest(3600.0, Q_TILTED_LL_B)
    omega_ll = mars_rotation_ll(GUSEV_LAT_RAD)
    imu = Ln200Imu(p, np.random.default_rng(11))
    out = imu.measure(t, q, omega_ll)
    truth = Rotation.from_quat(Q_TILTED_LL_B).inv().apply(omega_ll * CONTROL_DT_S)
    resid = out.delta_angle_b - truth
    resid -= resid.mean(axis=0)  # the bias moves by ~1e-9 rad per sample: irrelevant here
    expected_std = (
        p.gyro_arw_deg_per_sqrt_h * DEG_PER_SQRT_H_TO_RAD_PER_SQRT_S * math.sqrt(CONTROL_DT_S)
    )  # ARW sqrt(dt) = sqrt(ARW^2 / dt) dt, ~1.0e-5 rad
    np.testing.assert_allclose(resid.std(axis=0), expected_std, rtol=0.02)
    # White: no correlation between consecutive samples (sigma of the estimate ~0.006).
    for axis in range(3):
        r = resid[:, axis]
        assert abs(np.corrcoef(r[:-1], r[1:])[0, 1]) < 0.025
    # Accelerometer white noise: 50 ug/sqrt(Hz) -> sigma of dv = N sqrt(dt).
    f_b = Rotation.from_quat(Q_TILTED_LL_B).inv().apply([0.0, 0.0, -MARS_GRAVITY_M_S2])
    dv_resid = out.delta_velocity_b - f_b * CONTROL_DT_S
    dv_resid -= dv_resid.mean(axis=0)
    vrw = p.accel_noise_ug_per_sqrt_hz * 1e-6 * STANDARD_GRAVITY_M_S2
    np.testing.assert_allclose(dv_resid.std(axis=0), vrw * math.sqrt(CONTROL_DT_S), rtol=0.02)


def test_idle_aggregate_matches_sum_of_8hz_samples_in_distribution() -> None:
    # A bias-dominated IMU (1 min correlation time, 2 min span) so that the exact
    # propagation of the Gauss-Markov process is what the comparison sees.
    p = Ln200Params(
        gyro_bias_turn_on_deg_per_h=0.0,
        gyro_arw_deg_per_sqrt_h=0.05,
        gyro_bias_instability_deg_per_h=20.0,
        gyro_bias_corr_time_s=60.0,
        accel_bias_turn_on_ug=0.0,
        accel_noise_ug_per_sqrt_hz=50.0,
    )
    duration_s, runs = 120.0, 500
    t, q = at_rest(duration_s, Q_TILTED_LL_B)
    omega_ll = mars_rotation_ll(GUSEV_LAT_RAD)
    expected_b = Rotation.from_quat(Q_TILTED_LL_B).inv().apply(omega_ll * duration_s)
    summed, summed_dv, aggregated, aggregated_dv = [], [], [], []
    end_bias, end_bias_agg = [], []
    for k in range(runs):
        imu = Ln200Imu(p, np.random.default_rng(1000 + k))
        out = imu.measure(t, q, omega_ll)
        summed.append(out.delta_angle_b.sum(axis=0) - expected_b)
        summed_dv.append(out.delta_velocity_b.sum(axis=0))
        end_bias.append(imu.gyro_bias_rad_s)
        imu2 = Ln200Imu(p, np.random.default_rng(5000 + k))
        agg = imu2.measure_interval(duration_s, Q_TILTED_LL_B, omega_ll)
        aggregated.append(agg.delta_angle_b[0] - expected_b)
        aggregated_dv.append(agg.delta_velocity_b[0])
        end_bias_agg.append(imu2.gyro_bias_rad_s)
        assert imu2.t_s == pytest.approx(duration_s)

    # Independent reference: the stationary OU integral, 2 s^2 tau^2 (x - 1 + e^-x), + ARW.
    sigma = p.gyro_bias_instability_deg_per_h * DEG_PER_H_TO_RAD_S
    tau = p.gyro_bias_corr_time_s
    x = duration_s / tau
    var_expected = (
        2.0 * sigma**2 * tau**2 * (x - 1.0 + math.exp(-x))
        + (p.gyro_arw_deg_per_sqrt_h * DEG_PER_SQRT_H_TO_RAD_PER_SQRT_S) ** 2 * duration_s
    )
    cov_expected = sigma**2 * tau * (1.0 - math.exp(-x))  # Cov(bias at end, integral)
    for errs, ends in ((summed, end_bias), (aggregated, end_bias_agg)):
        e = np.asarray(errs).ravel()  # 1500 values: variance known to ~4 %
        b = np.asarray(ends).ravel()
        assert abs(e.mean()) < 4.0 * math.sqrt(var_expected / e.size)
        assert e.var() == pytest.approx(var_expected, rel=0.15)
        assert b.var() == pytest.approx(sigma**2, rel=0.15)  # stationary at the end too
        assert np.mean(e * b) == pytest.approx(cov_expected, rel=0.2)
    # Same distribution for the accelerometers: mean -g_b T, variance VRW^2 T.
    f_b = Rotation.from_quat(Q_TILTED_LL_B).inv().apply([0.0, 0.0, -MARS_GRAVITY_M_S2])
    vrw = p.accel_noise_ug_per_sqrt_hz * 1e-6 * STANDARD_GRAVITY_M_S2
    for dv in (summed_dv, aggregated_dv):
        d = np.asarray(dv) - f_b * duration_s
        assert d.var() == pytest.approx(vrw**2 * duration_s, rel=0.15)
        assert np.all(np.abs(d.mean(axis=0)) < 4.0 * vrw * math.sqrt(duration_s / runs))


def test_accelerometers_at_rest_read_gravity_up_on_a_tilted_rover() -> None:
    _yaw, pitch, roll = (math.radians(a) for a in YAW_PITCH_ROLL_DEG)
    # Textbook specific force at rest for a yaw-pitch-roll (z-y-x) attitude, N-E-D frames.
    f_ref_b = MARS_GRAVITY_M_S2 * np.array(
        [math.sin(pitch), -math.sin(roll) * math.cos(pitch), -math.cos(roll) * math.cos(pitch)]
    )
    t, q = at_rest(10.0, Q_TILTED_LL_B)
    omega_ll = mars_rotation_ll(GUSEV_LAT_RAD)
    ideal = Ln200Imu(Ln200Params.noise_free(), np.random.default_rng(0)).measure(t, q, omega_ll)
    np.testing.assert_allclose(
        ideal.delta_velocity_b / CONTROL_DT_S, np.tile(f_ref_b, (80, 1)), rtol=0, atol=1e-12
    )
    assert np.all(ideal.delta_velocity_b[:, 2] < 0.0)  # "up" is -z in the body

    level = Ln200Imu(Ln200Params.noise_free(), np.random.default_rng(0))
    out = level.measure(*at_rest(1.0, np.array([0.0, 0.0, 0.0, 1.0])), omega_ll)
    np.testing.assert_allclose(out.delta_velocity_b[0] / CONTROL_DT_S, [0.0, 0.0, -3.711])

    p = Ln200Params()
    sigma_bias = p.accel_bias_turn_on_ug * 1e-6 * STANDARD_GRAVITY_M_S2  # 2.9 mm/s^2
    for seed in range(5):
        noisy = Ln200Imu(p, np.random.default_rng(seed)).measure(t, q, omega_ll)
        f_mean = noisy.delta_velocity_b.sum(axis=0) / 10.0
        assert np.linalg.norm(f_mean) == pytest.approx(MARS_GRAVITY_M_S2, abs=5.0 * sigma_bias)
        cos_angle = f_mean @ f_ref_b / (np.linalg.norm(f_mean) * MARS_GRAVITY_M_S2)
        assert math.acos(min(cos_angle, 1.0)) < 5.0 * sigma_bias / MARS_GRAVITY_M_S2


def test_ninety_degree_yaw_integrates_to_ninety_degrees_about_body_z() -> None:
    t = np.arange(81) * CONTROL_DT_S  # 10 s
    yaw = 0.5 * math.pi * 0.5 * (1.0 - np.cos(math.pi * t / 10.0))  # smooth 0 -> 90 deg
    q = Rotation.from_euler("z", yaw[:, None]).as_quat()
    out = Ln200Imu(Ln200Params.noise_free(), np.random.default_rng(0)).measure(t, q, np.zeros(3))
    np.testing.assert_allclose(out.delta_angle_b.sum(axis=0), [0.0, 0.0, math.pi / 2], atol=1e-12)
    np.testing.assert_allclose(out.delta_angle_b[:, :2], 0.0, atol=1e-15)


def test_delta_angles_are_body_frame_rotation_increments() -> None:
    # A rover pitched 30 deg turning in place about its own z at 2.1 deg/s (Ali et al. 2005):
    # the body rate is exactly (0, 0, w) in body axes, though every Euler angle changes.
    rate = math.radians(2.1)
    t = np.arange(161) * CONTROL_DT_S
    R = Rotation.from_euler("y", 30.0, degrees=True) * Rotation.from_euler("z", (rate * t)[:, None])
    ideal = Ln200Imu(Ln200Params.noise_free(), np.random.default_rng(0))
    out = ideal.measure(t, R.as_quat(), np.zeros(3))
    expected = np.tile([0.0, 0.0, rate * CONTROL_DT_S], (160, 1))
    np.testing.assert_allclose(out.delta_angle_b, expected, rtol=0, atol=1e-14)

    # With Mars rotation as well: agrees with scipy's independent rotation algebra.
    omega_ll = mars_rotation_ll(GUSEV_LAT_RAD)
    out = Ln200Imu(Ln200Params.noise_free(), np.random.default_rng(0)).measure(
        t, R.as_quat(), omega_ll
    )
    mars = Rotation.from_rotvec(np.outer(np.diff(t), omega_ll))
    ref = (R[:-1].inv() * mars * R[1:]).as_rotvec()
    np.testing.assert_allclose(out.delta_angle_b, ref, atol=1e-15)


def test_bad_input_is_rejected_with_the_parameter_named() -> None:
    imu = Ln200Imu(Ln200Params(), np.random.default_rng(0), t_on_s=100.0)
    t, q = at_rest(1.0, Q_TILTED_LL_B)
    with pytest.raises(InputError, match="t_s"):
        imu.measure(t, q, np.zeros(3))  # starts before power-on
    with pytest.raises(InputError, match="q_ll_b"):
        imu.measure(t + 100.0, q[:-1], np.zeros(3))
    with pytest.raises(InputError, match="t_s"):
        imu.measure(np.array([101.0, 101.0, 102.0]), q[:3], np.zeros(3))
    with pytest.raises(InputError, match="dt_s"):
        imu.measure_interval(-1.0, Q_TILTED_LL_B, np.zeros(3))
    with pytest.raises(InputError, match="gyro_arw_deg_per_sqrt_h"):
        Ln200Params(gyro_arw_deg_per_sqrt_h=-0.1)
    # A gap before the next call is fine: the bias process is carried across it.
    out = imu.measure(t + 200.0, q, np.zeros(3))
    assert imu.t_s == pytest.approx(201.0)
    assert out.t_s[0] == pytest.approx(200.125)
