"""The tracking passes of ``VisualOdometry.step`` (estimation/vo/odometry.py,
estimation/vo/tracking.py): MER's tracking from the wheel-odometry prediction (Cheng, Maimone
and Matthies 2005 sec. 2), then again from the first pass's own estimate, searched near at
full resolution, and the checks that keep a step from being accepted on a bad estimate.

The pairs are the simulator's Gusev Navcam renders at 256 px (fixed seeds): seed 2 is a
0.75 m step whose coarse-only pass tracks 26 features and keeps 11 RANSAC inliers, too few.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import Any

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from estimation.vo.odometry import VisualOdometry, VoResult, VoStatus, motion_sigmas
from estimation.vo.params import VoParams
from estimation.vo.sanity import SanityLimits
from estimation.vo.search import PaddedImage
from estimation.vo.tracking import predict_points_b1, track_near
from sim.loop.rover_sim import RoverSim
from sim.loop.vo_drive import VO_MAST_AZ_RAD, VO_MAST_EL_RAD, VO_RIG

STEP_M = 0.75  # MER's step


@dataclass(frozen=True)
class Step:
    """Two 256 px pairs 0.75 m (commanded) apart, the truth motion and the wheel prediction."""

    pairs: tuple[Any, Any]
    R_b0_b1_true: np.ndarray
    p_b1_b0_true: np.ndarray
    kw: dict[str, Any]


def _step(seed: int) -> Step:
    rng = np.random.default_rng(seed)
    yaw = float(rng.uniform(-math.pi, math.pi))
    x, y = (float(v) for v in rng.uniform(-40.0, 40.0, 2))
    sim = RoverSim(
        "gusev", seed, datetime(2004, 3, 1, 12, 0, tzinfo=UTC), yaw_rad=yaw, x_m=x, y_m=y
    )
    first, state0 = sim.navcam_pair(VO_MAST_AZ_RAD, VO_MAST_EL_RAD, rig=VO_RIG), sim.drive_state
    sim.drive_straight(STEP_M)
    second, state1 = sim.navcam_pair(VO_MAST_AZ_RAD, VO_MAST_EL_RAD, rig=VO_RIG), sim.drive_state
    R_s_b0 = Rotation.from_quat(state0.q_s_b).as_matrix()
    kw = {"R_b0_b1_predicted": np.eye(3), "p_b1_b0_predicted": np.array([STEP_M, 0.0, 0.0]),
          "R_s_b0": R_s_b0, "mast_az_rad": VO_MAST_AZ_RAD,
          "mast_el_rad": VO_MAST_EL_RAD}  # fmt: skip
    R_true = R_s_b0.T @ Rotation.from_quat(state1.q_s_b).as_matrix()
    return Step((first, second), R_true, R_s_b0.T @ (state1.p_s - state0.p_s), kw)


@pytest.fixture(scope="module")
def slipped() -> Step:
    return _step(2)


def _run(step: Step, **changes: Any) -> tuple[VisualOdometry, dict[str, Any], VoResult]:
    """One VO step over the pairs; also what the first pair left for it (``state()``)."""
    vo = VisualOdometry(VO_RIG, dataclasses.replace(VoParams().for_width(256), **changes))
    first, second = step.pairs
    assert vo.step(first.left, first.right, **step.kw).status is VoStatus.INITIALISED
    previous = vo.state()["previous"]
    return vo, previous, vo.step(second.left, second.right, **step.kw)


def test_the_second_pass_recovers_what_the_coarse_pass_loses(slipped: Step) -> None:
    _, _, single = _run(slipped, track_passes=1)
    assert single.status is VoStatus.TOO_FEW_INLIERS  # MER's one pass: no update
    assert single.n_inliers < 12
    _, previous, result = _run(slipped)
    assert result.status is VoStatus.CONVERGED, result.reason
    assert result.n_tracked >= 2 * single.n_tracked and result.n_inliers >= 2 * 12
    assert result.motion is not None
    error_m = np.linalg.norm(result.motion.p_b1_b0 - slipped.p_b1_b0_true)
    error_rad = Rotation.from_matrix(result.motion.R_b0_b1 @ slipped.R_b0_b1_true.T).magnitude()
    assert error_m < 0.02 and math.degrees(error_rad) < 0.3  # against 5 cm and 1 deg
    # The features it reports are the final pass's: every tracked pixel is where the true
    # motion takes its previous feature's point (an independent reference), within a pixel
    # for the inliers.
    seen = result.features
    assert len(seen.tracked_uv_px) == len(seen.inlier) == result.n_tracked
    assert int(seen.inlier.sum()) == result.n_inliers
    rows = [np.flatnonzero(np.all(previous["uv_px"] == uv, axis=1)) for uv in
            seen.tracked_previous_uv_px]  # fmt: skip
    assert all(len(r) == 1 for r in rows)  # each is one of the previous pair's features
    p_b0 = previous["p_b"][[r[0] for r in rows]]
    from estimation.vo.geometry import PointedPair

    pair = PointedPair.from_rig(VO_RIG, VO_MAST_AZ_RAD, VO_MAST_EL_RAD)
    uv_true, _ = pair.project(predict_points_b1(p_b0, slipped.R_b0_b1_true, slipped.p_b1_b0_true))
    miss_px = np.linalg.norm(seen.tracked_uv_px - uv_true, axis=1)
    assert np.percentile(miss_px[seen.inlier], 90) < 1.0


def test_an_insane_first_estimate_is_never_accepted(slipped: Step) -> None:
    """The update limit below the slip: the first pass's estimate violates it, so no later
    pass runs from it and the step is judged on that first pass."""
    strict = SanityLimits(max_update_m=0.02)
    _, _, single = _run(slipped, track_passes=1, sanity=strict)
    _, _, result = _run(slipped, sanity=strict)
    assert not result.converged and result.motion is None
    assert (result.status, result.n_tracked, result.n_inliers) == (
        single.status,
        single.n_tracked,
        single.n_inliers,
    )
    # The same with the first pass good enough on its own: INSANE_UPDATE, as MER's.
    good = _step(0)
    _, _, single = _run(good, track_passes=1)
    assert single.converged and single.update is not None
    strict = SanityLimits(max_update_m=0.5 * float(np.linalg.norm(single.update.dp_s)))
    _, _, single = _run(good, track_passes=1, sanity=strict)
    _, _, result = _run(good, sanity=strict)
    assert single.status is result.status is VoStatus.INSANE_UPDATE
    assert result.n_tracked == single.n_tracked and result.motion is None


def test_an_update_too_uncertain_for_the_false_update_line_is_refused(slipped: Step) -> None:
    _, _, good = _run(slipped)
    assert good.motion is not None
    sigma_m, sigma_rad = motion_sigmas(good.motion.covariance)
    assert 0.0 < sigma_m < VoParams().max_sigma_m and 0.0 < sigma_rad < VoParams().max_sigma_rad
    _, _, result = _run(slipped, max_sigma_m=0.5 * sigma_m)
    assert result.status is VoStatus.TOO_UNCERTAIN and "too uncertain" in result.reason
    assert result.motion is None and result.update is not None
    with pytest.raises(ValueError, match="covariance"):
        motion_sigmas(np.eye(3))


def test_the_near_search_finds_a_shift_and_refuses_one_beyond_its_radius() -> None:
    rng = np.random.default_rng(5)
    image = rng.normal(size=(96, 96)).astype(np.float32)
    image = np.asarray(
        np.fft.ifft2(
            np.fft.fft2(image)
            * np.exp(
                -0.5 * (np.hypot(*np.meshgrid(np.fft.fftfreq(96), np.fft.fftfreq(96))) / 0.08) ** 2
            )
        ).real,
        np.float32,
    )  # fmt: skip  (smooth texture, 12 px features)
    shift = np.array([4, -3])  # (u, v) px
    moved = np.roll(image, (shift[1], shift[0]), axis=(0, 1))
    previous, new = PaddedImage(image, 20), PaddedImage(moved, 20)
    uv0 = np.stack(np.meshgrid(np.arange(30, 66, 6), np.arange(30, 66, 6)), -1).reshape(-1, 2)
    kw: dict[str, Any] = {"window_px": 9, "radius_px": 3, "cov_scale": 0.003, "min_sigma_px": 0.05}
    near = track_near(previous, new, uv0, uv0 + shift + 1, **kw)  # prediction 1 px off
    assert near.ok.all()
    miss_px = np.linalg.norm(near.uv_px - (uv0 + shift), axis=1)
    assert miss_px.max() < 0.5 and miss_px.mean() < 0.2  # the biquadratic fit's bias
    far = track_near(previous, new, uv0, uv0 + shift + 6, **kw)  # 6 px off, radius 3
    assert far.ok.mean() < 0.3  # the true peak lies outside: mostly no match at all
    assert np.all(np.isnan(far.uv_px[~far.ok]))
    with pytest.raises(ValueError, match="radius_px"):
        track_near(previous, new, uv0, uv0, **{**kw, "radius_px": 0})


def test_the_tracking_parameters_scale_and_are_validated() -> None:
    full = VoParams()
    assert full.for_width(1024) == full
    mer = full.for_width(256)  # MER's 256 px: detection at full resolution, as before
    assert (mer.feature_level, mer.grid_cell_px, mer.min_separation_px) == (0, 4, 10.0)
    assert (mer.window_px, mer.track_window_px, mer.harris_block_px) == (7, 7, 2)
    assert mer.track_near_radius_px == 3.0 and mer.ransac_threshold_px == 0.75
    # at 1024 features come from the pyramid level about 256 px wide, in its pixels
    assert (full.feature_level, full.grid_cell_px, full.track_window_px) == (2, 4, 29)
    with pytest.raises(ValueError, match="track_guide_min_inliers"):
        VoParams(track_guide_min_inliers=5)
    with pytest.raises(ValueError, match="track_passes"):
        VoParams(track_passes=0)
    with pytest.raises(ValueError, match="feature_level"):
        VoParams(feature_level=-1)
