"""Pseudo-normalised correlation and the biquadratic subpixel peak, vectorised over features.

Cheng, Maimone and Matthies 2005, sec. 2 "Feature-based stereo matching": the best
match maximises the pseudo-normalised correlation of two windows, and "a biquadratic
polynomial is fit to a 3x3 neighborhood of correlation scores and the peak of this polynomial
is chosen as the correlation peak"; the curvatures of that polynomial give each match's 2x2
covariance (``Σ_l``, ``Σ_r`` of eq. 11). The paper gives no formula for the correlation; the
pseudo-normalised form of Moravec (1977), used by the JPL stereo of Matthies, is

    score = 2 Σ a b / (Σ a² + Σ b²)      with a, b the mean-removed windows,

which is 1 for identical windows, is invariant to a common offset, and unlike the normalised
cross-correlation penalises a difference of contrast (``a = 2 b`` scores 0.8, not 1).

All functions work on stacks: ``N`` templates against ``N`` search regions at once, the
regions gathered with ``numpy.lib.stride_tricks.sliding_window_view``. The window sums of
the denominator come from box filters; the cross term ``Σ a' b`` is one ``einsum`` over all
features for small searches and OpenCV's ``matchTemplate`` per feature for large ones (it is
several times faster there). Pixel coordinates follow ``estimation.camera_model``: ``u``
column, ``v`` row. Flight software: numpy and OpenCV; bad arguments raise ``ValueError``.
"""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]
Float32Array = NDArray[np.float32]
IntArray = NDArray[np.intp]
BoolArray = NDArray[np.bool_]

# Windows whose summed squared deviation is below this (in squared image units) are flat:
# their score is defined as 0 rather than a ratio of rounding errors.
_FLAT_WINDOW_EPS = 1e-6


def pseudo_normalised_correlation(a: ArrayLike, b: ArrayLike) -> float:
    """``2 Σ a' b' / (Σ a'² + Σ b'²)`` of two equal-shape windows, ``'`` = mean removed.

    The reference, one-pair form of :func:`correlation_surfaces`. Two flat windows score 0.

    >>> round(pseudo_normalised_correlation([[1, 2], [3, 4]], [[11, 12], [13, 14]]), 12)
    1.0
    >>> round(pseudo_normalised_correlation([[1, 2], [3, 4]], [[2, 4], [6, 8]]), 12)
    0.8
    """
    x = np.asarray(a, dtype=np.float64)
    y = np.asarray(b, dtype=np.float64)
    if x.shape != y.shape or x.size == 0:
        raise ValueError(f"a, b: need two equal non-empty shapes, got {x.shape} and {y.shape}")
    x = x - x.mean()
    y = y - y.mean()
    denominator = float(np.sum(x * x) + np.sum(y * y))
    if denominator <= _FLAT_WINDOW_EPS:
        return 0.0
    return 2.0 * float(np.sum(x * y)) / denominator


def gather_windows(
    image: NDArray[Any], top: ArrayLike, left: ArrayLike, height: int, width: int
) -> NDArray[Any]:
    """The ``N`` sub-images ``image[top:top+height, left:left+width]``, stacked (N, h, w).

    ``top`` and ``left`` are integer arrays (N,); every window must lie inside the image
    (pad the image first to search near its edges).
    """
    if image.ndim != 2:
        raise ValueError(f"image: must be 2-D, got shape {image.shape}")
    if height < 1 or width < 1:
        raise ValueError(f"height/width: must be positive, got {height} x {width}")
    rows = np.asarray(top, dtype=np.intp)
    cols = np.asarray(left, dtype=np.intp)
    if rows.shape != cols.shape or rows.ndim != 1:
        raise ValueError(f"top/left: need two equal 1-D arrays, got {rows.shape}, {cols.shape}")
    if rows.size and (
        rows.min() < 0
        or cols.min() < 0
        or rows.max() + height > image.shape[0]
        or cols.max() + width > image.shape[1]
    ):
        raise ValueError("top/left: a window falls outside the image")
    windows = sliding_window_view(image, (height, width))
    out: NDArray[Any] = np.ascontiguousarray(windows[rows, cols])
    return out


