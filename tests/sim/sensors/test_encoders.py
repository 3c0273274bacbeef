"""Wheel encoders and steering sensors: quantisation bounds, odometry distance, continuity."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim.errors import InputError
from sim.rover.truth import CONTROL_DT_S, TruthTrajectory
from sim.sensors.encoders import EncoderParams, MobilityEncoders

WHEEL_RADIUS_M = 0.13  # MER wheel, 26 cm diameter (docs/REFERENCES.md)


def drive_truth(n: int = 801, t0_s: float = 0.0, seed: int = 0) -> TruthTrajectory:
    """100 s at 8 Hz: forward at 3.75 cm/s (Ali et al. 2005), a reverse stretch, per-wheel
    differences as on rough ground, and corner steering sweeping +-30 deg."""
    rng = np.random.default_rng(seed)
    t = t0_s + np.arange(n, dtype=np.float64) * CONTROL_DT_S
    speed_rad_s = 0.0375 / WHEEL_RADIUS_M * np.where((t - t0_s) < 70.0, 1.0, -0.6)
    rate = speed_rad_s[:, None] * (1.0 + 0.05 * rng.standard_normal((n, 6)))
    wheel = 3.0 + np.cumsum(rate * CONTROL_DT_S, axis=0)  # arbitrary angle at power-on
    steer = np.radians(30.0) * np.sin(2 * math.pi * (t - t0_s)[:, None] / 40.0 + np.arange(4))
    q = np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))
    return TruthTrajectory(
        t_s=t,
        p_s=np.zeros((n, 3)),
        q_s_b=q,
        rocker_rad=np.zeros(n),
        bogie_rad=np.zeros((n, 2)),
        wheel_angle_rad=wheel,
        steer_rad=steer,
        slip=np.zeros(n),
    )


def test_resolution_follows_the_mer_gearbox() -> None:
    p = EncoderParams()
    assert p.wheel_counts_per_rev == 24_000  # 16 counts x ~1500:1
    # 34 um of travel per count on a 0.13 m wheel.
    assert WHEEL_RADIUS_M * p.wheel_lsb_rad == pytest.approx(34.0e-6, rel=0.01)
    assert math.degrees(p.steer_lsb_rad) == pytest.approx(360.0 / 4096)


def test_wheel_counts_are_within_one_count_of_the_truth() -> None:
    truth = drive_truth()
    enc = MobilityEncoders(EncoderParams(), np.random.default_rng(1))
    out = enc.read(truth)
    lsb = enc.params.wheel_lsb_rad
    assert out.wheel_counts.dtype == np.int64
    np.testing.assert_array_equal(out.wheel_counts[0], 0)  # incremental: zero at power-on
    err = enc.wheel_angle_rad(out.wheel_counts) - (truth.wheel_angle_rad - truth.wheel_angle_rad[0])
    # floor((theta - theta_on) / lsb + phase), phase in [0, 1): error in (-1, 1) counts.
    assert np.all(np.abs(err) < lsb)
    # Quantisation is real: the error spreads over a whole count, not zero.
    assert np.ptp(err) > 0.9 * lsb


def test_odometry_distance_from_counts_matches_truth_within_one_count() -> None:
    truth = drive_truth()
    enc = MobilityEncoders(EncoderParams(), np.random.default_rng(2))
    out = enc.read(truth)
    counts_per_m = 1.0 / (WHEEL_RADIUS_M * enc.params.wheel_lsb_rad)
    for a, b in ((0, 560), (100, 800), (0, 800)):  # forward, across the reversal, all
        dist_counts_m = (out.wheel_counts[b] - out.wheel_counts[a]) / counts_per_m
        dist_true_m = WHEEL_RADIUS_M * (truth.wheel_angle_rad[b] - truth.wheel_angle_rad[a])
        assert np.all(np.abs(dist_counts_m - dist_true_m) <= 1.0 / counts_per_m)
    # ~2.6 m forward in 70 s at 3.75 cm/s.
    forward_m = (out.wheel_counts[560] - out.wheel_counts[0]).mean() / counts_per_m
    assert forward_m == pytest.approx(0.0375 * 70.0, rel=0.02)


def test_counts_continue_across_truth_segments() -> None:
    truth = drive_truth()
    whole = MobilityEncoders(EncoderParams(), np.random.default_rng(3)).read(truth)
    split = MobilityEncoders(EncoderParams(), np.random.default_rng(3))
    parts = []
    for sl in (slice(0, 300), slice(300, 801)):
        seg = TruthTrajectory(
            t_s=truth.t_s[sl],
            p_s=truth.p_s[sl],
            q_s_b=truth.q_s_b[sl],
            rocker_rad=truth.rocker_rad[sl],
            bogie_rad=truth.bogie_rad[sl],
            wheel_angle_rad=truth.wheel_angle_rad[sl],
            steer_rad=truth.steer_rad[sl],
            slip=truth.slip[sl],
        )
        parts.append(split.read(seg).wheel_counts)
    np.testing.assert_array_equal(np.concatenate(parts), whole.wheel_counts)


def test_steering_readings_are_quantised_with_the_stated_noise() -> None:
    truth = drive_truth()
    ideal_params = EncoderParams(steer_noise_rad=0.0)
    ideal = MobilityEncoders(ideal_params, np.random.default_rng(4)).read(truth)
    lsb = ideal_params.steer_lsb_rad
    assert np.all(np.abs(ideal.steer_rad - truth.steer_rad) <= 0.5 * lsb + 1e-15)
    np.testing.assert_allclose(ideal.steer_rad, ideal.steer_counts * lsb)

    p = EncoderParams()
    noisy = MobilityEncoders(p, np.random.default_rng(5)).read(truth)
    err = (noisy.steer_rad - truth.steer_rad).ravel()  # 3204 samples
    expected_std = math.sqrt(p.steer_noise_rad**2 + lsb**2 / 12.0)
    assert err.std() == pytest.approx(expected_std, rel=0.06)
    assert abs(err.mean()) < 4.0 * expected_std / math.sqrt(err.size)


def test_bad_parameters_are_rejected() -> None:
    with pytest.raises(InputError, match="motor_counts_per_rev"):
        EncoderParams(motor_counts_per_rev=0)
    with pytest.raises(InputError, match="steer_noise_rad"):
        EncoderParams(steer_noise_rad=-1.0)
