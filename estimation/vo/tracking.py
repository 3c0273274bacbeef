"""Feature tracking into the next stereo pair, guided by the wheel-odometry motion.

Cheng, Maimone and Matthies 2005, sec. 2 "Feature Tracking": "The features
selected from the previous image are projected into the second pair using the approximate
motion provided by onboard wheel odometry. Then a correlation-based search reestablishes
the 2D positions precisely in the second image pair. Stereo matching of these tracked
features determines their new 3D positions. Because the 3D positions of those tracked
features are already known from the previous step, the stereo matching search range can be
greatly reduced. Features whose initial and final 3D positions differ by too large an
amount are filtered out."

How, here:

1. Predict each feature's point in the new body frame ``b1`` from its point in the previous
   body frame ``b0``: ``p_b1 = R_b0_b1ᵀ (p_b0 - p_b1_b0)``, and project it into the new left
   image.
2. Search for the previous left-image window around the prediction. Slip makes the
   prediction tens of pixels wrong, so the search runs coarse to fine on image pyramids
   (``cv2.pyrDown``): the full radius at the coarsest level, then a small refinement at each
   finer one, the subpixel biquadratic peak and its covariance at full resolution.
3. Stereo-match the tracked (subpixel) position in the new right image over the disparities
   the predicted depth allows within the 3D tolerance of step 4 (the "greatly reduced"
   range), triangulate with the tracking covariance added to ``Σ_l``.
4. Reject features whose new point is farther from the predicted one than the tolerance
   ``max_error_m + max_rotation_error_rad * distance`` (distance from the left eye).

A second pass (``near_radius_px`` > 0, driven by ``estimation.vo.odometry``) replaces step 2
with :func:`track_near`: the prediction now comes from the first pass's estimated motion,
so each window is searched only ``± near_radius_px`` around it at full resolution, where a
window is distinctive; a true match more than that radius away shows as a peak on the
search's edge, which is no match. Tracking templates (``track_window_px``) cover the same
patch of ground at every pyramid level (:func:`level_window_px`): at 1024 px a 13 px
window holds one of the many alike pebbles and matches any of them.

The tolerance must exceed the largest wheel-odometry error expected, since the whole of that
error shows in every feature: the slip's translation error everywhere, and its heading
error in proportion to the distance (a 3 deg yaw slip moves a point 10 m away by 0.5 m).

Frames: ``b0``/``b1`` the body at the previous and new pair; ``R_b0_b1`` takes ``b1``
coordinates to ``b0``; ``p_b1_b0`` is the ``b1`` origin in ``b0``, m. Flight software: numpy
and OpenCV; bad arguments raise ``ValueError``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimation.camera_model import check_rotation_matrix
from estimation.vo.geometry import PointedPair
from estimation.vo.search import PaddedImage, SearchResult, search
from estimation.vo.stereo import stereo_points

FloatArray = NDArray[np.float64]
Float32Array = NDArray[np.float32]
BoolArray = NDArray[np.bool_]


def pyramid_levels(search_radius_px: float, coarse_radius_px: float, max_levels: int) -> int:
    """How many halvings bring ``search_radius_px`` down to ``coarse_radius_px`` (at most
    ``max_levels``).

    >>> pyramid_levels(64, 16, 4), pyramid_levels(10, 16, 4), pyramid_levels(1000, 8, 3)
    (2, 0, 3)
    """
    if not (search_radius_px > 0 and coarse_radius_px > 0):
        raise ValueError("search_radius_px/coarse_radius_px: must be positive")
    if max_levels < 0:
        raise ValueError(f"max_levels: must be non-negative, got {max_levels}")
    needed = math.ceil(math.log2(max(search_radius_px / coarse_radius_px, 1.0)))
    return min(needed, max_levels)


def build_pyramid(image: ArrayLike, levels: int, pad_px: int) -> list[PaddedImage]:
    """``levels + 1`` padded images, full resolution first, each half the size of the one
    before (Gaussian ``cv2.pyrDown``: level-L pixel ``x`` is level-0 pixel ``x * 2^L``)."""
    current: Float32Array = np.ascontiguousarray(image, dtype=np.float32)
    out = [PaddedImage(current, pad_px)]
    for _ in range(levels):
        current = np.asarray(cv2.pyrDown(current), dtype=np.float32)
        out.append(PaddedImage(current, pad_px))
    return out


def level_window_px(window_px: int, level: int) -> int:
    """The template size at pyramid ``level`` for ``window_px`` at full resolution: the same
    patch of the scene, halved per level, odd, never under 7 px (or ``window_px``).

    >>> [level_window_px(29, level) for level in range(3)], level_window_px(7, 2)
    ([29, 15, 7], 7)
    """
    size = 2 * round(0.5 * (window_px / (1 << level) - 1)) + 1
    return max(min(7, window_px), size)


def track_left(
    previous: list[PaddedImage],
    new: list[PaddedImage],
    uv_previous_px: ArrayLike,
    uv_predicted_px: ArrayLike,
    *,
    window_px: int,
    search_radius_px: float,
    refine_radius_px: int,
    cov_scale: float,
    min_sigma_px: float,
) -> SearchResult:
    """Coarse-to-fine search for the previous left-image windows in the new left image.

    ``previous``/``new``: pyramids of equal depth (:func:`build_pyramid`);
    ``uv_previous_px`` (N, 2) integer feature pixels in the previous image;
    ``uv_predicted_px`` (N, 2) their predicted pixels in the new one. A feature starts at
    the coarsest level where its template fits in the image (near the edges a coarse
    template would cover the margin) with a search of ``± ceil(search_radius_px / 2^L)``;
    each finer level searches ``± refine_radius_px`` around the doubled estimate. Returns
    the full-resolution match (subpixel, with covariance); ``uv_px`` is NaN where not ok.
    ``window_px`` is the full-resolution template; coarser levels use
    :func:`level_window_px`, the same patch of the scene.
    """
    if len(previous) != len(new) or not previous:
        raise ValueError("previous/new: need two non-empty pyramids of equal depth")
    if refine_radius_px < 1:
        raise ValueError(f"refine_radius_px: must be at least 1, got {refine_radius_px}")
    uv0 = np.asarray(uv_previous_px, dtype=np.float64).reshape(-1, 2)
    shift = np.asarray(uv_predicted_px, dtype=np.float64).reshape(-1, 2) - uv0  # level-0 px
    n = uv0.shape[0]
    alive: BoolArray = np.all(np.isfinite(shift), axis=1)
    shift = np.where(alive[:, None], shift, 0.0)
    started = np.zeros(n, dtype=bool)
    score = np.zeros(n)
    cov = np.broadcast_to(np.eye(2), (n, 2, 2)).copy()
    for level in range(len(previous) - 1, -1, -1):
        scale = 2.0**level
        centre = np.rint(uv0 / scale)  # template centre at this level (integer)
        templates, inside = previous[level].templates_at(centre, level_window_px(window_px, level))
        entering = alive & ~started & inside
        alive &= inside | ~started  # a started feature must stay trackable at each level
        groups = (
            (started & alive, refine_radius_px),
            (entering, math.ceil(search_radius_px / scale)),
        )
        for members, radius in groups:
            k = np.flatnonzero(members)
            if k.size == 0:
                continue
            start = np.rint(centre[k] + shift[k] / scale).astype(np.intp) - radius
            found = search(
                templates[k], new[level], start[:, 1], start[:, 0], 2 * radius + 1,
                2 * radius + 1, cov_scale=cov_scale, min_sigma_px=min_sigma_px,
            )  # fmt: skip
            alive[k] &= found.ok
            shift[k] = np.where(found.ok[:, None], (found.uv_px - centre[k]) * scale, 0.0)
            score[k], cov[k] = found.score, found.cov_px2
        started |= entering
    ok = alive & started
    uv = np.where(ok[:, None], uv0 + shift, np.nan)
    return SearchResult(uv, score, cov, ok)


def track_near(
    previous: PaddedImage,
    new: PaddedImage,
    uv_previous_px: ArrayLike,
    uv_predicted_px: ArrayLike,
    *,
    window_px: int,
    radius_px: int,
    cov_scale: float,
    min_sigma_px: float,
) -> SearchResult:
    """The previous full-resolution windows searched ``± radius_px`` around their predicted
    pixels in the new full-resolution image, no pyramid (the second tracking pass, whose
    prediction comes from the first pass's estimated motion: module docstring). A peak on
    the search's edge is no match (``search`` keeps interior maxima only)."""
    if radius_px < 1:
        raise ValueError(f"radius_px: must be at least 1, got {radius_px}")
    uv0 = np.asarray(uv_previous_px, dtype=np.float64).reshape(-1, 2)
    predicted = np.asarray(uv_predicted_px, dtype=np.float64).reshape(-1, 2)
    finite = np.all(np.isfinite(predicted), axis=1)
    templates, inside = previous.templates_at(np.rint(uv0), window_px)
    start = np.rint(np.where(finite[:, None], predicted, uv0)).astype(np.intp) - radius_px
    found = search(
        templates, new, start[:, 1], start[:, 0], 2 * radius_px + 1, 2 * radius_px + 1,
        cov_scale=cov_scale, min_sigma_px=min_sigma_px,
    )  # fmt: skip
    ok = found.ok & finite & inside
    uv = np.where(ok[:, None], found.uv_px, np.nan)
    return SearchResult(uv, found.score, found.cov_px2, ok)


@dataclass(frozen=True)
class Tracked:
    """Features tracked from the previous pair into the new one (all arrays over M tracked
    features, the survivors): ``index`` (M,) into the previous features; ``p_b0``, ``cov_b0``
    their previous points and covariances (body frame ``b0``); ``p_b1``, ``cov_b1`` the new
    ones (``b1``); ``uv_left_px``, ``uv_right_px`` (M, 2) their pixels in the new pair."""

    index: NDArray[np.intp]
    p_b0: FloatArray
    cov_b0: FloatArray
    p_b1: FloatArray
    cov_b1: FloatArray
    uv_left_px: FloatArray
    uv_right_px: FloatArray


def predict_points_b1(p_b0: ArrayLike, R_b0_b1: ArrayLike, p_b1_b0: ArrayLike) -> FloatArray:
    """Points (N, 3) of the previous body frame expressed in the new one, m:
    ``p_b1 = R_b0_b1ᵀ (p_b0 - p_b1_b0)``."""
    R = check_rotation_matrix(R_b0_b1, "R_b0_b1")
    t = np.asarray(p_b1_b0, dtype=np.float64)
    if t.shape != (3,) or not np.all(np.isfinite(t)):
        raise ValueError(f"p_b1_b0: must be a finite 3-vector, got {p_b1_b0!r}")
    p = np.asarray(p_b0, dtype=np.float64).reshape(-1, 3)
    out: FloatArray = (p - t) @ R  # row-wise R^T (p - t)
    return out


def track_features(
    *,
    previous_left: list[PaddedImage],
    new_left: list[PaddedImage],
    new_right: PaddedImage,
    new_pair: PointedPair,
    uv_previous_px: ArrayLike,
    p_b0: ArrayLike,
    cov_b0: ArrayLike,
    R_b0_b1: ArrayLike,
    p_b1_b0: ArrayLike,
    window_px: int,
    search_radius_px: float,
    refine_radius_px: int,
    row_slack_px: int,
    min_disparity_px: float,
    max_disparity_px: float,
    min_score: float,
    track_min_score: float,
    cov_scale: float,
    min_sigma_px: float,
    max_gap_m: float,
    max_range_m: float,
    max_error_m: float,
    max_rotation_error_rad: float,
    near_radius_px: int = 0,
    track_window_px: int | None = None,
) -> Tracked:
    """Steps 1-4 of the module docstring for the previous features (N,).

    ``uv_previous_px`` (N, 2) integer left pixels in the previous pair, ``p_b0`` (N, 3) and
    ``cov_b0`` (N, 3, 3) their points; ``R_b0_b1``, ``p_b1_b0`` the predicted motion.
    ``track_min_score`` is the least correlation accepted between the pairs (lower than the
    stereo ``min_score``: the viewpoint changed, so the windows foreshorten and rescale).
    ``near_radius_px`` > 0: the second pass, searching ``± near_radius_px`` at full
    resolution only (:func:`track_near`) instead of the pyramid's ``± search_radius_px``.
    ``track_window_px``: the tracking template at full resolution (default ``window_px``,
    the stereo template).
    Returns the survivors only.
    """
    if not max_error_m > 0.0:
        raise ValueError(f"max_error_m: must be positive, got {max_error_m}")
    if not max_rotation_error_rad >= 0.0:
        raise ValueError(f"max_rotation_error_rad: must be >= 0, got {max_rotation_error_rad}")
    points_b0 = np.asarray(p_b0, dtype=np.float64).reshape(-1, 3)
    covs_b0 = np.asarray(cov_b0, dtype=np.float64).reshape(-1, 3, 3)
    uv0 = np.asarray(uv_previous_px, dtype=np.float64).reshape(-1, 2)
    if not (points_b0.shape[0] == covs_b0.shape[0] == uv0.shape[0]):
        raise ValueError("uv_previous_px/p_b0/cov_b0: need the same number of features")
    predicted_b1 = predict_points_b1(points_b0, R_b0_b1, p_b1_b0)  # step 1
    uv_predicted, _ = new_pair.project(predicted_b1)
    track_window = window_px if track_window_px is None else track_window_px
    if near_radius_px > 0:  # step 2, second pass
        found = track_near(
            previous_left[0], new_left[0], uv0, uv_predicted, window_px=track_window,
            radius_px=near_radius_px, cov_scale=cov_scale, min_sigma_px=min_sigma_px,
        )  # fmt: skip
    else:  # step 2, first pass
        found = track_left(
            previous_left, new_left, uv0, uv_predicted,
            window_px=track_window, search_radius_px=search_radius_px,
            refine_radius_px=refine_radius_px, cov_scale=cov_scale, min_sigma_px=min_sigma_px,
        )  # fmt: skip
    keep = np.flatnonzero(found.ok & (found.score >= track_min_score))
    predicted = predicted_b1[keep]
    # Step 3: the disparities a point within the tolerance of its prediction can have.
    depth = ((predicted - new_pair.c_left_b) @ new_pair.R_b_cam)[:, 2]
    distance = np.linalg.norm(predicted - new_pair.c_left_b, axis=1)
    tolerance = max_error_m + max_rotation_error_rad * distance
    f_b = new_pair.camera.f_px * float(np.linalg.norm(new_pair.baseline_b))
    near = depth - tolerance
    d_hi = np.where(near > f_b / max_disparity_px, f_b / np.maximum(near, 1e-9), max_disparity_px)
    d_lo = np.maximum(f_b / (depth + tolerance), min_disparity_px)
    d_hi = np.clip(d_hi, d_lo, max_disparity_px)
    stereo = stereo_points(
        new_pair, new_left[0], new_right, found.uv_px[keep], d_lo, d_hi,
        window_px=window_px, row_slack_px=row_slack_px, min_score=min_score,
        cov_scale=cov_scale, min_sigma_px=min_sigma_px, max_gap_m=max_gap_m,
        max_range_m=max_range_m, cov_left_extra_px2=found.cov_px2[keep],
    )  # fmt: skip
    error = np.linalg.norm(stereo.p_b - predicted, axis=1)
    with np.errstate(invalid="ignore"):
        good = stereo.ok & (error <= tolerance)  # step 4
    index = keep[good]
    return Tracked(
        index, points_b0[index], covs_b0[index], stereo.p_b[good], stereo.cov_b[good],
        stereo.uv_left_px[good], stereo.uv_right_px[good],
    )  # fmt: skip