def correlation_surfaces(
    templates: Float32Array,
    regions: Float32Array,
    window_sums: tuple[FloatArray, FloatArray] | None = None,
) -> Float32Array:
    """Pseudo-normalised score of each template at every position of its search region.

    ``templates`` (N, t, t) and ``regions`` (N, H, W) with ``H, W >= t``; returns (N, H-t+1,
    W-t+1) where ``[n, i, j]`` scores ``templates[n]`` against ``regions[n, i:i+t, j:j+t]``,
    so the match of the template centre is at region pixel ``(i + t//2, j + t//2)``.
    ``window_sums``: optionally the sums of ``b`` and ``b²`` over those windows, each (N,
    H-t+1, W-t+1) (gathered from image-wide box filters, which is cheaper); computed from
    the regions if absent.
    """
    if templates.ndim != 3 or templates.shape[1] != templates.shape[2]:
        raise ValueError(f"templates: must be (N, t, t), got {templates.shape}")
    if regions.ndim != 3 or regions.shape[0] != templates.shape[0]:
        raise ValueError(f"regions: must be (N, H, W) with N = {templates.shape[0]}")
    t = templates.shape[1]
    if regions.shape[1] < t or regions.shape[2] < t:
        raise ValueError(f"regions: {regions.shape[1:]} is smaller than the {t}x{t} template")
    out_shape = (regions.shape[0], regions.shape[1] - t + 1, regions.shape[2] - t + 1)
    if window_sums is None:
        window_sums = _box_sums(regions.astype(np.float64), t)
    sum_b, sum_b2 = window_sums
    if sum_b.shape != out_shape or sum_b2.shape != out_shape:
        raise ValueError(f"window_sums: must be two arrays of shape {out_shape}")
    a = (templates - templates.mean(axis=(1, 2), keepdims=True)).astype(np.float32)
    sum_a2 = np.einsum("nkl,nkl->n", a, a, dtype=np.float64)
    cross = cross_terms(a, regions.astype(np.float32, copy=False))
    sum_b2_centred = sum_b2 - sum_b * sum_b / float(t * t)  # Σ b'² = Σ b² - (Σ b)² / n
    denominator = sum_a2[:, None, None] + sum_b2_centred
    flat = denominator <= _FLAT_WINDOW_EPS
    score = 2.0 * cross / np.where(flat, 1.0, denominator)
    out: Float32Array = np.where(flat, 0.0, score).astype(np.float32)
    return out


# Above this many positions per surface, OpenCV's matchTemplate (one optimised call per
# feature) beats one numpy einsum over all features' gathered windows; below it, the
# einsum's single call wins over the per-call overhead. Measured on the 2-core target.
_LOOP_ABOVE_POSITIONS = 256


def cross_terms(zero_mean_templates: Float32Array, regions: Float32Array) -> Float32Array:
    """``Σ a' b`` of each zero-mean template over every window of its region (N, H-t+1,
    W-t+1); equal to ``Σ a' b'`` because ``Σ a' = 0``, so the window means never enter."""
    n, t = zero_mean_templates.shape[0], zero_mean_templates.shape[1]
    rows, cols = regions.shape[1] - t + 1, regions.shape[2] - t + 1
    if rows * cols <= _LOOP_ABOVE_POSITIONS:
        windows = sliding_window_view(regions, (t, t), axis=(1, 2))
        out: Float32Array = np.einsum("nijkl,nkl->nij", windows, zero_mean_templates)
        return out
    out = np.empty((n, rows, cols), dtype=np.float32)
    for k in range(n):
        out[k] = cv2.matchTemplate(regions[k], zero_mean_templates[k], cv2.TM_CCORR)
    return out


