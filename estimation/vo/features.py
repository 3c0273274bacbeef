"""Corner features for visual odometry: Harris response, one candidate per grid cell, a fixed
number of the strongest kept at a minimum separation.

Cheng, Maimone and Matthies 2005, sec. 2 "Feature Detection": "An interest
operator tuned for corner detection (e.g. Förstner or Harris) is applied to an image pair,
and pixels with the highest interest values are selected. To reduce the computational cost,
a grid with cells smaller than the minimum distance between features is superimposed on the
left image. The feature with strongest corner response in each grid cell is selected as a
viable candidate. A fixed number of features having the highest interest operator responses
is selected subject to a minimum distance constraint to ensure that features span the
image." Sec. 4.3 tells why the separation matters: too small a value let the features
cluster on one small planar patch and produced false updates.

The Harris response (Harris and Stephens 1988) is OpenCV's ``cornerHarris``:
``det(M) - k trace(M)²`` of the gradient structure tensor ``M`` summed over a block.
Pixel coordinates follow ``estimation.camera_model`` (``u`` column, ``v`` row); features are
integer pixels. Flight software: numpy and OpenCV; bad arguments raise ``ValueError``.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

Float32Array = NDArray[np.float32]
IntArray = NDArray[np.intp]


def harris_response(image: Float32Array, block_px: int, aperture_px: int, k: float) -> Float32Array:
    """Harris corner response of a float32 image, same shape; large positive at corners.

    ``block_px`` the window summing the structure tensor, ``aperture_px`` the Sobel size
    (3, 5 or 7), ``k`` Harris' trace weight (0.04-0.06 usual).
    """
    if image.ndim != 2 or image.dtype != np.float32:
        raise ValueError(f"image: must be a 2-D float32 array, got {image.dtype} {image.shape}")
    if block_px < 2:
        raise ValueError(f"block_px: must be at least 2, got {block_px}")
    if aperture_px not in (3, 5, 7):
        raise ValueError(f"aperture_px: must be 3, 5 or 7, got {aperture_px}")
    if not 0.0 < k < 0.25:
        raise ValueError(f"k: must be in (0, 0.25), got {k}")
    out: Float32Array = np.asarray(cv2.cornerHarris(image, block_px, aperture_px, k), np.float32)
    return out


def grid_candidates(
    response: Float32Array, cell_px: int, border_px: int
) -> tuple[IntArray, IntArray, Float32Array]:
    """The strongest pixel of each ``cell_px`` grid cell, ignoring a ``border_px`` margin.

    Returns ``u``, ``v`` (column, row) and the response of every cell's best pixel whose
    response is positive (a corner rather than an edge or a flat patch), strongest first.
    """
    if response.ndim != 2:
        raise ValueError(f"response: must be 2-D, got shape {response.shape}")
    if cell_px < 1:
        raise ValueError(f"cell_px: must be positive, got {cell_px}")
    if border_px < 0:
        raise ValueError(f"border_px: must be non-negative, got {border_px}")
    h, w = response.shape
    n_rows = (h - 2 * border_px) // cell_px
    n_cols = (w - 2 * border_px) // cell_px
    if n_rows < 1 or n_cols < 1:
        return np.empty(0, np.intp), np.empty(0, np.intp), np.empty(0, np.float32)
    inner = response[
        border_px : border_px + n_rows * cell_px, border_px : border_px + n_cols * cell_px
    ]
    blocks = inner.reshape(n_rows, cell_px, n_cols, cell_px).transpose(0, 2, 1, 3)
    cells = blocks.reshape(n_rows, n_cols, cell_px * cell_px)
    best = np.argmax(cells, axis=2)
    strength = np.take_along_axis(cells, best[..., None], axis=2)[..., 0]
    dv, du = np.divmod(best, cell_px)
    grid_v, grid_u = np.mgrid[0:n_rows, 0:n_cols]
    v = border_px + grid_v * cell_px + dv
    u = border_px + grid_u * cell_px + du
    keep = strength > 0.0
    order = np.argsort(-strength[keep], kind="stable")
    return (
        u[keep][order].astype(np.intp),
        v[keep][order].astype(np.intp),
        strength[keep][order].astype(np.float32),
    )


def select_separated(
    u: IntArray, v: IntArray, n_features: int, min_separation_px: float
) -> IntArray:
    """Indices of up to ``n_features`` candidates, taken in the given (strongest-first)
    order, each at least ``min_separation_px`` from every one taken before it.

    Greedy, with buckets of the separation's size so that each test looks at 3x3 buckets.
    """
    if n_features < 1:
        raise ValueError(f"n_features: must be positive, got {n_features}")
    if not min_separation_px > 0.0:
        raise ValueError(f"min_separation_px: must be positive, got {min_separation_px}")
    d2 = float(min_separation_px) ** 2
    size = float(min_separation_px)
    buckets: dict[tuple[int, int], list[tuple[int, int]]] = {}
    chosen: list[int] = []
    for i, (x, y) in enumerate(zip(u.tolist(), v.tolist(), strict=True)):
        bx, by = int(x // size), int(y // size)
        crowded = any(
            (x - px) ** 2 + (y - py) ** 2 < d2
            for nx in (bx - 1, bx, bx + 1)
            for ny in (by - 1, by, by + 1)
            for px, py in buckets.get((nx, ny), ())
        )
        if crowded:
            continue
        buckets.setdefault((bx, by), []).append((x, y))
        chosen.append(i)
        if len(chosen) == n_features:
            break
    return np.asarray(chosen, dtype=np.intp)


def detect_features(
    image: Float32Array,
    *,
    n_features: int,
    cell_px: int,
    min_separation_px: float,
    border_px: int,
    block_px: int,
    aperture_px: int,
    harris_k: float,
) -> tuple[IntArray, Float32Array]:
    """Corner features of a left image (the whole of Cheng, Maimone and Matthies 2005's "Feature
    Detection").

    Returns ``uv`` (M, 2) integer ``(u, v)`` pixels, ``M <= n_features``, strongest first,
    and their Harris responses (M,). ``cell_px`` must be smaller than ``min_separation_px``
    (the paper's grid), so that no two grid candidates closer than the separation are lost
    to one cell. ``border_px`` keeps features far enough from the edges for the correlation
    windows.
    """
    if not cell_px < min_separation_px:
        raise ValueError(
            f"cell_px: must be smaller than min_separation_px ({cell_px} >= {min_separation_px})"
        )
    response = harris_response(image, block_px, aperture_px, harris_k)
    u, v, strength = grid_candidates(response, cell_px, border_px)
    chosen = select_separated(u, v, n_features, min_separation_px)
    uv = np.stack([u[chosen], v[chosen]], axis=1).astype(np.intp)
    return uv.reshape(-1, 2), strength[chosen]
