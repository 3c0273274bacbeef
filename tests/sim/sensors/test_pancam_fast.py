"""The fast paths of Pancam sun imaging against the whole-frame computations they replace,
bit for bit. The renderer: rays traced and blurred only around the disk, the read noise
drawn in bulk; suns across the field, on its edges, just off it (the PSF wings only), well
off it and behind the camera. The sun finder on integer frames: the histogram median and
MAD against ``np.median``, the banded peak and blobs against the whole frame's."""

from __future__ import annotations

import numpy as np
import pytest

import sim.sensors.pancam as pancam
from estimation.camera_model import PANCAM, R_b_pancam
from estimation.sapp.sunfind import (
    SunFinderParams,
    _float_blobs,
    _integer_blobs,
    _median_and_mad,
)
from sim.sensors.pancam import PancamDetector, render_sun_image, render_sun_stamp

MARS_PERIHELION_AU = 1.3814  # NASA Mars fact sheet
MARS_APHELION_AU = 1.6660  # NASA Mars fact sheet

# Pixels (column, row) of the sun's centre: centre, corners, on the edges, just past them
# (only the blur's wings on the detector), far off the field.
SUN_PIXELS = [
    (511.5, 511.5),
    (0.0, 0.0),
    (1023.0, 1023.0),
    (-0.5, 300.0),
    (1023.5, 700.0),
    (400.0, -6.0),
    (800.0, 1030.0),
    (-12.0, -12.0),
    (1040.0, 512.0),
    (3000.0, -2000.0),
]


def _sun_cam(u: float, v: float) -> np.ndarray:
    ray: np.ndarray = PANCAM.unproject(u, v)
    return ray


def _random_suns(n: int, seed: int) -> list[np.ndarray]:
    """Unit camera-frame suns over a field a little wider than the detector's."""
    rng = np.random.default_rng(seed)
    return [_sun_cam(*rng.uniform(-20.0, 1044.0, 2)) for _ in range(n)]


@pytest.mark.parametrize("distance_au", [MARS_PERIHELION_AU, MARS_APHELION_AU])
def test_the_restricted_stamp_is_the_whole_stamp(distance_au: float) -> None:
    det = PancamDetector()
    rho = pancam.sun_angular_radius_rad(distance_au)
    suns = [_sun_cam(u, v) for u, v in SUN_PIXELS] + _random_suns(40, seed=1)
    suns.append(np.array([0.0, 0.3, -1.0]))  # behind the camera
    rendered = 0
    for s in suns:
        fast = render_sun_stamp(s, PANCAM, det, rho, 0.45, 2.0e7)
        ref = render_sun_stamp(s, PANCAM, det, rho, 0.45, 2.0e7, restrict=False)
        assert (fast is None) == (ref is None)
        if fast is None or ref is None:
            continue
        rendered += 1
        assert (fast.row0, fast.col0) == (ref.row0, ref.col0)
        np.testing.assert_array_equal(fast.rate_e_s, ref.rate_e_s)
        assert ref.rate_e_s.max() > 0.0
    assert rendered >= 40


def test_a_tiny_supersample_and_a_wide_blur_agree_too() -> None:
    """Other detector settings: the box and the blur's reach follow them."""
    for det in (PancamDetector(supersample=2, psf_sigma_px=2.5), PancamDetector(supersample=1)):
        rho = pancam.sun_angular_radius_rad(1.52)
        for s in _random_suns(10, seed=2):
            fast = render_sun_stamp(s, PANCAM, det, rho, 0.45, 2.0e7)
            ref = render_sun_stamp(s, PANCAM, det, rho, 0.45, 2.0e7, restrict=False)
            assert (fast is None) == (ref is None)
            if fast is not None and ref is not None:
                np.testing.assert_array_equal(fast.rate_e_s, ref.rate_e_s)


def _reference_frame(
    sun_b: np.ndarray, az: float, el: float, rng: np.random.Generator
) -> tuple[np.ndarray, float]:
    """The frame and exposure as rendered before the shortcuts: the whole stamp, numpy's
    ``standard_normal`` over the frame, rounding then clipping."""
    det, opt = PancamDetector(), pancam.SolarFilter()
    distance = pancam.MARS_MEAN_SUN_DISTANCE_AU
    rho = pancam.sun_angular_radius_rad(distance)
    rate = pancam.sun_disk_rate_e_s(distance, 0.6, opt)
    sun_cam = R_b_pancam(az, el).T @ (sun_b / np.linalg.norm(sun_b))
    stamp = render_sun_stamp(sun_cam, PANCAM, det, rho, 0.45, rate, restrict=False)
    peak_rate = pancam._on_detector_peak(stamp, PANCAM) if stamp is not None else 0.0
    if peak_rate <= 0.0:
        boresight = render_sun_stamp([0.0, 0.0, 1.0], PANCAM, det, rho, 0.45, rate, restrict=False)
        assert boresight is not None
        peak_rate = float(boresight.rate_e_s.max())
    exposure_s = 0.7 * det.full_well_e / peak_rate
    dn = rng.standard_normal((PANCAM.height_px, PANCAM.width_px), dtype=np.float32)
    dn *= np.float32(det.read_noise_e / det.gain_e_per_dn)
    dn += np.float32(det.dark_offset_dn)
    if stamp is not None:
        r0, c0 = max(stamp.row0, 0), max(stamp.col0, 0)
        r1 = min(stamp.row0 + stamp.rate_e_s.shape[0], PANCAM.height_px)
        c1 = min(stamp.col0 + stamp.rate_e_s.shape[1], PANCAM.width_px)
        if r1 > r0 and c1 > c0:
            mean_e = stamp.rate_e_s[
                r0 - stamp.row0 : r1 - stamp.row0, c0 - stamp.col0 : c1 - stamp.col0
            ]
            electrons = np.minimum(rng.poisson(mean_e * exposure_s), det.full_well_e)
            dn[r0:r1, c0:c1] += (electrons / det.gain_e_per_dn).astype(np.float32)
    return np.clip(np.rint(dn), 0.0, 4095.0).astype(np.uint16), exposure_s


def test_the_frame_is_the_reference_frame() -> None:
    """Whole frames, noise included, and the camera generator left in the same state."""
    az, el = 0.4, 0.6
    R = R_b_pancam(az, el)
    suns_b = [R @ _sun_cam(u, v) for u, v in SUN_PIXELS] + [R @ s for s in _random_suns(6, 3)]
    fast_rng, ref_rng = np.random.default_rng(42), np.random.default_rng(42)
    lit = 0
    for sun_b in suns_b:
        fast = render_sun_image(sun_b, az, el, fast_rng)
        image, exposure_s = _reference_frame(sun_b, az, el, ref_rng)
        np.testing.assert_array_equal(fast.image, image)
        assert fast.exposure_s == exposure_s
        lit += fast.peak_e > 0.0
    assert fast_rng.bit_generator.state == ref_rng.bit_generator.state
    assert 4 <= lit < len(suns_b)  # suns on the detector and suns off it


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
    return [*frames, two, hot, edges, flat, small]


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
        img: np.ndarray = rng.integers(0, top + 1, tuple(rng.integers(1, 40, 2))).astype(dtype)
        sub = img.astype(np.float32)
        background = float(np.median(sub))
        assert _median_and_mad(img) == (background, float(np.median(np.abs(sub - background))))
