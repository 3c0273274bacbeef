"""The visual-odometry front: one call per stereo pair, MER's algorithm end to end.

Cheng, Maimone and Matthies 2005, sec. 2: detect features in the new left image
(``features``), match and triangulate them in the new pair (``stereo``, eqs. 1-11) for the
next step; track the previous pair's features into the new pair with the wheel-odometry
prediction (``tracking``); estimate the motion by closed-form least squares inside RANSAC
(``motion``, eqs. 12-14) and refine it by maximum likelihood (``ml_motion``, eqs. 15-17);
check the update against the February 2005 constraints (``sanity``). "If any internal
consistency check fails, too few feature points are tracked, or the estimation fails to
converge, then no motion estimate update will be produced and the initial estimate
(nominally based on wheel odometry and the IMU) will be maintained" (sec. 1).

Beyond MER: tracking again from VO's own estimate. The paper's tracking searches around
the wheel-odometry prediction, which slip makes tens of pixels wrong, so it searches coarse
to fine on pyramids whose coarse levels match ambiguously (at 256 px a step kept about 46 of
~120 features, docs/BENCHMARKS.md). Here that pass only has to give a first estimate
(RANSAC and ML on as few as ``track_guide_min_inliers`` inliers). If that estimate passes
the sanity constraints, the previous features are predicted again with it, now a few
pixels wrong at most, and searched ``± track_near_radius_px`` at full resolution only
(``tracking.track_near``); RANSAC rescores the first estimate among its samples on this new
set, and ML refits the winner. Passes repeat (``track_passes``) while they gain at least
``track_pass_min_gain`` more inliers; the step is judged on its last fit by MER's rules
(``min_features``, ``min_inliers``, ML convergence, the sanity constraints), so a first
estimate that the constraints refuse is never improved into an accepted one. A search near
a wrong estimate finds few consistent matches, so a wrong first estimate ends as "too few
inliers". Last, an update is refused if its own ML covariance is too wide for the bench's
false-update line (``max_sigma_m``, ``max_sigma_rad``): sec. 4.3's false updates came from
poorly conditioned feature sets, which is what a wide covariance says.

Whatever the outcome, the new pair becomes the reference for the next step (after a
failure VO re-initialises on the pair it has, as MER did after too large a motion).

Frames (docs/CONVENTIONS.md): ``b0`` the body at the previous pair, ``b1`` at the new one;
``R_b0_b1`` takes ``b1`` coordinates to ``b0`` (the new attitude relative to the old);
``p_b1_b0`` is the new body origin in ``b0``, m. ``R_s_b0`` is the estimated attitude in the
Site frame at the previous pair (for the sanity constraints only). Mast angles as in
``estimation.vo.stereo_rig``. Flight software: numpy, scipy, OpenCV.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from estimation.camera_model import check_rotation_matrix
from estimation.vo.features import detect_features
from estimation.vo.geometry import PointedPair
from estimation.vo.ml_motion import MlMotion, refine_ml, skew
from estimation.vo.motion import GapFunction, RansacMotion, motion_weights, ransac_motion
from estimation.vo.params import VoParams
from estimation.vo.sanity import Update, update_of, violation
from estimation.vo.search import PaddedImage
from estimation.vo.shadow_mask import SHADOW_MARGIN_M, in_rover_shadow
from estimation.vo.stereo import stereo_points
from estimation.vo.stereo_rig import StereoRig
from estimation.vo.tracking import Tracked, build_pyramid, pyramid_levels, track_features

FloatArray = NDArray[np.float64]


class VoStatus(enum.Enum):
    """Outcome of one step; only ``CONVERGED`` carries a motion."""

    INITIALISED = "initialised"  # first pair (or after reset): nothing to compare with
    CONVERGED = "converged"
    TOO_FEW_FEATURES = "too few features"
    TOO_FEW_INLIERS = "too few inliers"
    NO_CONVERGENCE = "no convergence"
    INSANE_UPDATE = "update violates a sanity constraint"
    TOO_UNCERTAIN = "update too uncertain"


@dataclass(frozen=True)
class VoMotion:
    """The body motion between two pairs, from VO.

    ``R_b0_b1`` (3, 3) the new attitude relative to the previous (``v_b0 = R_b0_b1 v_b1``);
    ``p_b1_b0`` (3,) the new body origin in the previous body frame, m; ``covariance`` (6, 6)
    of ``(θ, δp)``: ``θ`` (rad) the rotation error on the left in ``b0``
    (``R_true = exp([θ]×) R_b0_b1``), ``δp`` (m) the position error in ``b0``.
    """

    R_b0_b1: FloatArray
    p_b1_b0: FloatArray
    covariance: FloatArray

    @property
    def q_b0_b1(self) -> FloatArray:
        """``R_b0_b1`` as an ``[x, y, z, w]`` quaternion (docs/CONVENTIONS.md)."""
        out: FloatArray = Rotation.from_matrix(self.R_b0_b1).as_quat()
        return out


_NO_PX = np.zeros((0, 2))


@dataclass(frozen=True)
class VoFeatures:
    """What a step saw, in pixels of the rig's images (the paper's Figs. 5-6 draw these):
    ``features_uv_px`` (N, 2) the new pair's stereo-matched features in its left image;
    ``tracked_previous_uv_px`` and ``tracked_uv_px`` (M, 2) the previous pair's features
    tracked into the new left image, before and after; ``inlier`` (M,) those RANSAC kept
    (all False when no motion was estimated)."""

    features_uv_px: FloatArray = field(default_factory=lambda: _NO_PX.copy())
    tracked_previous_uv_px: FloatArray = field(default_factory=lambda: _NO_PX.copy())
    tracked_uv_px: FloatArray = field(default_factory=lambda: _NO_PX.copy())
    inlier: NDArray[np.bool_] = field(default_factory=lambda: np.zeros(0, dtype=bool))


@dataclass(frozen=True)
class VoResult:
    """One step's outcome: ``status`` and a human ``reason``; ``motion`` only when
    converged; ``update`` (the change VO makes to wheel odometry) once a motion was
    estimated, even if the sanity check refused it; the counts: features stereo-matched in
    the new pair, previous features tracked into it, RANSAC inliers, ML iterations;
    ``features`` their pixels."""

    status: VoStatus
    reason: str
    motion: VoMotion | None
    update: Update | None
    n_features: int
    n_tracked: int
    n_inliers: int
    ml_iterations: int
    features: VoFeatures = field(default_factory=VoFeatures)

    @property
    def converged(self) -> bool:
        return self.status is VoStatus.CONVERGED


@dataclass(frozen=True)
class _Frame:
    """What a step keeps of its pair for the next: the left pyramid and the features'
    integer left pixels (M, 2), body-frame points (M, 3) and covariances (M, 3, 3)."""

    left_pyramid: list[PaddedImage]
    uv_px: FloatArray
    p_b: FloatArray
    cov_b: FloatArray


@dataclass(frozen=True)
class _Fit:
    """One tracking pass's estimate: its ``tracked`` features, the RANSAC winner (``None``
    with fewer tracked than a sample), its ML refinement (``None`` with fewer inliers than a
    sample or when it did not converge, after ``ml_iterations``)."""

    tracked: Tracked
    ransac: RansacMotion | None
    ml: MlMotion | None
    ml_iterations: int = 0


class VisualOdometry:
    """MER visual odometry for one stereo rig (module docstring).

    ``params`` must suit the rig's image width (``VoParams().for_width(w)``); ``rng`` drives
    the RANSAC samples (a fixed default seed keeps runs repeatable).
    """

    def __init__(
        self,
        rig: StereoRig,
        params: VoParams | None = None,
        rng: np.random.Generator | None = None,
    ) -> None:
        self.rig = rig
        self.params = params if params is not None else VoParams().for_width(rig.camera.width_px)
        if not isinstance(self.params, VoParams):
            raise ValueError(f"params: must be a VoParams, got {params!r}")
        self.rng = rng if rng is not None else np.random.default_rng(0)
        p = self.params
        self.levels = pyramid_levels(
            p.track_search_radius_px, p.track_coarse_radius_px, p.track_max_levels
        )
        # Pad enough for any window the searches gather near an edge: the left images for
        # the tracking searches, the right one for the stereo search along the rows.
        window = max(p.window_px, p.track_window_px) + 2
        self.left_pad_px = window + math.ceil(
            p.track_search_radius_px / 2**self.levels + p.track_refine_radius_px
            + p.track_near_radius_px
        )  # fmt: skip
        self.pad_px = window + math.ceil(max(p.max_disparity_px, p.row_slack_px))
        self._previous: _Frame | None = None

    def reset(self) -> None:
        """Forget the previous pair: the next step initialises."""
        self._previous = None

    def state(self) -> dict[str, Any]:
        """What the next step needs, as plain data (``estimation.state``): the previous
        pair's left image and features, and the RANSAC generator's position."""
        bits = self.rng.bit_generator.state
        previous = self._previous
        return {
            "rng": {"state": bits["state"], "has_uint32": bits["has_uint32"],
                    "uinteger": bits["uinteger"]},
            "previous": None if previous is None else {
                "left_px": previous.left_pyramid[0].image.copy(),
                "uv_px": previous.uv_px.copy(),
                "p_b": previous.p_b.copy(),
                "cov_b": previous.cov_b.copy(),
            },
        }  # fmt: skip

    def load_state(self, state: Mapping[str, Any]) -> None:
        """Load ``state()``'s output onto a ``VisualOdometry`` built with the same rig,
        parameters and kind of generator (the left pyramid is rebuilt from the image)."""
        bits = dict(self.rng.bit_generator.state)
        bits.update(state["rng"])
        self.rng.bit_generator.state = bits
        previous = state["previous"]
        self._previous = None
        if previous is not None:
            self._previous = _Frame(
                build_pyramid(
                    np.array(previous["left_px"], np.float32), self.levels, self.left_pad_px
                ),
                np.array(previous["uv_px"], dtype=np.float64),
                np.array(previous["p_b"], dtype=np.float64),
                np.array(previous["cov_b"], dtype=np.float64),
            )

    def step(
        self,
        left: ArrayLike,
        right: ArrayLike,
        *,
        R_b0_b1_predicted: ArrayLike,
        p_b1_b0_predicted: ArrayLike,
        R_s_b0: ArrayLike,
        mast_az_rad: float,
        mast_el_rad: float,
        sun_b: ArrayLike | None = None,
    ) -> VoResult:
        """Process a new stereo pair (rectified ``left``, ``right``, (H, W) images of the
        rig's size) taken after the body moved by the predicted (wheel-odometry) motion
        ``R_b0_b1_predicted``, ``p_b1_b0_predicted`` since the previous pair; ``R_s_b0`` the
        estimated attitude at the previous pair; the mast pointing of the new pair.
        ``sun_b``: the Sun's unit vector in the body frame now; given, the new pair's
        features in or at the edge of the rover's own shadow are dropped
        (``estimation.vo.shadow_mask``); None (the default): no mask.
        """
        p = self.params
        left_img = self._image(left, "left")
        right_img = self._image(right, "right")
        R_pred = check_rotation_matrix(R_b0_b1_predicted, "R_b0_b1_predicted")
        t_pred = np.asarray(p_b1_b0_predicted, dtype=np.float64)
        if t_pred.shape != (3,) or not np.all(np.isfinite(t_pred)):
            raise ValueError(f"p_b1_b0_predicted: must be a finite 3-vector, got {t_pred!r}")
        R_s = check_rotation_matrix(R_s_b0, "R_s_b0")
        for name, angle in (("mast_az_rad", mast_az_rad), ("mast_el_rad", mast_el_rad)):
            if not (isinstance(angle, int | float | np.floating) and math.isfinite(angle)):
                raise ValueError(f"{name}: must be a finite angle in radians, got {angle!r}")
        pair = PointedPair.from_rig(self.rig, mast_az_rad, mast_el_rad)

        left_pyramid = build_pyramid(left_img, self.levels, self.left_pad_px)
        right_padded = PaddedImage(right_img, self.pad_px)
        new_frame = self._stereo_features(pair, left_pyramid, right_padded)
        if sun_b is not None:
            new_frame = _shadow_masked(new_frame, sun_b)
        previous, self._previous = self._previous, new_frame
        n_new = len(new_frame.uv_px)
        seen = VoFeatures(features_uv_px=new_frame.uv_px.copy())
        if previous is None:
            return _result(VoStatus.INITIALISED, "first pair", n_features=n_new, features=seen)
        if len(previous.uv_px) < p.min_features:
            reason = f"{len(previous.uv_px)} stereo features in the previous pair"
            return _result(VoStatus.TOO_FEW_FEATURES, f"{reason}, need {p.min_features}",
                           n_features=n_new, features=seen)  # fmt: skip
        # Sec. 2 "Feature Tracking", from the wheel-odometry prediction, then (module
        # docstring) again from each pass's own estimate while that gains inliers.
        tracked = self._track(previous, new_frame, right_padded, pair, R_pred, t_pred)
        fit = self._fit(pair, tracked, None)
        for _ in range(p.track_passes - 1):
            if fit.ml is None or fit.ransac is None or fit.ransac.score < p.track_guide_min_inliers:
                break
            guide = body_motion(fit.ml.R, fit.ml.T, fit.ml.covariance)
            if violation(update_of(guide.R_b0_b1, guide.p_b1_b0, R_pred, t_pred, R_s), p.sanity):
                break  # an insane estimate guides nothing: the step is judged on it
            near = self._track(
                previous, new_frame, right_padded, pair, guide.R_b0_b1, guide.p_b1_b0,
                near_radius_px=math.ceil(p.track_near_radius_px),
            )  # fmt: skip
            refit = self._fit(pair, near, (fit.ml.R, fit.ml.T))
            if refit.ml is None or refit.ransac is None or refit.ransac.score <= fit.ransac.score:
                break
            gain = refit.ransac.score / fit.ransac.score - 1.0
            fit = refit
            if gain < p.track_pass_min_gain:
                break
        return self._judge(fit, seen, previous, n_new, R_pred, t_pred, R_s)

    def _fit(
        self,
        pair: PointedPair,
        tracked: Tracked,
        hypothesis: tuple[FloatArray, FloatArray] | None,
    ) -> _Fit:
        """RANSAC (with ``hypothesis`` rescored among its samples) and the ML refinement of
        its winner, as far as the tracked features allow."""
        p = self.params
        n_tracked = len(tracked.index)
        if n_tracked < p.ransac_sample_size:
            return _Fit(tracked, None, None)
        ransac = self._ransac(pair, tracked, hypothesis)  # fewer samples beside a hypothesis
        if ransac.score < p.ransac_sample_size:
            return _Fit(tracked, ransac, None)
        inl = ransac.inliers
        ml = refine_ml(
            tracked.p_b0[inl], tracked.p_b1[inl], tracked.cov_b0[inl], tracked.cov_b1[inl],
            ransac.R, ransac.T, max_iterations=p.ml_max_iterations, tol_rad=p.ml_tol_rad,
            tol_m=p.ml_tol_m,
        )  # fmt: skip
        return _Fit(tracked, ransac, ml if ml.converged else None, ml.iterations)

    def _judge(
        self,
        fit: _Fit,
        seen: VoFeatures,
        previous: _Frame,
        n_new: int,
        R_pred: FloatArray,
        t_pred: FloatArray,
        R_s: FloatArray,
    ) -> VoResult:
        """The step's outcome from its last fit: MER's minimum counts, convergence and the
        sanity constraints (sec. 2, "Robust Motion Estimation"; the February 2005 checks)."""
        p = self.params
        tracked, ransac, ml = fit.tracked, fit.ransac, fit.ml
        n_tracked = len(tracked.index)
        n_inliers = 0 if ransac is None else ransac.score
        inlier = np.zeros(n_tracked, dtype=bool) if ransac is None else ransac.inliers.copy()
        seen = VoFeatures(
            seen.features_uv_px, previous.uv_px[tracked.index], tracked.uv_left_px.copy(),
            np.asarray(inlier, dtype=bool),
        )  # fmt: skip
        counts: dict[str, Any] = {"n_features": n_new, "n_tracked": n_tracked,
                                  "n_inliers": n_inliers, "features": seen}  # fmt: skip
        if n_tracked < p.min_features:
            reason = f"{n_tracked} features tracked, need {p.min_features}"
            return _result(VoStatus.TOO_FEW_FEATURES, reason, **counts)
        if n_inliers < p.min_inliers:
            reason = f"{n_inliers} RANSAC inliers of {n_tracked}, need {p.min_inliers}"
            return _result(VoStatus.TOO_FEW_INLIERS, reason, **counts)
        if ml is None:
            reason = f"maximum-likelihood refinement did not converge in {fit.ml_iterations} steps"
            return _result(VoStatus.NO_CONVERGENCE, reason, ml_iterations=fit.ml_iterations,
                           **counts)  # fmt: skip
        motion = body_motion(ml.R, ml.T, ml.covariance)
        update = update_of(motion.R_b0_b1, motion.p_b1_b0, R_pred, t_pred, R_s)
        problem = violation(update, p.sanity)
        status = VoStatus.CONVERGED if problem is None else VoStatus.INSANE_UPDATE
        sigma_m, sigma_rad = motion_sigmas(motion.covariance)
        if problem is None and (sigma_m > p.max_sigma_m or sigma_rad > p.max_sigma_rad):
            status = VoStatus.TOO_UNCERTAIN
            problem = (
                f"update too uncertain: σ {100.0 * sigma_m:.2f} cm and "
                f"{math.degrees(sigma_rad):.2f}° on its worst axes, limits "
                f"{100.0 * p.max_sigma_m:.2f} cm and {math.degrees(p.max_sigma_rad):.2f}°"
            )
        return VoResult(
            status, problem or f"{n_inliers} inliers of {n_tracked} tracked features",
            motion if problem is None else None, update, n_features=n_new,
            n_tracked=n_tracked, n_inliers=n_inliers, ml_iterations=ml.iterations,
            features=seen,
        )  # fmt: skip

    def _track(
        self,
        previous: _Frame,
        new: _Frame,
        right: PaddedImage,
        pair: PointedPair,
        R_b0_b1_predicted: FloatArray,
        p_b1_b0_predicted: FloatArray,
        near_radius_px: int = 0,
    ) -> Tracked:
        """The previous pair's features tracked into the new pair (``tracking``); a second
        pass searches ``± near_radius_px`` at full resolution."""
        p = self.params
        return track_features(
            previous_left=previous.left_pyramid, new_left=new.left_pyramid, new_right=right,
            new_pair=pair, uv_previous_px=previous.uv_px, p_b0=previous.p_b,
            cov_b0=previous.cov_b, R_b0_b1=R_b0_b1_predicted, p_b1_b0=p_b1_b0_predicted,
            window_px=p.window_px, search_radius_px=p.track_search_radius_px,
            refine_radius_px=p.track_refine_radius_px, row_slack_px=p.row_slack_px,
            min_disparity_px=p.min_disparity_px, max_disparity_px=p.max_disparity_px,
            min_score=p.min_score, track_min_score=p.track_min_score,
            cov_scale=p.peak_cov_scale, min_sigma_px=p.min_sigma_px,
            max_gap_m=p.max_gap_m, max_range_m=p.max_range_m, max_error_m=p.track_max_error_m,
            max_rotation_error_rad=p.track_max_rotation_error_rad, near_radius_px=near_radius_px,
            track_window_px=p.track_window_px,
        )  # fmt: skip

    def _ransac(
        self,
        pair: PointedPair,
        tracked: Tracked,
        hypothesis: tuple[FloatArray, FloatArray] | None = None,
    ) -> RansacMotion:
        """RANSAC over the closed-form fit (``motion``, eqs. 12-14)."""
        p = self.params
        return ransac_motion(
            tracked.p_b0, tracked.p_b1, motion_weights(tracked.cov_b0, tracked.cov_b1),
            _reprojection_gaps(pair, tracked),
            iterations=p.ransac_iterations if hypothesis is None else p.ransac_guided_iterations,
            sample_size=p.ransac_sample_size, threshold_px=p.ransac_threshold_px, rng=self.rng,
            hypothesis=hypothesis,
        )  # fmt: skip

    def _image(self, image: ArrayLike, name: str) -> NDArray[np.float32]:
        arr = np.asarray(image)
        cam = self.rig.camera
        if arr.shape != (cam.height_px, cam.width_px):
            raise ValueError(
                f"{name}: must be ({cam.height_px}, {cam.width_px}) like the rig, got {arr.shape}"
            )
        if not np.issubdtype(arr.dtype, np.number) or np.iscomplexobj(arr):
            raise ValueError(f"{name}: must be a real-valued image, got dtype {arr.dtype}")
        out = np.asarray(arr, dtype=np.float32)
        if not np.all(np.isfinite(out)):
            raise ValueError(f"{name}: has non-finite pixels")
        return out

    def _stereo_features(
        self, pair: PointedPair, left_pyramid: list[PaddedImage], right: PaddedImage
    ) -> _Frame:
        """Detect, match and triangulate the new pair's features (kept for the next step)."""
        p = self.params
        left = left_pyramid[0]
        # Features are detected at pyramid level ``feature_level`` (params), in its pixels.
        image, scale = left.image, 2**p.feature_level
        for _ in range(p.feature_level):
            image = np.asarray(cv2.pyrDown(image), dtype=np.float32)
        border_px = max(p.window_px, p.track_window_px) // 2 + p.track_refine_radius_px + 1
        uv_level, _ = detect_features(
            image, n_features=p.n_features, cell_px=p.grid_cell_px,
            min_separation_px=p.min_separation_px, border_px=math.ceil(border_px / scale),
            block_px=p.harris_block_px, aperture_px=p.harris_aperture_px, harris_k=p.harris_k,
        )  # fmt: skip
        uv = uv_level * scale
        stereo = stereo_points(
            pair, left, right, uv.astype(np.float64), p.min_disparity_px, p.max_disparity_px,
            window_px=p.window_px, row_slack_px=p.row_slack_px, min_score=p.min_score,
            cov_scale=p.peak_cov_scale, min_sigma_px=p.min_sigma_px, max_gap_m=p.max_gap_m,
            max_range_m=p.max_range_m,
        )  # fmt: skip
        ok = stereo.ok
        return _Frame(left_pyramid, uv[ok].astype(np.float64), stereo.p_b[ok], stereo.cov_b[ok])


def _shadow_masked(frame: _Frame, sun_b: ArrayLike) -> _Frame:
    """``frame`` without the features in the rover's shadow or at its edge."""
    keep = ~in_rover_shadow(frame.p_b, sun_b, SHADOW_MARGIN_M)
    return _Frame(frame.left_pyramid, frame.uv_px[keep], frame.p_b[keep], frame.cov_b[keep])


def _reprojection_gaps(pair: PointedPair, tracked: Tracked) -> GapFunction:
    """RANSAC step 2's gap: reproject the previous points ``p_b0`` under each hypothesis
    ``P_c = R P_p + T`` into the new pair and take the worse of the two eyes' pixel gaps to
    the tracked pixels (the right eye sees depth errors as disparity)."""

    def gap_px(R: FloatArray, T: FloatArray) -> FloatArray:
        moved_b1 = np.einsum("kij,nj->kni", R, tracked.p_b0) + T[:, None, :]
        uv_l, uv_r = pair.project_many(moved_b1)
        gap_l = np.linalg.norm(uv_l - tracked.uv_left_px, axis=-1)
        gap_r = np.linalg.norm(uv_r - tracked.uv_right_px, axis=-1)
        out: FloatArray = np.maximum(gap_l, gap_r)
        return out

    return gap_px


def motion_sigmas(covariance: ArrayLike) -> tuple[float, float]:
    """The standard deviations along the worst axes of a motion's position (m) and rotation
    (rad) errors, from its (6, 6) ``(θ, δp)`` covariance (``VoMotion``)."""
    cov = np.asarray(covariance, dtype=np.float64)
    if cov.shape != (6, 6) or not np.all(np.isfinite(cov)):
        raise ValueError(f"covariance: must be a finite (6, 6) matrix, got shape {cov.shape}")
    rotation = float(np.max(np.linalg.eigvalsh(0.5 * (cov[:3, :3] + cov[:3, :3].T))))
    position = float(np.max(np.linalg.eigvalsh(0.5 * (cov[3:, 3:] + cov[3:, 3:].T))))
    return math.sqrt(max(position, 0.0)), math.sqrt(max(rotation, 0.0))


def body_motion(R_b1_b0: ArrayLike, T_b1: ArrayLike, covariance_phi_T: ArrayLike) -> VoMotion:
    """Convert the estimator's ``P_c = R P_p + T`` (``R = R_b1_b0``, ``T`` the ``b0`` origin in
    ``b1``) and the covariance of ``(φ, T)`` (``φ`` left rotation error in ``b1``) to the body
    motion ``R_b0_b1 = Rᵀ``, ``p_b1_b0 = -Rᵀ T`` and the covariance of ``(θ, δp)`` in ``b0``.

    To first order ``θ = -Rᵀ φ`` and ``δp = -Rᵀ δT - Rᵀ [T]× φ``.
    """
    R = check_rotation_matrix(R_b1_b0, "R_b1_b0")
    T = np.asarray(T_b1, dtype=np.float64).reshape(3)
    cov = np.asarray(covariance_phi_T, dtype=np.float64)
    if cov.shape != (6, 6):
        raise ValueError(f"covariance_phi_T: must be (6, 6), got {cov.shape}")
    J = np.zeros((6, 6))
    J[:3, :3] = -R.T
    J[3:, :3] = -R.T @ skew(T)
    J[3:, 3:] = -R.T
    return VoMotion(R.T.copy(), -R.T @ T, J @ cov @ J.T)


def _result(
    status: VoStatus,
    reason: str,
    *,
    update: Update | None = None,
    n_features: int = 0,
    n_tracked: int = 0,
    n_inliers: int = 0,
    ml_iterations: int = 0,
    features: VoFeatures | None = None,
) -> VoResult:
    """A step without a motion (initialisation or a failure)."""
    return VoResult(
        status, reason, None, update, n_features, n_tracked, n_inliers, ml_iterations,
        features if features is not None else VoFeatures(),
    )  # fmt: skip
