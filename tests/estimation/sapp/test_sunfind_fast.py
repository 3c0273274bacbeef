"""The sun finder's shortcuts for integer frames against the whole-frame computations they
replace, bit for bit: the histogram median and MAD against ``np.median``, the banded peak
and blobs against smoothing and thresholding the whole frame."""

from __future__ import annotations

import numpy as np
import pytest

from estimation.camera_model import PANCAM, R_b_pancam
from estimation.sapp.sunfind import (
    SunFinderParams,
    _float_blobs,
    _integer_blobs,
    _median_and_mad,
)
from sim.sensors.pancam import render_sun_image


def _frames() -> list[np.ndarray]:
    """Pancam frames with the sun across the field, on its edges, off it; and synthetic
    ones: two suns, a hot pixel, blobs on the top and bottom rows, uint8, flat."""
    rng = np.random.default_rng(21)
    az, el = 0.2, 0.7
    R = R_b_pancam(az, el)
    frames = []
    pixels = [(511.5, 511.5), (2.0, 3.0), (1021.0, 1022.0), (-3.0, 600.0), (500.0, 1026.0)]
    pixels += [tuple(rng.uniform(-30.0, 1054.0, 2)) for _ in range(20)]
    for u, v in pixels:
        frames.append(render_sun_image(R @ PANCAM.unproject(u, v), az, el, rng).image)
    two = frames[0].copy()
    two[100:140, 700:740] = np.maximum(two[100:140, 700:740], frames[0][492:532, 492:532])
    hot = frames[5].copy()
    hot[300, 300] = 4095
    edges = frames[0].copy()
    edges[0:3, 10:60] = 3000
    edges[-2:, 900:1000] = 2500
    flat = np.full((64, 80), 7, dtype=np.uint16)
    small = (frames[0][400:624, 400:624] // 16).astype(np.uint8)
    return frames + [two, hot, edges, flat, small]


@pytest.mark.parametrize("params", [SunFinderParams(), SunFinderParams(threshold_fraction=0.9)])
def test_the_banded_blobs_are_the_whole_frame_blobs(params: SunFinderParams) -> None:
    seen = 0
    for img in _frames():
        background, mad = _median_and_mad(img[::4, ::4])
        noise = max(1.4826 * mad, 1.0 / np.sqrt(12.0))
        for min_rise in (params.min_snr * noise, 0.5):  # 0.5: noise frames go all the way
            fast = _integer_blobs(img, background, min_rise, params.threshold_fraction)
            ref = _float_blobs(img, background, min_rise, params.threshold_fraction)
            assert (fast is None) == (ref is None)
            if fast is None or ref is None:
                continue
            seen += 1
            assert fast[0] == ref[0]
            assert len(fast[1]) == len(ref[1])
            for a, b in zip(fast[1], ref[1], strict=True):
                np.testing.assert_array_equal(a, b)
    assert seen >= 30


def test_the_histogram_median_and_mad_are_numpys() -> None:
    rng = np.random.default_rng(4)
    for k in range(300):
        dtype = (np.uint8, np.uint16)[k % 2]
        top = int(rng.choice([1, 3, 255] if dtype is np.uint8 else [1, 50, 4095, 65535]))
        img = rng.integers(0, top + 1, tuple(rng.integers(1, 40, 2))).astype(dtype)
        sub = img.astype(np.float32)
        background = float(np.median(sub))
        assert _median_and_mad(img) == (background, float(np.median(np.abs(sub - background))))
