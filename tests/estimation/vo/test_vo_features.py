"""Corner features: Harris response, one candidate per grid cell, a fixed number kept at a
minimum separation (estimation/vo/features.py; Cheng, Maimone and Matthies 2005 sec. 2 "Feature
Detection")."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from scipy import ndimage

from estimation.vo import features

ARGS: dict[str, Any] = {"block_px": 3, "aperture_px": 3, "harris_k": 0.04}


def _squares(corners: list[tuple[int, int]], size: int = 12) -> np.ndarray:
    """Bright squares on a dark background; their top-left corners at ``corners`` (u, v)."""
    image = np.zeros((128, 128), np.float32)
    for u, v in corners:
        image[v : v + size, u : u + size] = 200.0
    out: np.ndarray = ndimage.gaussian_filter(image, 0.7).astype(np.float32)
    return out


def test_harris_fires_on_corners_not_on_edges_or_flat_ground() -> None:
    image = _squares([(40, 40)], size=30)
    response = features.harris_response(image, 3, 3, 0.04)
    v, u = np.unravel_index(np.argmax(response), response.shape)
    assert min(abs(u - 40), abs(u - 69)) <= 1 and min(abs(v - 40), abs(v - 69)) <= 1
    assert response[55, 40] < 0.0  # the middle of an edge: negative
    assert abs(response[10, 10]) < 1e-6 * response.max()  # flat


def test_one_candidate_per_cell_strongest_first() -> None:
    rng = np.random.default_rng(0)
    response = rng.random((64, 64)).astype(np.float32)
    u, v, strength = features.grid_candidates(response, 8, border_px=4)
    assert len(u) == 7 * 7  # (64 - 2*4) // 8 cells per side
    assert np.all(np.diff(strength) <= 0.0)
    cells = set(zip(((u - 4) // 8).tolist(), ((v - 4) // 8).tolist(), strict=True))
    assert len(cells) == 49
    for x, y, s in zip(u, v, strength, strict=True):
        cx, cy = 4 + 8 * ((x - 4) // 8), 4 + 8 * ((y - 4) // 8)
        assert s == response[cy : cy + 8, cx : cx + 8].max() == response[y, x]


def test_selection_keeps_the_strongest_at_the_minimum_separation() -> None:
    rng = np.random.default_rng(1)
    image = ndimage.gaussian_filter(rng.normal(0.0, 50.0, (256, 256)), 1.0).astype(np.float32)
    uv, strength = features.detect_features(
        image, n_features=60, cell_px=6, min_separation_px=15.0, border_px=8, **ARGS
    )
    assert len(uv) == 60
    assert np.all(np.diff(strength) <= 0.0)
    d = np.linalg.norm(uv[:, None, :] - uv[None, :, :], axis=2) + 1e9 * np.eye(len(uv))
    assert d.min() >= 15.0
    assert uv.min() >= 8 and uv.max() <= 255 - 8
    # Features span the image rather than crowding one patch (the Sol 137 lesson, sec. 4.3).
    assert np.ptp(uv[:, 0]) > 180 and np.ptp(uv[:, 1]) > 180


def test_greedy_separation_takes_candidates_in_order() -> None:
    u = np.array([10, 12, 30, 31, 50])
    v = np.array([10, 10, 10, 10, 10])
    np.testing.assert_array_equal(features.select_separated(u, v, 10, 5.0), [0, 2, 4])
    np.testing.assert_array_equal(features.select_separated(u, v, 2, 5.0), [0, 2])


def test_corners_of_squares_are_found() -> None:
    image = _squares([(20, 20), (70, 30), (40, 80)])
    uv, _ = features.detect_features(
        image, n_features=12, cell_px=4, min_separation_px=6.0, border_px=4, **ARGS
    )
    corners = [(u + du, v + dv) for u, v in [(20, 20), (70, 30), (40, 80)] for du in (0, 11)
               for dv in (0, 11)]  # fmt: skip
    nearest = [min(np.hypot(x - cu, y - cv) for x, y in uv) for cu, cv in corners]
    assert max(nearest) <= 1.5


def test_bad_arguments_are_named() -> None:
    image = np.zeros((32, 32), np.float32)
    with pytest.raises(ValueError, match="cell_px"):
        features.detect_features(
            image, n_features=5, cell_px=8, min_separation_px=8.0, border_px=0, **ARGS
        )
    with pytest.raises(ValueError, match="image"):
        features.harris_response(np.zeros((32, 32)), 3, 3, 0.04)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="aperture_px"):
        features.harris_response(image, 3, 4, 0.04)
    with pytest.raises(ValueError, match="n_features"):
        features.select_separated(np.array([1]), np.array([1]), 0, 2.0)
