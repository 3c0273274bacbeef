"""Feature-based stereo: match left-image features along the epipolar line of the right
image, triangulate, and keep the good matches.

Cheng, Maimone and Matthies 2005, sec. 2 "Feature-based stereo matching":
"Because the stereo cameras are well calibrated, the stereo matching is done strictly along
the epipolar line with only a few pixels of offset buffer above and below it. We use
pseudo-normalized correlation to determine the best match. In order to obtain sub-pixel
accuracy, a biquadratic polynomial is fit to a 3x3 neighborhood of correlation scores";
then the rays are intersected (eqs. 1-7, ``estimation.vo.triangulation``), "features with
large gaps are thrown out", and each point gets its covariance (eqs. 8-11).

The pair is rectified (``estimation.vo.stereo_rig``): the epipolar line of a left pixel
``(u, v)`` is row ``v`` of the right image and the match lies at ``u - d`` for a disparity
``d > 0``. The search covers rows ``v ± row_slack_px`` and each feature's disparity range.

Covariances: the peak curvature of the stereo correlation gives one 2x2 covariance per
match; it stands for both ``Σ_l`` and ``Σ_r`` of eq. 11 (the correlation surface measures
the relative position of the two windows, and the paper takes both from it). A caller
whose left position is itself uncertain (a tracked feature) adds that covariance to
``Σ_l``. Flight software: numpy and OpenCV; bad arguments raise ``ValueError``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimation.vo.geometry import PointedPair
from estimation.vo.search import PaddedImage, search
from estimation.vo.triangulation import triangulate

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


@dataclass(frozen=True)
class StereoPoints:
    """Stereo-matched features, all arrays over the N input features.

    ``uv_left_px``, ``uv_right_px`` (N, 2) the matched pixels; ``p_b`` (N, 3) the
    triangulated points in the body frame, m; ``cov_b`` (N, 3, 3) their covariance, m²;
    ``score`` (N,) the correlation; ``gap_m`` (N,) the ray gap; ``ok`` (N,) the match passed
    every test (the other values of a failed match are meaningless).
    """

    uv_left_px: FloatArray
    uv_right_px: FloatArray
    p_b: FloatArray
    cov_b: FloatArray
    score: FloatArray
    gap_m: FloatArray
    ok: BoolArray


def stereo_points(
    pair: PointedPair,
    left: PaddedImage,
    right: PaddedImage,
    uv_left_px: ArrayLike,
    disparity_min_px: ArrayLike,
    disparity_max_px: ArrayLike,
    *,
    window_px: int,
    row_slack_px: int,
    min_score: float,
    cov_scale: float,
    min_sigma_px: float,
    max_gap_m: float,
    max_range_m: float,
    cov_left_extra_px2: ArrayLike | None = None,
) -> StereoPoints:
    """Match features ``uv_left_px`` (N, 2, subpixel allowed) into the right image and
    triangulate them (Cheng, Maimone and Matthies 2005 sec. 2, eqs. 1-11).

    ``disparity_min_px`` / ``disparity_max_px``: scalars or (N,) per-feature ranges, px.
    ``window_px`` the odd correlation window; ``row_slack_px`` >= 1 the rows searched above
    and below the epipolar line; matches scoring under ``min_score``, with a ray gap over
    ``max_gap_m`` or farther than ``max_range_m`` from the left eye are rejected.
    ``cov_left_extra_px2`` (N, 2, 2) is added to ``Σ_l`` (see the module docstring).
    """
    uv = np.asarray(uv_left_px, dtype=np.float64).reshape(-1, 2)
    n = uv.shape[0]
    if not np.all(np.isfinite(uv)):
        raise ValueError("uv_left_px: must be finite")
    if window_px < 3 or window_px % 2 != 1:
        raise ValueError(f"window_px: must be odd and at least 3, got {window_px}")
    if row_slack_px < 1:
        raise ValueError(f"row_slack_px: must be at least 1, got {row_slack_px}")
    d_lo = np.broadcast_to(np.asarray(disparity_min_px, dtype=np.float64), (n,))
    d_hi = np.broadcast_to(np.asarray(disparity_max_px, dtype=np.float64), (n,))
    if np.any(~np.isfinite(d_lo)) or np.any(~np.isfinite(d_hi)) or np.any(d_lo > d_hi):
        raise ValueError("disparity_min_px/disparity_max_px: need finite ranges with min <= max")
    if np.any(d_lo < 0.0):
        raise ValueError("disparity_min_px: must be non-negative (points in front of the pair)")
    if n == 0:
        empty = np.empty((0, 2))
        return StereoPoints(
            empty, empty, np.empty((0, 3)), np.empty((0, 3, 3)), np.empty(0), np.empty(0),
            np.empty(0, dtype=bool),
        )  # fmt: skip

    templates, inside = left.templates_at(uv, window_px)
    rows_top = np.rint(uv[:, 1]).astype(np.intp) - row_slack_px
    n_rows = 2 * row_slack_px + 1
    cols_left = np.floor(uv[:, 0] - d_hi).astype(np.intp)
    n_cols = max(3, int(np.max(np.ceil(uv[:, 0] - d_lo) - cols_left)) + 1)
    disparity = uv[:, 0, None] - (cols_left[:, None] + np.arange(n_cols)[None, :])
    in_range = (disparity >= d_lo[:, None]) & (disparity <= d_hi[:, None])
    allowed = np.broadcast_to(in_range[:, None, :], (n, n_rows, n_cols))
    found = search(
        templates, right, rows_top, cols_left, n_rows, n_cols,
        allowed=allowed, cov_scale=cov_scale, min_sigma_px=min_sigma_px,
    )  # fmt: skip

    cov_left = found.cov_px2.copy()
    if cov_left_extra_px2 is not None:
        extra = np.asarray(cov_left_extra_px2, dtype=np.float64)
        if extra.shape != (n, 2, 2):
            raise ValueError(f"cov_left_extra_px2: must be ({n}, 2, 2), got {extra.shape}")
        cov_left = cov_left + extra
    points = triangulate(pair, uv, found.uv_px, cov_left, found.cov_px2)
    distance = np.linalg.norm(points.p_b - pair.c_left_b, axis=1)
    with np.errstate(invalid="ignore"):
        ok = (
            found.ok
            & inside
            & (found.score >= min_score)
            & (uv[:, 0] - found.uv_px[:, 0] > 0.0)
            & (points.gap_m <= max_gap_m)
            & (points.range_left_m > 0.0)
            & (points.range_right_m > 0.0)
            & (distance <= max_range_m)
            & np.all(np.isfinite(points.cov_b), axis=(1, 2))
        )
    return StereoPoints(uv, found.uv_px, points.p_b, points.cov_b, found.score, points.gap_m, ok)