def _box_sums(regions: FloatArray, t: int) -> tuple[FloatArray, FloatArray]:
    """Sums of ``b`` and ``b²`` over every t x t window of each region (summed-area tables)."""
    n, h, w = regions.shape
    table = np.zeros((2, n, h + 1, w + 1))
    table[0, :, 1:, 1:] = regions.cumsum(axis=1).cumsum(axis=2)
    table[1, :, 1:, 1:] = (regions * regions).cumsum(axis=1).cumsum(axis=2)
    sums = table[:, :, t:, t:] - table[:, :, :-t, t:] - table[:, :, t:, :-t] + table[:, :, :-t, :-t]
    return sums[0], sums[1]


# Least-squares fit of f = c0 + c1 x + c2 y + c3 x² + c4 x y + c5 y² to the 3x3 samples at
# x (column offset), y (row offset) in {-1, 0, 1}, row-major: coefficients = _FIT @ samples.
_GRID_Y, _GRID_X = np.mgrid[-1:2, -1:2]
_DESIGN = np.stack(
    [
        np.ones(9),
        _GRID_X.ravel(),
        _GRID_Y.ravel(),
        _GRID_X.ravel() ** 2,
        (_GRID_X * _GRID_Y).ravel(),
        _GRID_Y.ravel() ** 2,
    ],
    axis=1,
).astype(np.float64)
_FIT = np.linalg.pinv(_DESIGN)  # (6, 9)


def biquadratic_peak(samples: ArrayLike) -> tuple[FloatArray, FloatArray, BoolArray]:
    """Peak of the biquadratic fitted to 3x3 score neighbourhoods (Cheng, Maimone and Matthies 2005
    sec. 2).

    ``samples`` (N, 3, 3): scores around each integer peak (row index = ``v``, column = ``u``).
    Returns ``offset`` (N, 2) the peak's ``(du, dv)`` from the centre sample in pixels,
    ``hessian`` (N, 2, 2) the fitted polynomial's second derivatives in ``(u, v)``
    (score / px²), and ``ok`` (N,): the fit has a true maximum (negative definite Hessian)
    within one pixel of the centre. Where not ``ok`` the offset is 0.

    >>> y, x = np.mgrid[-1:2, -1:2]
    >>> s = 1.0 - 0.5 * (x - 0.2) ** 2 - 0.25 * (y + 0.3) ** 2
    >>> off, hess, ok = biquadratic_peak(s[None])
    >>> np.round(off[0], 12).tolist(), (np.round(hess[0], 12) + 0.0).tolist(), bool(ok[0])
    ([0.2, -0.3], [[-1.0, 0.0], [0.0, -0.5]], True)
    """
    s = np.asarray(samples, dtype=np.float64)
    if s.ndim != 3 or s.shape[1:] != (3, 3):
        raise ValueError(f"samples: must be (N, 3, 3), got {s.shape}")
    c = s.reshape(-1, 9) @ _FIT.T  # (N, 6)
    hessian = np.empty((s.shape[0], 2, 2))
    hessian[:, 0, 0] = 2.0 * c[:, 3]
    hessian[:, 0, 1] = hessian[:, 1, 0] = c[:, 4]
    hessian[:, 1, 1] = 2.0 * c[:, 5]
    gradient = c[:, 1:3]
    det = hessian[:, 0, 0] * hessian[:, 1, 1] - hessian[:, 0, 1] ** 2
    is_maximum = (hessian[:, 0, 0] < 0.0) & (det > 0.0)
    safe_det = np.where(is_maximum, det, 1.0)
    # H δ = -g, solved in closed form for the 2x2 (the peak of the fitted quadratic).
    du = -(hessian[:, 1, 1] * gradient[:, 0] - hessian[:, 0, 1] * gradient[:, 1]) / safe_det
    dv = -(hessian[:, 0, 0] * gradient[:, 1] - hessian[:, 1, 0] * gradient[:, 0]) / safe_det
    offset = np.stack([du, dv], axis=1)
    ok = is_maximum & np.all(np.abs(offset) <= 1.0, axis=1)
    offset[~ok] = 0.0
    return offset, hessian, ok


