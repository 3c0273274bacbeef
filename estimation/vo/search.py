"""Correlation search: N templates, each over its own rectangle of candidate positions in an
image, with the subpixel peak and its covariance. The common step of stereo matching and
tracking in Cheng, Maimone and Matthies 2005 sec. 2.

The image is padded once so that every search rectangle can be gathered as one stack
(``estimation.vo.correlation.gather_windows``) however close to an edge it lies; candidate
positions whose window leaves the real image are masked out, never scored. The window sums
of the correlation's denominator come from image-wide box filters, computed once per image.

Pixel coordinates are ``(u, v)`` = (column, row) of the unpadded image
(``estimation.camera_model``). Flight software: numpy and OpenCV.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimation.vo.correlation import (
    best_peaks,
    biquadratic_peak,
    correlation_surfaces,
    gather_windows,
    neighbourhoods,
    peak_covariance,
)

FloatArray = NDArray[np.float64]
Float32Array = NDArray[np.float32]
IntArray = NDArray[np.intp]
BoolArray = NDArray[np.bool_]


class PaddedImage:
    """A float32 image with a zero margin of ``pad_px`` on every side, for window gathers.

    ``image`` (H, W) any real dtype; it is converted to float32 once.
    """

    def __init__(self, image: ArrayLike, pad_px: int) -> None:
        arr = np.asarray(image)
        if arr.ndim != 2 or arr.size == 0:
            raise ValueError(f"image: must be a non-empty 2-D array, got shape {arr.shape}")
        if pad_px < 0:
            raise ValueError(f"pad_px: must be non-negative, got {pad_px}")
        self.image = np.ascontiguousarray(arr, dtype=np.float32)
        self.pad_px = int(pad_px)
        self.padded = np.pad(self.image, self.pad_px)
        self.height, self.width = self.image.shape
        self._sums: dict[int, tuple[FloatArray, FloatArray]] = {}

    def window_sums(self, size: int) -> tuple[FloatArray, FloatArray]:
        """Maps (padded shape) of ``Σ b`` and ``Σ b²`` over the ``size`` x ``size`` window
        centred on each pixel, float64, computed once per size."""
        if size not in self._sums:
            box = cv2.boxFilter(self.padded, cv2.CV_64F, (size, size), normalize=False)
            box2 = cv2.sqrBoxFilter(self.padded, cv2.CV_64F, (size, size), normalize=False)
            self._sums[size] = (np.asarray(box, np.float64), np.asarray(box2, np.float64))
        return self._sums[size]

    def windows(
        self,
        top: IntArray,
        left: IntArray,
        height: int,
        width: int,
        source: NDArray[Any] | None = None,
    ) -> tuple[NDArray[Any], BoolArray]:
        """Windows ``image[top:top+height, left:left+width]`` (N, height, width) in unpadded
        coordinates, and ``fits`` (N,): the window lies inside the padded image. Windows that
        do not fit are gathered from a clamped position and must be discarded. ``source``:
        another array of the padded image's shape to gather from (e.g. a window-sum map)."""
        p = self.pad_px
        t = np.asarray(top, dtype=np.intp) + p
        left_p = np.asarray(left, dtype=np.intp) + p
        max_t = self.padded.shape[0] - height
        max_l = self.padded.shape[1] - width
        fits = (t >= 0) & (left_p >= 0) & (t <= max_t) & (left_p <= max_l)
        out = gather_windows(
            self.padded if source is None else source,
            np.clip(t, 0, max(max_t, 0)),
            np.clip(left_p, 0, max(max_l, 0)),
            height,
            width,
        )
        return out, fits

    def templates_at(self, uv_px: ArrayLike, size: int) -> tuple[Float32Array, BoolArray]:
        """``size`` x ``size`` templates centred on subpixel positions ``uv_px`` (N, 2),
        bilinearly interpolated (exact at integer positions), and ``inside`` (N,): the
        template lies wholly inside the real image."""
        uv = np.asarray(uv_px, dtype=np.float64).reshape(-1, 2)
        half = size // 2
        corner = np.floor(uv).astype(np.intp)
        fx, fy = (uv - corner).T
        grid, fits = self.windows(corner[:, 1] - half, corner[:, 0] - half, size + 1, size + 1)
        wx = fx[:, None, None].astype(np.float32)
        wy = fy[:, None, None].astype(np.float32)
        out: Float32Array = (1 - wy) * (
            (1 - wx) * grid[:, :-1, :-1] + wx * grid[:, :-1, 1:]
        ) + wy * ((1 - wx) * grid[:, 1:, :-1] + wx * grid[:, 1:, 1:])
        inside = (
            fits
            & (uv[:, 0] - half >= 0)
            & (uv[:, 1] - half >= 0)
            & (uv[:, 0] + half <= self.width - 1)
            & (uv[:, 1] + half <= self.height - 1)
        )
        return out, inside


