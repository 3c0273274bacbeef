"""The VO benchmark on small counts (the full Monte Carlo is ``roverops bench vo``): the
output contract, sane figures from one drive of each kind, the bookkeeping that puts VO's
steps back together as SAPP's position, and the baseline's camera-to-body conversion
against a hand-built motion."""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from bench.registry import BENCHES
from bench.vo import bench_vo
from bench.vo.baseline import body_motion_from_camera
from bench.vo.courses import bench_courses
from sim.errors import InputError
from sim.loop.vo_drive import VO_RIG


@pytest.fixture(scope="module")
def small() -> dict[str, Any]:
    return bench_courses(
        n_rock=1, n_slope=1, n_convergence=1, n_shadow=1, timing_poses=1, timing_repeats=1,
        slope_course_m=3.0, seed=0, workers=1,
    )  # fmt: skip


def test_the_output_contract(small: dict[str, Any]) -> None:
    assert "vo" in BENCHES
    assert set(small) == {"bench", "metrics", "targets", "ok", "machine"}
    assert small["bench"] == "vo"
    metrics, targets = small["metrics"], small["targets"]
    for key in ("rock_course_err_pct", "slope_drive_err_pct", "convergence_pct_gusev",
                "false_update_count", "vo_step_s_1024", "vo_step_s_256"):  # fmt: skip
        assert key in targets
    for key in targets:
        assert key in metrics
    for key in ("rock_course_wheel_err_pct", "slope_drive_wheel_err_pct",
                "convergence_pct_meridiani", "baseline_rock_course_err_pct",
                "baseline_slope_drive_err_pct", "baseline_convergence_pct_gusev",
                "baseline_false_update_count", "baseline_step_s_256"):  # fmt: skip
        assert key in metrics
    json.dumps(small, allow_nan=False)  # NaN became null: valid JSON


def test_the_rock_course_is_the_seeds(small: dict[str, Any]) -> None:
    m = small["metrics"]
    assert m["rock_course_runs"] == 1
    assert 0.08 <= m["rock_course_rock_max_m"] <= 0.20  # rocks, but non-obstacles
    # seven 35 cm steps with 0-85 % slip: the rover truly drove less than commanded
    assert 0.3 < m["rock_course_distance_mean_m"] < 2.45
    assert m["rock_course_step_slip_max_pct"] <= 90.0
    # wheel odometry cannot see the slip; VO can
    assert m["rock_course_wheel_err_pct"] > 10.0
    assert m["rock_course_err_pct"] < 0.5 * m["rock_course_wheel_err_pct"]


def test_the_slope_is_twenty_degrees_and_slips(small: dict[str, Any]) -> None:
    m = small["metrics"]
    assert 18.5 <= m["slope_drive_slope_mean_deg"] <= 21.5
    assert 30.0 <= m["slope_drive_step_slip_max_pct"] <= 65.0  # 30-60 % slip, plus creep
    assert m["slope_drive_wheel_err_pct"] > 15.0


def test_step_figures_are_counts_and_fractions(small: dict[str, Any]) -> None:
    m = small["metrics"]
    for site in ("gusev", "meridiani"):
        assert m[f"convergence_steps_{site}"] == 4  # a 3 m drive in 0.75 m steps
        assert 0.0 <= m[f"convergence_pct_{site}"] <= 100.0
    assert m["accepted_steps"] >= 1 and m["false_update_count"] >= 0
    assert m["step_err_rms_cm"] < 5.0  # a converged step is good to centimetres
    assert m["shadow_steps"] == 4 and m["shadow_pixels_pct_median"] > 1.0  # shadow in view
    # SAPP's position after a drive is the chain of its VO steps (and wheel odometry's
    # steps where VO failed): the bookkeeping of the errors matches the session's
    assert m["vo_chain_gap_max_m"] < 1e-9
    assert m["drives_not_completed"] == 0
    for width in (1024, 256):
        assert m[f"vo_step_s_{width}"] > 0.0 and m[f"baseline_step_s_{width}"] > 0.0


@pytest.mark.parametrize("name", ["n_rock", "n_convergence", "timing_repeats"])
def test_bad_counts_are_refused(name: str) -> None:
    with pytest.raises(InputError, match=name):
        bench_courses(**{name: 0})
    with pytest.raises(InputError, match="slope_course_m"):
        bench_courses(slope_course_m=math.nan)


@pytest.mark.parametrize("name", ["steps_1024", "n_advised", "n_sol235", "ground_map_drives"])
def test_the_whole_bench_refuses_bad_counts_before_it_runs(name: str) -> None:
    with pytest.raises(InputError, match=name):
        bench_vo(**{name: -1})


def test_the_baseline_turns_camera_motion_into_body_motion() -> None:
    rng = np.random.default_rng(2)
    az, el = 0.3, -0.6
    R_b0_b1 = Rotation.from_rotvec(rng.normal(scale=0.1, size=3)).as_matrix()
    p_b1_b0 = rng.normal(scale=0.5, size=3)
    # by hand: P_b1 = A P_b0 + a, and the left camera sees P_c = R_cb (P_b - e)
    A, a = R_b0_b1.T, -R_b0_b1.T @ p_b1_b0
    R_cb = VO_RIG.R_b_cam(az, el).T
    e = VO_RIG.eye_centres_b(az, el)[0]
    R_c1_c0 = R_cb @ A @ R_cb.T
    t_c1 = R_cb @ (A @ e + a - e)
    R, p = body_motion_from_camera(VO_RIG, az, el, R_c1_c0, t_c1)
    np.testing.assert_allclose(R, R_b0_b1, atol=1e-12)
    np.testing.assert_allclose(p, p_b1_b0, atol=1e-12)
