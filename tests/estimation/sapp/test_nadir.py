"""Nadir Update / Nadir Check (Ali et al. 2005 sec. 2.2.1, 2.3.1) and the Attitude Quality Flag.

References from outside the module: hand-derived tilt and heading formulas, scipy's
``Rotation.align_vectors`` as an independent minimal-rotation solver, the LN-200 IMU model
of ``sim.sensors.imu`` for noisy samples with a known bias.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from estimation.mars_constants import MARS_GRAVITY_M_S2
from estimation.sapp.aqf import AttitudeQuality
from estimation.sapp.nadir import (
    AccelAverager,
    NadirCheckOutcome,
    NadirFailure,
    NadirParams,
    average_accelerometer,
    nadir_check,
    nadir_in_body,
    nadir_update,
    tilt_correction,
    tilt_from_specific_force_rad,
    tilt_of_estimate_rad,
)
from sim.sensors.imu import Ln200Imu, Ln200Params

F = NDArray[np.float64]
DT_S = 0.125  # 8 Hz
DOWN = np.array([0.0, 0.0, 1.0])


def q_b_ll_from_euler_deg(yaw: float, pitch: float, roll: float) -> F:
    """q_b_ll of a rover with NED yaw-pitch-roll (intrinsic ZYX) R_ll_b."""
    out: F = Rotation.from_euler("ZYX", [yaw, pitch, roll], degrees=True).inv().as_quat()
    return out


def specific_force_b(q_b_ll: F) -> F:
    """What a perfect accelerometer reads at rest: f_b = R_b_ll (-g_ll), pointing up."""
    out: F = Rotation.from_quat(q_b_ll).apply([0.0, 0.0, -MARS_GRAVITY_M_S2])
    return out


def clean_samples(q_b_ll: F, n: int = 80) -> tuple[F, F]:
    dv = np.tile(specific_force_b(q_b_ll) * DT_S, (n, 1))
    return dv, np.full(n, DT_S)


def angle(u: F, v: F) -> float:
    return math.atan2(float(np.linalg.norm(np.cross(u, v))), float(np.dot(u, v)))


def heading_deg(q_b_ll: F) -> float:
    """Euler yaw: the LL azimuth of body x (clockwise from North)."""
    x_ll = Rotation.from_quat(q_b_ll).inv().apply([1.0, 0.0, 0.0])
    return math.degrees(math.atan2(x_ll[1], x_ll[0]))


# --- Attitude Quality Flag ---------------------------------------------------------------


def test_aqf_order_and_names_follow_section_2_1() -> None:
    flags = [
        AttitudeQuality.FINE,
        AttitudeQuality.UNKNOWN,
        AttitudeQuality.COARSE,
        AttitudeQuality.TILT_ONLY,
    ]
    assert [f.paper_name for f in sorted(flags)] == ["Unknown", "TiltOnly", "Coarse", "Fine"]
    assert AttitudeQuality.COARSE >= AttitudeQuality.COARSE > AttitudeQuality.TILT_ONLY
    assert AttitudeQuality.UNKNOWN <= AttitudeQuality.FINE
    with pytest.raises(TypeError):
        _ = AttitudeQuality.FINE < 3


# --- tilt ----------------------------------------------------------------------------------


@pytest.mark.parametrize(("pitch", "roll"), [(0.0, 0.0), (12.0, 0.0), (0.0, -7.0), (20.0, 25.0)])
def test_tilts_match_hand_formula(pitch: float, roll: float) -> None:
    # Body z in LL for R_ll_b = Rz Ry(pitch) Rx(roll): its Down component is cos(p) cos(r).
    expected = math.acos(math.cos(math.radians(pitch)) * math.cos(math.radians(roll)))
    q = q_b_ll_from_euler_deg(123.0, pitch, roll)
    assert tilt_of_estimate_rad(q) == pytest.approx(expected, abs=1e-12)
    assert tilt_from_specific_force_rad(specific_force_b(q)) == pytest.approx(expected, abs=1e-12)


# --- averaging -----------------------------------------------------------------------------


def test_invalid_samples_are_dropped() -> None:
    rng = np.random.default_rng(11)
    q = q_b_ll_from_euler_deg(40.0, 6.0, -3.0)
    dv, dt = clean_samples(q)
    dv = dv + rng.normal(0.0, 2e-3 * DT_S, dv.shape)  # make every sample distinct
    valid = np.ones(80, dtype=bool)
    bad = {3: "nan dv", 10: "driver flag", 17: "dt zero", 25: "dt nan", 40: "spike", 55: "zero"}
    dv[3, 1] = np.nan
    valid[10] = False
    dt[17] = 0.0
    dt[25] = np.nan
    dv[40] *= 5.0  # |f| = 18.6 m/s^2, outside the 1 m/s^2 gate
    dv[55] = 0.0  # stuck at zero
    avg = average_accelerometer(dv, dt, valid)
    keep = np.setdiff1d(np.arange(80), list(bad))
    assert (avg.n_valid, avg.n_rejected) == (80 - len(bad), len(bad))
    expected = dv[keep].sum(axis=0) / dt[keep].sum()
    np.testing.assert_allclose(avg.f_b_m_s2, expected, rtol=0, atol=1e-14)
    # The two samples without a usable dt cover no time.
    assert avg.elapsed_s == pytest.approx(78 * DT_S, abs=1e-12)


def test_window_limits_consumption_and_batches_equal_single_samples() -> None:
    q = q_b_ll_from_euler_deg(0.0, 3.0, 4.0)
    dv, dt = clean_samples(q, 120)
    dv = dv * np.linspace(0.99, 1.01, 120)[:, None]
    batch = AccelAverager()
    assert batch.add(dv, dt) == 80
    assert batch.full
    single = AccelAverager()
    taken = [single.add(dv[i], dt[i]) for i in range(120)]
    assert sum(taken) == 80 and taken[79] == 1 and taken[80] == 0
    np.testing.assert_allclose(single.average().f_b_m_s2, batch.average().f_b_m_s2, atol=1e-14)
    # 0.1 s steps do not sum to exactly 10 s; the window still holds 100 of them.
    ten_hz = AccelAverager()
    assert ten_hz.add(np.tile(dv[0] * 0.8, (150, 1)), np.full(150, 0.1)) == 100


# --- Nadir Update --------------------------------------------------------------------------


def test_noise_free_update_recovers_true_tilt() -> None:
    rng = np.random.default_rng(2005)
    for _ in range(25):
        yaw, pitch, roll = rng.uniform(-180, 180), rng.uniform(-30, 30), rng.uniform(-30, 30)
        q_true = q_b_ll_from_euler_deg(yaw, pitch, roll)
        q_est = q_b_ll_from_euler_deg(
            yaw + rng.uniform(-20, 20), pitch + rng.uniform(-15, 15), roll + rng.uniform(-15, 15)
        )
        res = nadir_update(q_est, average_accelerometer(*clean_samples(q_true)))
        assert res.success and res.aqf is AttitudeQuality.TILT_ONLY
        assert angle(nadir_in_body(res.q_b_ll), nadir_in_body(q_true)) < 1e-9
        assert abs(tilt_of_estimate_rad(res.q_b_ll) - tilt_of_estimate_rad(q_true)) < 1e-9
        # δq^B is the minimal rotation n_b -> g_b: scipy's single-pair align_vectors.
        ref, _ = Rotation.align_vectors([nadir_in_body(q_true)], [nadir_in_body(q_est)])
        assert (Rotation.from_quat(res.delta_q_b) * ref.inv()).magnitude() < 1e-9
        assert res.correction_rad == pytest.approx(ref.magnitude(), abs=1e-12)
        # "Yaw unchanged": the correction, seen in LL, has no component about Down.
        c_ll = Rotation.from_quat(res.q_b_ll).inv() * Rotation.from_quat(q_est)
        assert abs(c_ll.as_rotvec()[2]) < 1e-12
        assert abs(c_ll.magnitude() - res.correction_rad) < 1e-9


@pytest.mark.parametrize(("pitch", "roll"), [(5.0, 5.0), (10.0, 0.0), (0.0, -8.0), (3.0, -9.0)])
def test_heading_change_for_a_level_prior_matches_closed_form(pitch: float, roll: float) -> None:
    # Level prior; the correction turns by t about a horizontal axis a at angle alpha from
    # body x (horizontal): x_h' = (cos alpha, sin alpha cos t) in the (a, z x a) basis, so
    # |d heading| = |atan2(|sin alpha| cos t, |cos alpha|) - atan2(|sin alpha|, |cos alpha|)|.
    q_prior = q_b_ll_from_euler_deg(30.0, 0.0, 0.0)
    q_true = q_b_ll_from_euler_deg(30.0, pitch, roll)
    res = nadir_update(q_prior, average_accelerometer(*clean_samples(q_true)))
    n_b, g_b = nadir_in_body(q_prior), nadir_in_body(q_true)
    a_b = np.cross(n_b, g_b) / np.linalg.norm(np.cross(n_b, g_b))
    t = angle(n_b, g_b)
    cos_a, sin_a = abs(a_b[0]), math.hypot(a_b[1], a_b[2])  # body x is horizontal here
    expected = abs(math.atan2(sin_a * math.cos(t), cos_a) - math.atan2(sin_a, cos_a))
    change = abs(heading_deg(res.q_b_ll) - heading_deg(q_prior))
    assert change == pytest.approx(math.degrees(expected), abs=1e-9)
    # Its maximum over alpha, at tan(alpha) = 1/sqrt(cos t): atan((1 - cos t) / (2 sqrt(cos t))).
    bound = math.atan((1.0 - math.cos(t)) / (2.0 * math.sqrt(math.cos(t))))
    assert change <= math.degrees(bound) + 1e-12
    assert bound == pytest.approx(t**2 / 4.0, rel=0.01)  # ~ t^2 / 4


def test_heading_changes_to_first_order_for_a_tilted_prior() -> None:
    # Prior pitched 10 deg, truth also rolled 5 deg: the body-x azimuth moves by about
    # t sin(10 deg) (first order), so the paper's rotation does not keep the Euler yaw.
    q_prior = q_b_ll_from_euler_deg(30.0, 10.0, 0.0)
    q_true = q_b_ll_from_euler_deg(30.0, 10.0, 5.0)
    res = nadir_update(q_prior, average_accelerometer(*clean_samples(q_true)))
    first_order_deg = math.degrees(res.correction_rad) * math.sin(math.radians(10.0))
    change_deg = heading_deg(res.q_b_ll) - heading_deg(q_prior)
    assert abs(change_deg) == pytest.approx(first_order_deg, rel=0.05)  # measured 0.869 deg


def test_upside_down_estimate_is_turned_over() -> None:
    q_true = q_b_ll_from_euler_deg(0.0, 0.0, 0.0)
    q_prior = q_b_ll_from_euler_deg(0.0, 0.0, 180.0)
    dq, turn = tilt_correction(q_prior, [0.0, 0.0, 1.0])
    assert turn == pytest.approx(math.pi, abs=1e-12)
    res = nadir_update(q_prior, average_accelerometer(*clean_samples(q_true)))
    assert angle(nadir_in_body(res.q_b_ll), DOWN) < 1e-12
    c_ll = Rotation.from_quat(res.q_b_ll).inv() * Rotation.from_quat(q_prior)
    assert abs(Rotation.from_quat(dq).as_quat()[2]) < 1e-12 and abs(c_ll.as_quat()[2]) < 1e-12


@pytest.mark.parametrize("seed", [1, 2, 3, 4, 5])
def test_ln200_update_error_is_the_bias_term(seed: int) -> None:
    q_true = q_b_ll_from_euler_deg(75.0, 8.0, -11.0)
    q_prior = q_b_ll_from_euler_deg(70.0, 0.0, 0.0)
    imu = Ln200Imu(Ln200Params(), np.random.default_rng(seed))
    t_s = np.arange(81) * DT_S
    q_ll_b = np.tile(Rotation.from_quat(q_true).inv().as_quat(), (81, 1))
    samples = imu.measure(t_s, q_ll_b, np.zeros(3))
    res = nadir_update(q_prior, average_accelerometer(samples.delta_velocity_b, samples.dt_s))
    assert res.success and res.average.n_valid == 80
    f_true = specific_force_b(q_true)
    bias_term = angle(f_true, f_true + imu.accel_bias_m_s2)  # 300 ug: ~7.9e-4 rad per axis
    error = angle(nadir_in_body(res.q_b_ll), nadir_in_body(q_true))
    # White noise: 50 ug/sqrt(Hz) -> 1.39e-3 m/s^2 per 8 Hz sample, / sqrt(80) / g = 4.7e-5 rad
    # per axis; 2.5e-4 rad is over 5 sigma of the difference.
    assert abs(error - bias_term) < 2.5e-4
    assert error < math.radians(0.15)  # 3 sigma of the 2-axis bias term is ~0.14 deg


def test_failed_sanity_checks_leave_estimate_and_set_unknown() -> None:
    q_true = q_b_ll_from_euler_deg(10.0, 4.0, 2.0)
    q_est = q_b_ll_from_euler_deg(10.0, 0.0, 0.0)
    dv, dt = clean_samples(q_true)
    few = np.zeros(80, dtype=bool)
    few[:39] = True  # one short of min_valid_samples = 40
    cases = {
        NadirFailure.TOO_FEW_SAMPLES: average_accelerometer(dv, dt, few),
        NadirFailure.GRAVITY_MAGNITUDE: average_accelerometer(dv * 3.5 / MARS_GRAVITY_M_S2, dt),
    }
    for reason, avg in cases.items():
        res = nadir_update(q_est, avg)
        assert not res.success and res.failure is reason
        assert res.aqf is AttitudeQuality.UNKNOWN
        np.testing.assert_array_equal(res.q_b_ll, q_est)
        np.testing.assert_array_equal(res.delta_q_b, [0.0, 0.0, 0.0, 1.0])
    # Earth-gravity samples fail the per-sample gate: nothing valid, hence too few.
    earth = average_accelerometer(dv * 9.81 / MARS_GRAVITY_M_S2, dt)
    assert earth.n_valid == 0 and nadir_update(q_est, earth).failure is NadirFailure.TOO_FEW_SAMPLES
    # Exactly 40 valid samples pass.
    few[39] = True
    assert nadir_update(q_est, average_accelerometer(dv, dt, few)).success


# --- Nadir Check ---------------------------------------------------------------------------


def test_nadir_check_pass_fail_abort() -> None:
    q_true = q_b_ll_from_euler_deg(200.0, -5.0, 9.0)
    avg = average_accelerometer(*clean_samples(q_true))
    off_half = q_b_ll_from_euler_deg(200.0, -5.5, 9.0)  # 0.5 deg off in pitch
    off_two = q_b_ll_from_euler_deg(200.0, -5.0, 11.0)  # 2 deg off in roll
    before = off_two.copy()

    ok = nadir_check(off_half, avg, AttitudeQuality.FINE)
    assert ok.outcome is NadirCheckOutcome.PASSED and ok.aqf is AttitudeQuality.FINE
    assert math.degrees(ok.nadir_error_rad) == pytest.approx(0.5, abs=1e-9)

    bad = nadir_check(off_two, avg, AttitudeQuality.FINE)
    assert bad.outcome is NadirCheckOutcome.FAILED and bad.aqf is AttitudeQuality.UNKNOWN
    # n_b = (-sin p, cos p sin r, cos p cos r): a roll step dr moves it along a circle of
    # radius cos p, a chord of 2 cos p sin(dr/2), hence an angle 2 asin(cos p sin(dr/2)).
    expected_deg = math.degrees(
        2.0 * math.asin(math.cos(math.radians(5.0)) * math.sin(math.radians(1.0)))
    )
    assert math.degrees(bad.nadir_error_rad) == pytest.approx(expected_deg, abs=1e-9)
    np.testing.assert_array_equal(off_two, before)  # never changes the estimate

    wide = NadirParams(check_tolerance_rad=math.radians(2.5))
    assert nadir_check(off_two, avg, AttitudeQuality.FINE, wide).outcome is NadirCheckOutcome.PASSED

    dv, dt = clean_samples(q_true)
    for reason, sick in {
        NadirFailure.TOO_FEW_SAMPLES: average_accelerometer(dv[:20], dt[:20]),
        NadirFailure.GRAVITY_MAGNITUDE: average_accelerometer(dv * 0.95, dt),
    }.items():
        res = nadir_check(off_two, sick, AttitudeQuality.COARSE)
        assert res.outcome is NadirCheckOutcome.ABORTED and res.failure is reason
        assert res.aqf is AttitudeQuality.COARSE and math.isnan(res.nadir_error_rad)


# --- argument checks -----------------------------------------------------------------------


def test_bad_arguments_name_the_parameter() -> None:
    avg = average_accelerometer(*clean_samples(q_b_ll_from_euler_deg(0.0, 0.0, 0.0)))
    with pytest.raises(ValueError, match="q_b_ll"):
        nadir_update([0.0, 0.0, 0.0, 2.0], avg)
    with pytest.raises(ValueError, match="q_b_ll"):
        nadir_check([0.0, 0.0, 1.0], avg, AttitudeQuality.FINE)
    with pytest.raises(ValueError, match="min_valid_samples"):
        NadirParams(min_valid_samples=0)
    with pytest.raises(ValueError, match="gravity_tolerance_m_s2"):
        NadirParams(gravity_tolerance_m_s2=-1.0)
    with pytest.raises(ValueError, match="check_tolerance_rad"):
        NadirParams(check_tolerance_rad=4.0)
    with pytest.raises(ValueError, match="delta_velocity_b"):
        AccelAverager().add(np.zeros((5, 2)), np.ones(5))
    with pytest.raises(ValueError, match="dt_s"):
        AccelAverager().add(np.zeros((5, 3)), np.ones(4))
    with pytest.raises(ValueError, match="valid"):
        AccelAverager().add(np.zeros((5, 3)), np.ones(5), np.ones(5))
    with pytest.raises(ValueError, match="f_b_m_s2"):
        tilt_from_specific_force_rad([0.0, 0.0, 0.0])


def test_a_sample_at_a_time_is_add_sample_by_sample() -> None:
    """``add_sample`` (NATE's 8 Hz cycle, plain floats) consumes, gates and sums exactly as
    ``add`` does, to the window's end: valid, flagged, non-finite and out-of-gate samples."""
    rng = np.random.default_rng(16)
    n = 120  # past the 10 s window, so the last samples are left unconsumed
    dv = np.tile([0.0, 0.0, -3.711 * 0.125], (n, 1)) + rng.normal(0.0, 0.002, (n, 3))
    dv[5] = np.nan
    dv[9] *= 3.0  # far out of the gate
    dt = rng.uniform(0.12, 0.13, n)
    valid = rng.uniform(size=n) > 0.1
    one, many = AccelAverager(), AccelAverager()
    consumed = [
        one.add_sample(tuple(dv[k].tolist()), float(dt[k]), bool(valid[k])) for k in range(n)
    ]
    taken = [many.add(dv[k], dt[k], np.array([valid[k]])) for k in range(n)]
    assert consumed == [bool(t) for t in taken] and not all(consumed)
    state_one, state_many = one.state(), many.state()
    assert np.array_equal(state_one.pop("sum_dv_b"), state_many.pop("sum_dv_b"))
    assert state_one == state_many  # bit for bit: the sums, counts and time covered
    assert one.average().n_rejected >= 2
