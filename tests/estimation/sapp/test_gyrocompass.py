"""Gyrocompassing at rest (Ali et al. 2005 sec. 5 lessons learned; ``estimation.sapp.gyrocompass``).

References from outside the module: the simulator's LN-200 model (``sim.sensors.imu``) senses the
truth attitude of a tilted rover at rest; truth headings come from scipy's Euler angles; the
error spread is compared with a hand-derived budget (chi-square bounds on the sample
spread); the tilt coupling is checked against the hand-derived ``tan φ · ε``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from estimation.ivp import mars_rotation_ll
from estimation.quaternion import quat_multiply
from estimation.sapp.gyrocompass import (
    GyrocompassParams,
    gyrocompass,
    gyrocompass_samples,
    heading_sigma_rad,
    min_duration_s,
)
from sim.sensors.imu import DEG_PER_H_TO_RAD_S, Ln200Imu, Ln200Params

FloatArray = NDArray[np.float64]

GUSEV_LAT_RAD = math.radians(-14.57)  # Spirit's landing site (sim/world/sites.py), planetographic
HOUR_S = 3600.0


def _truth_q_b_ll(
    heading_deg: float, pitch_deg: float = 8.0, roll_deg: float = -12.0
) -> FloatArray:
    """Tilted rover: R_ll_b = Rz(heading) Ry(pitch) Rx(roll) (ZYX Euler), as q_b_ll."""
    r_ll_b = Rotation.from_euler("ZYX", [heading_deg, pitch_deg, roll_deg], degrees=True)
    q: FloatArray = r_ll_b.inv().as_quat()
    return q


def _tilt_only(q_b_ll: FloatArray, wrong_heading_rad: float) -> FloatArray:
    """A Nadir-Update-like estimate: truth turned about LL Down (tilt right, heading not)."""
    dq = Rotation.from_rotvec([0.0, 0.0, wrong_heading_rad]).as_quat()
    out: FloatArray = quat_multiply(q_b_ll, dq)
    return out


def _wrap(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def _sum_delta_angle(
    imu: Ln200Imu, q_b_ll: FloatArray, lat_rad: float, span_s: float
) -> FloatArray:
    q_ll_b = Rotation.from_quat(q_b_ll).inv().as_quat()
    s = imu.measure_interval(span_s, q_ll_b, mars_rotation_ll(lat_rad))
    out: FloatArray = s.delta_angle_b[0]
    return out


def _nadir_b(q_b_ll: FloatArray) -> FloatArray:
    out: FloatArray = Rotation.from_quat(q_b_ll).apply([0.0, 0.0, 1.0])
    return out


HEADINGS_DEG = [0.0, 1e-7, 359.9999999, 180.0, 179.9999999, 180.0000001, 90.0, 270.0, 33.3]


@pytest.mark.parametrize(
    "heading_deg", HEADINGS_DEG + list(np.random.default_rng(7).uniform(0, 360, 8))
)
def test_noise_free_heading_exact(heading_deg: float) -> None:
    q_true = _truth_q_b_ll(heading_deg)
    imu = Ln200Imu(Ln200Params.noise_free(), np.random.default_rng(0))
    dtheta = _sum_delta_angle(imu, q_true, GUSEV_LAT_RAD, HOUR_S)
    q_est = _tilt_only(q_true, math.radians(123.0 - heading_deg))
    res = gyrocompass(dtheta, HOUR_S, q_est, GUSEV_LAT_RAD)
    truth_heading = math.radians(heading_deg)
    assert abs(_wrap(res.heading_rad - truth_heading)) < 1e-9
    assert 0.0 <= res.heading_rad < 2.0 * math.pi
    # The whole attitude, not just the heading, equals the truth.
    err = Rotation.from_quat(res.q_b_ll) * Rotation.from_quat(q_true).inv()
    assert err.magnitude() < 1e-9
    assert res.horizontal_rate_rad_s == pytest.approx(res.expected_horizontal_rate_rad_s, rel=1e-9)
    assert res.q_b_ll[3] >= 0.0 and np.linalg.norm(res.q_b_ll) == pytest.approx(1.0, abs=1e-12)


def test_raw_samples_agree_with_sum_and_level_rover() -> None:
    """8 Hz samples over 15 min (level rover at 0 deg estimate, truth 250 deg)."""
    q_true = _truth_q_b_ll(250.0, 0.0, 0.0)
    q_ll_b = Rotation.from_quat(q_true).inv().as_quat()
    imu = Ln200Imu(Ln200Params.noise_free(), np.random.default_rng(1))
    n = 7200
    t = np.arange(n + 1) * 0.125
    s = imu.measure(t, np.tile(q_ll_b, (n + 1, 1)), mars_rotation_ll(GUSEV_LAT_RAD))
    res = gyrocompass_samples(s.delta_angle_b, s.dt_s, [0.0, 0.0, 0.0, 1.0], GUSEV_LAT_RAD)
    res_scalar = gyrocompass_samples(s.delta_angle_b, 0.125, [0.0, 0.0, 0.0, 1.0], GUSEV_LAT_RAD)
    assert abs(_wrap(res.heading_rad - math.radians(250.0))) < 1e-9
    assert res_scalar.heading_rad == pytest.approx(res.heading_rad, abs=1e-12)
    assert res.duration_s == pytest.approx(900.0)
    # Level estimate at heading 0: the applied turn is minus the heading (ψ_new = ψ - δ).
    assert _wrap(res.delta_q_ll_angle_rad + math.radians(250.0)) == pytest.approx(0.0, abs=1e-9)


def test_tilt_preserved_by_the_update() -> None:
    rng = np.random.default_rng(3)
    for k in range(20):
        q_true = _truth_q_b_ll(
            float(rng.uniform(0, 360)), float(rng.uniform(-25, 25)), float(rng.uniform(-25, 25))
        )
        imu = Ln200Imu(Ln200Params(), np.random.default_rng(100 + k))
        dtheta = _sum_delta_angle(imu, q_true, GUSEV_LAT_RAD, HOUR_S)
        q_est = _tilt_only(q_true, float(rng.uniform(-math.pi, math.pi)))
        res = gyrocompass(dtheta, HOUR_S, q_est, GUSEV_LAT_RAD)
        np.testing.assert_allclose(_nadir_b(res.q_b_ll), _nadir_b(q_est), atol=1e-12)
        # The applied correction is a pure turn about LL Down: eq. (3)'s form.
        assert res.delta_q_ll[0] == 0.0 and res.delta_q_ll[1] == 0.0


def _gm_averaged_sigma_rad_s(p: Ln200Params, span_s: float) -> float:
    """Bias sigma averaged over the span: turn-on plus the stationary Gauss-Markov part,
    whose time average has variance σ² 2(τ/T)(1 - (τ/T)(1 - e^{-T/τ})) (textbook OU)."""
    x = span_s / p.gyro_bias_corr_time_s
    var_gm = p.gyro_bias_instability_deg_per_h**2 * 2.0 / x * (1.0 - (1.0 - math.exp(-x)) / x)
    return math.sqrt(p.gyro_bias_turn_on_deg_per_h**2 + var_gm) * DEG_PER_H_TO_RAD_S


def test_noisy_spread_matches_predicted_sigma() -> None:
    p = Ln200Params()
    n_seeds = 400
    errors = np.empty(n_seeds)
    rng = np.random.default_rng(11)
    for seed in range(n_seeds):
        heading_deg = float(rng.uniform(0.0, 360.0))
        q_true = _truth_q_b_ll(heading_deg)
        imu = Ln200Imu(p, np.random.default_rng(seed))
        dtheta = _sum_delta_angle(imu, q_true, GUSEV_LAT_RAD, HOUR_S)
        q_est = _tilt_only(q_true, float(rng.uniform(-math.pi, math.pi)))
        res = gyrocompass(dtheta, HOUR_S, q_est, GUSEV_LAT_RAD)
        errors[seed] = _wrap(res.heading_rad - math.radians(heading_deg))
    params = GyrocompassParams(
        gyro_bias_sigma_rad_s=_gm_averaged_sigma_rad_s(p, HOUR_S), tilt_sigma_rad=0.0
    )
    sigma = heading_sigma_rad(GUSEV_LAT_RAD, HOUR_S, params)
    # ~4.2 deg at Gusev: Coarse class, as the module says.
    assert 3.9 < math.degrees(sigma) < 4.4
    sample_sigma = float(np.sqrt(np.mean(errors**2)))
    # RMS of n normal errors: relative standard error 1/sqrt(2n); 3.5 of them.
    tol = 3.5 / math.sqrt(2.0 * n_seeds)
    assert abs(sample_sigma / sigma - 1.0) < tol, (sample_sigma, sigma)
    assert abs(float(errors.mean())) < 3.5 * sigma / math.sqrt(n_seeds)
    assert np.mean(np.abs(errors) < 3.0 * sigma) > 0.985


def test_tilt_error_coupling_is_tan_lat() -> None:
    """A tilt error ε about North turns Ω sin φ into East: heading error tan φ · ε."""
    lat = math.radians(-50.0)
    eps = 1e-3
    q_true = _truth_q_b_ll(40.0, 0.0, 0.0)
    imu = Ln200Imu(Ln200Params.noise_free(), np.random.default_rng(0))
    dtheta = _sum_delta_angle(imu, q_true, lat, HOUR_S)
    q_est = quat_multiply(q_true, Rotation.from_rotvec([eps, 0.0, 0.0]).as_quat())
    res = gyrocompass(dtheta, HOUR_S, q_est, lat)
    err = _wrap(res.heading_rad - math.radians(40.0))
    assert err == pytest.approx(math.tan(lat) * eps, abs=1e-6)
    only_tilt = GyrocompassParams(
        gyro_bias_sigma_rad_s=0.0, gyro_arw_rad_per_sqrt_s=0.0, tilt_sigma_rad=eps
    )
    assert heading_sigma_rad(lat, HOUR_S, only_tilt) == pytest.approx(
        abs(math.tan(lat)) * eps, rel=1e-12
    )


def test_budget_hand_computed_at_gusev() -> None:
    # Ω = 350.89198226 deg/day = 14.6205 deg/h; cos(14.57 deg) = 0.96784.
    horizontal_deg_h = 350.89198226 / 24.0 * math.cos(math.radians(14.57))
    params = GyrocompassParams(tilt_sigma_rad=0.0)
    expected = math.sqrt(1.0**2 + 0.1**2 / 1.0) / horizontal_deg_h  # rad, 1 h span
    assert heading_sigma_rad(GUSEV_LAT_RAD, HOUR_S, params) == pytest.approx(expected, rel=1e-6)
    res_deg = math.degrees(expected)
    assert 4.0 < res_deg < 4.2
    # ARW term 0.1 deg/sqrt(h) / sqrt(T) / 14.15 deg/h = 1 deg at T = (0.1/14.15/(pi/180))^2 h.
    t_min_h = (0.1 / horizontal_deg_h / math.radians(1.0)) ** 2
    assert min_duration_s(GUSEV_LAT_RAD) == pytest.approx(t_min_h * HOUR_S, rel=1e-6)


def test_refuses_near_pole() -> None:
    imu = Ln200Imu(Ln200Params.noise_free(), np.random.default_rng(0))
    for lat_deg in (80.0, -85.0, 90.0):
        lat = math.radians(lat_deg)
        dtheta = _sum_delta_angle(imu, _truth_q_b_ll(10.0), lat, HOUR_S)
        with pytest.raises(ValueError, match="lat_rad: too close to a pole"):
            gyrocompass(dtheta, HOUR_S, [0.0, 0.0, 0.0, 1.0], lat)
    # 65 deg still passes (Ω cos φ = 6.2 deg/h > 5 deg/h), noise-free so exact.
    lat = math.radians(65.0)
    dtheta = _sum_delta_angle(imu, _truth_q_b_ll(10.0), lat, HOUR_S)
    res = gyrocompass(dtheta, HOUR_S, _tilt_only(_truth_q_b_ll(10.0), 1.0), lat)
    assert abs(_wrap(res.heading_rad - math.radians(10.0))) < 1e-9


def test_refuses_short_span() -> None:
    q_true = _truth_q_b_ll(10.0)
    imu = Ln200Imu(Ln200Params.noise_free(), np.random.default_rng(0))
    dtheta = _sum_delta_angle(imu, q_true, GUSEV_LAT_RAD, 300.0)
    with pytest.raises(ValueError, match=r"duration_s: .*too short"):
        gyrocompass(dtheta, 300.0, q_true, GUSEV_LAT_RAD)
    # A noise-free gyro model (ARW 0) has no minimum span.
    perfect = GyrocompassParams(gyro_arw_rad_per_sqrt_s=0.0)
    res = gyrocompass(dtheta, 300.0, _tilt_only(q_true, 2.0), GUSEV_LAT_RAD, params=perfect)
    assert abs(_wrap(res.heading_rad - math.radians(10.0))) < 1e-9


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"delta_angle_sum_b": [1.0, 2.0]}, "delta_angle_sum_b"),
        ({"delta_angle_sum_b": [1.0, np.nan, 0.0]}, "delta_angle_sum_b"),
        ({"duration_s": 0.0}, "duration_s"),
        ({"duration_s": math.inf}, "duration_s"),
        ({"q_b_ll": [0.0, 0.0, 0.0, 0.0]}, "q_b_ll"),
        ({"q_b_ll": [0.0, 0.0, 1.0]}, "q_b_ll"),
        ({"lat_rad": 2.0}, "lat_rad"),
        ({"omega_mars_rad_s": -1e-5}, "omega_mars_rad_s"),
    ],
)
def test_bad_arguments(kwargs: dict[str, object], name: str) -> None:
    args: dict[str, object] = {
        "delta_angle_sum_b": [0.1, 0.0, 0.0],
        "duration_s": HOUR_S,
        "q_b_ll": [0.0, 0.0, 0.0, 1.0],
        "lat_rad": GUSEV_LAT_RAD,
    }
    args.update(kwargs)
    with pytest.raises(ValueError, match=name):
        gyrocompass(**args)  # type: ignore[arg-type]


def test_bad_sample_arguments() -> None:
    with pytest.raises(ValueError, match="delta_angle_b"):
        gyrocompass_samples(np.zeros((5, 2)), 0.125, [0, 0, 0, 1], GUSEV_LAT_RAD)
    with pytest.raises(ValueError, match="dt_s"):
        gyrocompass_samples(np.zeros((5, 3)), np.full(4, 0.125), [0, 0, 0, 1], GUSEV_LAT_RAD)
    with pytest.raises(ValueError, match="dt_s"):
        gyrocompass_samples(np.zeros((5, 3)), -0.125, [0, 0, 0, 1], GUSEV_LAT_RAD)
    with pytest.raises(ValueError, match="tilt_sigma_rad"):
        GyrocompassParams(tilt_sigma_rad=-1.0)