@dataclass(frozen=True)
class SearchResult:
    """Best match of each template: ``uv_px`` (N, 2) subpixel position of the template
    centre in the searched image, ``score`` (N,) the pseudo-normalised correlation at the
    integer peak, ``cov_px2`` (N, 2, 2) the match covariance from the peak curvature (identity
    where not ``ok``), ``ok`` (N,): an interior maximum with a valid biquadratic fit."""

    uv_px: FloatArray
    score: FloatArray
    cov_px2: FloatArray
    ok: BoolArray


def search(
    templates: Float32Array,
    image: PaddedImage,
    top: ArrayLike,
    left: ArrayLike,
    n_rows: int,
    n_cols: int,
    *,
    allowed: BoolArray | None = None,
    cov_scale: float,
    min_sigma_px: float,
) -> SearchResult:
    """Score ``templates`` (N, t, t), t odd, at the candidate centres ``(left + j, top + i)``,
    ``0 <= i < n_rows``, ``0 <= j < n_cols``, and return the best match of each.

    ``top``, ``left`` (N,) integer, unpadded coordinates. ``allowed`` (N, n_rows, n_cols)
    optionally restricts the candidates (e.g. to a disparity range); candidates whose window
    leaves the image are never allowed.
    """
    t = templates.shape[1]
    if t % 2 != 1:
        raise ValueError(f"templates: size must be odd, got {t}")
    if n_rows < 3 or n_cols < 3:
        raise ValueError(f"n_rows/n_cols: need at least 3 x 3 candidates, got {n_rows} x {n_cols}")
    half = t // 2
    top_i = np.asarray(top, dtype=np.intp)
    left_i = np.asarray(left, dtype=np.intp)
    regions, fits = image.windows(top_i - half, left_i - half, n_rows + t - 1, n_cols + t - 1)
    sum_map, sum2_map = image.window_sums(t)
    sums = (
        image.windows(top_i, left_i, n_rows, n_cols, source=sum_map)[0],
        image.windows(top_i, left_i, n_rows, n_cols, source=sum2_map)[0],
    )
    surfaces = correlation_surfaces(templates, regions, sums)
    rows = top_i[:, None] + np.arange(n_rows)[None, :]
    cols = left_i[:, None] + np.arange(n_cols)[None, :]
    row_in = (rows >= half) & (rows <= image.height - 1 - half)
    col_in = (cols >= half) & (cols <= image.width - 1 - half)
    valid = row_in[:, :, None] & col_in[:, None, :] & fits[:, None, None]
    if allowed is not None:
        if allowed.shape != valid.shape:
            raise ValueError(f"allowed: must be {valid.shape}, got {allowed.shape}")
        valid &= allowed
    row, col, score, ok = best_peaks(surfaces, valid)
    offset, hessian, fit_ok = biquadratic_peak(neighbourhoods(surfaces, row, col))
    ok &= fit_ok
    cov = np.broadcast_to(np.eye(2), hessian.shape).copy()
    if np.any(ok):
        cov[ok] = peak_covariance(hessian[ok], cov_scale, min_sigma_px)
    uv = np.stack([left_i + col + offset[:, 0], top_i + row + offset[:, 1]], axis=1)
    return SearchResult(uv.astype(np.float64), score, cov, ok)
