"""Sunfind search geometry, confirmation checks and heading update (Ali et al. 2005 sec. 2.2.2).

References from outside the module: scipy ``Rotation`` (matrix products, relative
rotations), the Pancam pinhole model of ``estimation.camera_model`` (does the sun land in
the image?), hand-derived elevations, and the Mars solar day for the sun's motion.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from estimation.camera_model import PANCAM, PANCAM_FOV_RAD, R_b_pancam
from estimation.ivp import sun_ll as ivp_sun_ll
from estimation.quaternion import quat_multiply
from estimation.sapp.sunfind_search import (
    SunfindSearchParams,
    elevation_check,
    elevation_rad,
    heading_correction_rad,
    heading_delta_quat,
    heading_update,
    motion_check,
    observed_elevation_rad,
    search_guess,
    search_plan,
)

F = NDArray[np.float64]
DOWN = np.array([0.0, 0.0, 1.0])
SOL_S = 88775.244  # mean Mars solar day (Allison and McEwen 2000)
PARAMS = SunfindSearchParams()
R_FOOT = PARAMS.footprint_radius_rad


def q_b_ll_from_euler_deg(yaw: float, pitch: float, roll: float) -> F:
    """q_b_ll of a rover with NED yaw-pitch-roll (intrinsic ZYX) R_ll_b."""
    out: F = Rotation.from_euler("ZYX", [yaw, pitch, roll], degrees=True).inv().as_quat()
    return out


def sun_dir_ll(az_deg: float, el_deg: float) -> F:
    a, e = math.radians(az_deg), math.radians(el_deg)
    return np.array([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), -math.sin(e)])


def rot_angle_rad(q1: F, q2: F) -> float:
    return float((Rotation.from_quat(q1).inv() * Rotation.from_quat(q2)).magnitude())


def random_tilted(rng: np.random.Generator, max_tilt_deg: float = 30.0) -> F:
    return q_b_ll_from_euler_deg(
        rng.uniform(-180.0, 180.0),
        rng.uniform(-max_tilt_deg, max_tilt_deg),
        rng.uniform(-max_tilt_deg, max_tilt_deg),
    )


# --- conventions -------------------------------------------------------------------------


def test_delta_quat_is_rotation_about_ll_down_applied_on_the_right() -> None:
    for angle in (0.3, math.pi / 2, -2.0, math.pi):
        ref = Rotation.from_rotvec([0.0, 0.0, angle]).as_quat()
        assert np.allclose(heading_delta_quat(angle), ref, atol=1e-15)
    rng = np.random.default_rng(1)
    q = random_tilted(rng)
    psi = 0.7
    lhs = Rotation.from_quat(quat_multiply(q, heading_delta_quat(psi))).as_matrix()
    rhs = Rotation.from_quat(q).as_matrix() @ Rotation.from_rotvec([0.0, 0.0, psi]).as_matrix()
    assert np.allclose(lhs, rhs, atol=1e-14)  # R_b_ll(q ⊗ δq) = R_b_ll(q) Rz(ψ)


def test_positive_step_turns_believed_heading_counterclockwise() -> None:
    # Level rover believed to face 30 deg; after ψ = +10 deg it is believed to face 20 deg,
    # so the sun it predicts lies 10 deg further clockwise in the body frame.
    q = q_b_ll_from_euler_deg(30.0, 0.0, 0.0)
    sun = sun_dir_ll(100.0, 40.0)
    g = search_guess(q, sun, 1, math.radians(10.0))
    yaw_deg = Rotation.from_quat(g.q_b_ll).inv().as_euler("ZYX", degrees=True)[0]
    assert yaw_deg == pytest.approx(20.0, abs=1e-12)
    assert math.degrees(g.mast_az_rad) == pytest.approx(100.0 - 20.0, abs=1e-12)
    assert math.degrees(g.mast_el_rad) == pytest.approx(40.0, abs=1e-12)


def test_guesses_and_update_keep_the_tilt() -> None:
    rng = np.random.default_rng(2)
    for _ in range(50):
        q = random_tilted(rng)
        n_b = Rotation.from_quat(q).apply(DOWN)
        z_ll = Rotation.from_quat(q).inv().apply(DOWN)  # body z axis in LL
        sun = sun_dir_ll(rng.uniform(0, 360), rng.uniform(5, 80))
        for i in (1, 5, 17):
            q_i = search_guess(q, sun, i, 0.3).q_b_ll
            assert np.allclose(Rotation.from_quat(q_i).apply(DOWN), n_b, atol=1e-14)
            # body z keeps its angle from Down (its LL z component); only its azimuth turns
            assert Rotation.from_quat(q_i).inv().apply(DOWN)[2] == pytest.approx(z_ll[2], abs=1e-14)
        obs_b = Rotation.from_quat(random_tilted(rng)).apply(sun)
        up = heading_update(q, obs_b, sun)
        assert np.allclose(Rotation.from_quat(up.q_b_ll).apply(DOWN), n_b, atol=1e-14)
    # Negative control: the same δq on the *left* (a body-frame correction) tilts the estimate.
    q = q_b_ll_from_euler_deg(10.0, 20.0, -15.0)
    left = quat_multiply(heading_delta_quat(0.5), q)
    moved = Rotation.from_quat(left).apply(DOWN) - Rotation.from_quat(q).apply(DOWN)
    assert np.linalg.norm(moved) > 0.1


# --- search plan and coverage ------------------------------------------------------------


def test_search_plan_hand_values_and_invariants() -> None:
    # Horizon: the cone is a great circle, Δξ_max = 2 r exactly; Pancam r = 6 deg -> 30.
    p0 = search_plan(0.0)
    assert math.degrees(p0.max_step_rad) == pytest.approx(12.0, abs=1e-12)
    assert p0.n_guesses == 30
    assert search_plan(math.radians(90.0)).n_guesses == 1
    assert search_plan(math.radians(89.99)).n_guesses == 1
    # One image when the whole cone (diameter 2(90 - e)) fits within r of the first aim.
    assert search_plan(math.radians(90.0 - 0.49 * math.degrees(R_FOOT))).n_guesses == 1
    prev = 10**9
    for e_deg in np.linspace(-30.0, 90.0, 241):
        plan = search_plan(math.radians(float(e_deg)))
        assert plan.step_rad <= plan.max_step_rad + 1e-15
        assert plan.n_guesses * plan.step_rad == pytest.approx(2.0 * math.pi, rel=1e-15)
        if e_deg >= 0.0:
            assert plan.n_guesses <= prev
            prev = plan.n_guesses
    wide = search_plan(0.0, SunfindSearchParams(overlap_fraction=0.0))
    assert wide.n_guesses == 23  # 360 / 16


def _cone_ll(e_rad: float, n: int = 1440) -> F:
    az = np.linspace(0.0, 2.0 * math.pi, n, endpoint=False)
    ce = math.cos(e_rad)
    out: F = np.stack([ce * np.cos(az), ce * np.sin(az), -math.sin(e_rad) * np.ones(n)], axis=-1)
    return out


@pytest.mark.parametrize("e_deg", [*range(0, 81, 5), 84, 86, 87.5, 89])
def test_footprints_cover_the_cone_in_the_pancam_image(e_deg: float) -> None:
    rng = np.random.default_rng(int(10 * e_deg))
    q = random_tilted(rng)
    e = math.radians(e_deg)
    plan = search_plan(e)
    sun0 = sun_dir_ll(rng.uniform(0, 360), e_deg)
    cone_b = Rotation.from_quat(q).apply(_cone_ll(e))
    margin_px = math.tan(0.5 * PANCAM_FOV_RAD) * PANCAM.f_px - math.tan(R_FOOT) * PANCAM.f_px
    best_off = np.full(len(cone_b), np.inf)
    boresights = []
    for i in range(plan.n_guesses):
        g = search_guess(q, sun0, i, plan.step_rad)
        R = R_b_pancam(g.mast_az_rad, g.mast_el_rad)
        boresights.append(R[:, 2])
        cam = cone_b @ R  # rows: R^T v_b
        u, v = PANCAM.project(cam)
        c = 0.5 * (PANCAM.width_px - 1)
        inside = np.nan_to_num(np.maximum(np.abs(u - c), np.abs(v - c)), nan=np.inf)
        best_off = np.minimum(best_off, inside)
    # Every direction of the cone is imaged by some guess, clear of the edge by the margin.
    assert np.max(best_off) <= 0.5 * PANCAM.width_px - margin_px + 1e-6
    # Consecutive footprints overlap: the cone point midway in azimuth is in both.
    for i in range(plan.n_guesses if plan.n_guesses > 1 else 0):
        mid_ll = Rotation.from_rotvec([0.0, 0.0, (i + 0.5) * plan.step_rad]).apply(sun0)
        mid_b = Rotation.from_quat(q).apply(mid_ll)
        for k in (i, (i + 1) % plan.n_guesses):
            assert math.acos(min(1.0, float(mid_b @ boresights[k]))) <= R_FOOT + 1e-9


def test_chord_midpoint_formula_leaves_a_gap_this_one_does_not() -> None:
    # The brief's 2 asin(sin r / cos e) spaces the aims 2r apart along the great circle;
    # the cone arc bulges towards the zenith, so its midpoint is more than r from both.
    e, r = math.radians(60.0), math.radians(8.0)
    chord_step = 2.0 * math.asin(math.sin(r) / math.cos(e))
    mid_dist = 2.0 * math.asin(math.cos(e) * math.sin(chord_step / 4.0))
    assert math.degrees(mid_dist - r) == pytest.approx(0.06, abs=0.01)
    plan = search_plan(e, SunfindSearchParams(overlap_fraction=0.0))
    mid = 2.0 * math.asin(math.cos(e) * math.sin(plan.max_step_rad / 4.0))
    assert mid == pytest.approx(r, abs=1e-12)


def test_search_reaches_the_true_sun_for_any_heading_error() -> None:
    rng = np.random.default_rng(3)
    for e_deg in range(5, 81, 5):
        plan = search_plan(math.radians(e_deg))
        for psi_deg in (-180.0, -97.0, -3.0, 0.0, 41.0, 133.0, 179.0, *rng.uniform(-180, 180, 4)):
            q_true = random_tilted(rng)
            q_est = quat_multiply(q_true, heading_delta_quat(-math.radians(psi_deg)))
            sun = sun_dir_ll(rng.uniform(0, 360), e_deg)
            sun_true_b = Rotation.from_quat(q_true).apply(sun)
            found = None
            for i in range(plan.n_guesses):
                g = search_guess(q_est, sun, i, plan.step_rad)
                if math.acos(min(1.0, float(g.sun_b @ sun_true_b))) <= R_FOOT:
                    found = g
                    break
            assert found is not None, (e_deg, psi_deg)
            cam = R_b_pancam(found.mast_az_rad, found.mast_el_rad).T @ sun_true_b
            u, v = PANCAM.project(cam)
            assert bool(PANCAM.in_image(u, v))
            # within half a field of the image centre on both axes
            assert abs(float(u) - 511.5) <= 512.0 and abs(float(v) - 511.5) <= 512.0


# --- confirmation checks -----------------------------------------------------------------


def test_elevation_hand_case_and_heading_independence() -> None:
    # Nose up 10 deg; a sun 20 deg above the body x axis is 30 deg above the horizon.
    q = q_b_ll_from_euler_deg(0.0, 10.0, 0.0)
    sun_b = np.array([math.cos(math.radians(20.0)), 0.0, -math.sin(math.radians(20.0))])
    assert math.degrees(observed_elevation_rad(q, sun_b)) == pytest.approx(30.0, abs=1e-12)
    for yaw in (-170.0, -20.0, 65.0, 150.0):
        q_y = q_b_ll_from_euler_deg(yaw, 10.0, 0.0)
        assert math.degrees(observed_elevation_rad(q_y, sun_b)) == pytest.approx(30.0, abs=1e-12)
    ok = elevation_check(q, sun_b, sun_dir_ll(75.0, 31.5))
    assert ok.passed and math.degrees(ok.error_rad) == pytest.approx(-1.5, abs=1e-12)
    bad = elevation_check(q, sun_b, sun_dir_ll(75.0, 32.5))
    assert not bad.passed and math.degrees(bad.expected_elev_rad) == pytest.approx(32.5)
    assert elevation_rad([1.0, 0.0, -1.0]) == pytest.approx(math.pi / 4, abs=1e-15)


def test_motion_check_with_ivp_suns() -> None:
    lat, lon = math.radians(-14.57), math.radians(175.47)  # Gusev
    t1 = 1.3e8 + 3.0 * 3600.0
    dt = 120.0
    s1, s2 = ivp_sun_ll(t1, lat, lon), ivp_sun_ll(t1 + dt, lat, lon)
    # Outside reference: the sun turns about the pole at 2π per sol, on a circle of radius
    # cos(dec); sin(dec) = sun · pole, pole in LL (cos lat, 0, -sin lat).
    sin_dec = float(s1 @ np.array([math.cos(lat), 0.0, -math.sin(lat)]))
    ref = 2.0 * math.asin(math.sqrt(1.0 - sin_dec**2) * math.sin(math.pi * dt / SOL_S))
    q_true = q_b_ll_from_euler_deg(123.0, 7.0, -4.0)
    o1, o2 = Rotation.from_quat(q_true).apply(s1), Rotation.from_quat(q_true).apply(s2)
    res = motion_check(o1, o2, s1, s2)
    assert res.expected_rad == pytest.approx(ref, rel=2e-3)
    assert res.passed and res.discriminating and abs(res.error_rad) < 1e-12
    # 0.1 deg too much motion along the same great circle, or none at all, fails.
    axis = np.cross(o1, o2) / np.linalg.norm(np.cross(o1, o2))
    o2_bad = Rotation.from_rotvec(axis * (res.observed_rad + math.radians(0.1))).apply(o1)
    moved = motion_check(o1, o2_bad, s1, s2)
    assert not moved.passed and math.degrees(moved.error_rad) == pytest.approx(0.1, abs=1e-9)
    assert not motion_check(o1, o1, s1, s2).passed
    # Images 5 s apart: the sun moves 0.02 deg, under the tolerance: not discriminating.
    short = motion_check(o1, o1, s1, ivp_sun_ll(t1 + 5.0, lat, lon))
    assert short.passed and not short.discriminating


# --- heading update ----------------------------------------------------------------------


def test_heading_update_recovers_true_heading_exactly() -> None:
    rng = np.random.default_rng(4)
    worst = 0.0
    for _ in range(300):
        q_true = random_tilted(rng, 35.0)
        psi = rng.uniform(-math.pi, math.pi)
        q_est = quat_multiply(q_true, heading_delta_quat(-psi))
        sun = sun_dir_ll(rng.uniform(0, 360), rng.uniform(-5, 84))
        obs_b = Rotation.from_quat(q_true).apply(sun)
        up = heading_update(q_est, obs_b, sun)
        assert up.applied
        worst = max(worst, rot_angle_rad(up.q_b_ll, q_true))
        # scipy's relative rotation est^-1 * true is the correction about LL Down
        rel = (Rotation.from_quat(q_est).inv() * Rotation.from_quat(q_true)).as_rotvec()
        assert np.allclose(rel[:2], 0.0, atol=1e-12)
        assert up.delta_q_ll_angle_rad == pytest.approx(rel[2], abs=1e-9)
        assert np.allclose(Rotation.from_quat(up.q_b_ll).apply(sun), obs_b, atol=1e-12)
    assert worst < 1e-12


def test_zenith_rule() -> None:
    q_true = q_b_ll_from_euler_deg(40.0, 5.0, -3.0)
    q_est = quat_multiply(q_true, heading_delta_quat(math.radians(60.0)))
    high = sun_dir_ll(200.0, 86.0)
    skip = heading_update(q_est, Rotation.from_quat(q_true).apply(high), high)
    assert not skip.applied and skip.delta_q_ll_angle_rad == 0.0
    assert np.array_equal(skip.q_b_ll, q_est / np.linalg.norm(q_est))
    lower = sun_dir_ll(200.0, 84.0)
    done = heading_update(q_est, Rotation.from_quat(q_true).apply(lower), lower)
    assert done.applied and rot_angle_rad(done.q_b_ll, q_true) < 1e-12
    # A tighter zone applies the update at 86 deg.
    tight = SunfindSearchParams(zenith_exclusion_rad=math.radians(2.0))
    assert heading_update(q_est, Rotation.from_quat(q_true).apply(high), high, tight).applied
    with pytest.raises(ValueError, match="sun_ll"):
        heading_correction_rad(q_est, [1.0, 0.0, 0.0], [0.0, 0.0, -1.0])


def test_bad_arguments_name_the_parameter() -> None:
    q = np.array([0.0, 0.0, 0.0, 1.0])
    with pytest.raises(ValueError, match="q_b_ll"):
        search_guess([0.0, 0.0, 0.0, 2.0], [1.0, 0.0, 0.0], 0, 0.1)
    with pytest.raises(ValueError, match="sun_ll"):
        search_guess(q, [0.0, 0.0, 0.0], 0, 0.1)
    with pytest.raises(ValueError, match="index"):
        search_guess(q, [1.0, 0.0, 0.0], -1, 0.1)
    with pytest.raises(ValueError, match="step_rad"):
        search_guess(q, [1.0, 0.0, 0.0], 0, 0.0)
    with pytest.raises(ValueError, match="sun_elev_rad"):
        search_plan(2.0)
    with pytest.raises(ValueError, match="overlap_fraction"):
        SunfindSearchParams(overlap_fraction=1.0)
    with pytest.raises(ValueError, match="fov_rad"):
        SunfindSearchParams(fov_rad=0.0)
    with pytest.raises(ValueError, match="sun_b_obs_2"):
        motion_check([1.0, 0, 0], [np.nan, 0, 0], [1.0, 0, 0], [1.0, 0, 0])