def peak_covariance(hessian: FloatArray, scale: float, min_sigma_px: float) -> FloatArray:
    """Each match's 2x2 pixel covariance from its correlation peak's curvature, (N, 2, 2).

    ``Σ = scale · (-H)⁻¹ + min_sigma_px² I``: a sharp peak (large curvature) is a precise
    match. ``scale`` is the score noise in correlation units (about the score drop one
    sigma of position error causes), calibrated on rendered pairs; the floor stands for
    what the curvature cannot see (rounding, camera calibration). Frames: ``(u, v)`` pixels.
    """
    if not (np.isfinite(scale) and scale > 0.0):
        raise ValueError(f"scale: must be positive, got {scale}")
    if not (np.isfinite(min_sigma_px) and min_sigma_px >= 0.0):
        raise ValueError(f"min_sigma_px: must be non-negative, got {min_sigma_px}")
    h = np.asarray(hessian, dtype=np.float64)
    if h.ndim != 3 or h.shape[1:] != (2, 2):
        raise ValueError(f"hessian: must be (N, 2, 2), got {h.shape}")
    a, b, d = -h[:, 0, 0], -h[:, 0, 1], -h[:, 1, 1]
    det = a * d - b * b
    if np.any(det <= 0.0) or np.any(a <= 0.0):
        raise ValueError("hessian: every peak must be a maximum (negative definite)")
    inverse = np.empty_like(h)
    inverse[:, 0, 0] = d / det
    inverse[:, 1, 1] = a / det
    inverse[:, 0, 1] = inverse[:, 1, 0] = -b / det
    out: FloatArray = scale * inverse + (min_sigma_px**2) * np.eye(2)
    return out


def best_peaks(
    surfaces: Float32Array, valid: BoolArray | None = None
) -> tuple[IntArray, IntArray, FloatArray, BoolArray]:
    """Integer peak of each score surface with its 3x3 neighbourhood inside the surface.

    ``surfaces`` (N, H, W); ``valid`` (N, H, W) marks positions that may be used (e.g. inside
    the image, inside the disparity range); invalid ones never win. Returns ``row``, ``col``
    (N,), ``score`` (N,) and ``ok`` (N,): the peak is valid, not on the surface border, and
    all 8 neighbours are valid, so the biquadratic fit is possible.
    """
    if surfaces.ndim != 3 or surfaces.shape[1] < 3 or surfaces.shape[2] < 3:
        raise ValueError(f"surfaces: must be (N, H>=3, W>=3), got {surfaces.shape}")
    n, h, w = surfaces.shape
    masked = surfaces if valid is None else np.where(valid, surfaces, -np.inf)
    flat_index = np.argmax(masked.reshape(n, -1), axis=1)
    row, col = np.divmod(flat_index, w)
    score = masked.reshape(n, -1)[np.arange(n), flat_index].astype(np.float64)
    ok = np.isfinite(score) & (row >= 1) & (row <= h - 2) & (col >= 1) & (col <= w - 2)
    if valid is not None:
        r = np.clip(row, 1, h - 2)
        c = np.clip(col, 1, w - 2)
        block = valid[
            np.arange(n)[:, None, None], r[:, None, None] + _GRID_Y, c[:, None, None] + _GRID_X
        ]
        ok &= block.all(axis=(1, 2))
    return row.astype(np.intp), col.astype(np.intp), score, ok


def neighbourhoods(surfaces: Float32Array, row: IntArray, col: IntArray) -> FloatArray:
    """The 3x3 score neighbourhoods (N, 3, 3) around ``(row, col)``, clipped to the surface."""
    n, h, w = surfaces.shape
    r = np.clip(row, 1, h - 2)[:, None, None] + _GRID_Y
    c = np.clip(col, 1, w - 2)[:, None, None] + _GRID_X
    out: FloatArray = surfaces[np.arange(n)[:, None, None], r, c].astype(np.float64)
    return out
