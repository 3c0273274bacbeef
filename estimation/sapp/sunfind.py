"""The onboard sun finder: locate the sun disk in a Pancam solar-filter image.

MER finds the sun by centroiding its image in a Pancam frame taken through the 440 or
880 nm solar filter with neutral density 5 (Eisenman, Liebe and Perez 2002, "Sun sensing
on the Mars Exploration Rovers", Ali et al. 2005 ref. [3]); SAPP's Sunfind, Suncheck and Sungaze
(Ali et al. 2005 sec. 2.2.2-2.2.3 and 2.3) turn the centroid into a body-frame
sun vector. The paper's exact onboard code is not public; this is the standard method:

1. Background and noise: the median and the MAD of a 1-in-16 subsample of the frame.
   The sun covers well under 0.1 % of the pixels, so both are those of the dark sky.
2. Peak: the maximum of a 3x3 box-filtered copy, so that a single hot pixel or cosmic-ray
   hit cannot pose as the sun. No sun if the peak is not ``min_snr`` noise sigmas above
   the background. (Integer frames are smoothed only in the rows that can hold the peak
   and the blobs of step 3: the same figures, at a fraction of the cost.)
3. Threshold the filtered image at ``threshold_fraction`` of the way from the background
   to the peak; the 8-connected components of the mask, found by their outer borders
   (``cv2.findContours``, Suzuki and Abe 1985), holes filled.
4. Plausibility: the candidate's area must lie within ``[area_min_factor, area_max_factor]``
   times the disk area expected over the whole Sun-Mars distance range (aphelion to
   perihelion), and its bounding box must stay ``edge_margin_px`` clear of the image edge:
   a disk cut by the edge has its centroid pulled inwards, so it is rejected rather than
   reported wrong. The largest plausible component wins; none means "not found".
5. Subpixel centroid: the intensity-weighted mean of ``image - background`` over the
   component grown by ``centroid_margin_px`` pixels (which takes in the PSF wings below
   the threshold, so the threshold's pixel-grid cut does not bias the centroid); noise
   pixels average to zero there because they are not clipped.
6. Unproject the centroid through the camera model and rotate it into the body frame.

Flight software: numpy and OpenCV only; bad arguments raise ``ValueError``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimation.camera_model import PinholeCamera, check_rotation_matrix

FloatArray = NDArray[np.float64]

# The Sun's apparent angular radius over the Mars year: solar radius 695,700 km (IAU 2015
# Resolution B3) over the perihelion 1.3814 AU and aphelion 1.6660 AU distances of Mars
# (NASA Mars fact sheet; 1 AU = 149,597,870.7 km). About 0.35 deg diameter at 1.52 AU.
SUN_ANGULAR_RADIUS_MAX_RAD = 3.366e-3  # at perihelion
SUN_ANGULAR_RADIUS_MIN_RAD = 2.791e-3  # at aphelion


@dataclass(frozen=True)
class SunFinderParams:
    """Tuning of the sun finder; the defaults suit Pancam's 880 nm ND5 sun images."""

    threshold_fraction: float = 0.25  # of (peak - background), step 3
    min_snr: float = 20.0  # peak above background in noise sigmas, step 2
    area_min_factor: float = 0.5  # x the aphelion disk area, step 4
    area_max_factor: float = 1.6  # x the perihelion disk area, step 4
    edge_margin_px: int = 4  # must be >= centroid_margin_px so the window stays inside
    centroid_margin_px: int = 3  # ~4 PSF sigmas past the threshold contour, step 5

    def __post_init__(self) -> None:
        if not 0.0 < self.threshold_fraction < 1.0:
            raise ValueError("threshold_fraction: must be in (0, 1)")
        if self.min_snr <= 0.0:
            raise ValueError("min_snr: must be positive")
        if not 0.0 < self.area_min_factor < self.area_max_factor:
            raise ValueError("area_min_factor/area_max_factor: need 0 < min < max")
        if self.centroid_margin_px < 0 or self.edge_margin_px < self.centroid_margin_px:
            raise ValueError("edge_margin_px: must be >= centroid_margin_px >= 0")


@dataclass(frozen=True)
class SunFix:
    """A found sun: ``sun_b`` the unit sun vector in the body frame, (3,);
    ``centroid_uv_px`` its subpixel image position (column, row), (2,); ``area_px`` the
    thresholded blob area; ``peak_dn``, ``background_dn`` and ``noise_dn`` the smoothed
    peak, the dark-sky level and its noise sigma, in data numbers."""

    sun_b: FloatArray
    centroid_uv_px: FloatArray
    area_px: int
    peak_dn: float
    background_dn: float
    noise_dn: float


def expected_area_px(camera: PinholeCamera, angular_radius_rad: float) -> float:
    """Area in pixels of a disk of ``angular_radius_rad`` near the image centre."""
    return math.pi * (angular_radius_rad * camera.f_px) ** 2


def find_sun(
    image: ArrayLike,
    camera: PinholeCamera,
    R_b_cam: ArrayLike,
    params: SunFinderParams | None = None,
) -> SunFix | None:
    """Find the sun in ``image`` (H, W) and return its body-frame unit vector, or None.

    ``image`` is a single-channel frame in data numbers (uint8/uint16/float) matching
    ``camera``; ``R_b_cam`` (3, 3) takes camera coordinates to body coordinates (the mast
    pointing when the image was taken). Returns None when there is no plausible sun disk:
    no blob bright enough, only blobs of implausible size, or only a disk cut by the edge.
    """
    p = params if params is not None else SunFinderParams()
    R = check_rotation_matrix(R_b_cam, "R_b_cam")
    img = np.asarray(image)
    if img.shape != (camera.height_px, camera.width_px):
        raise ValueError(
            f"image: shape {img.shape} does not match the camera "
            f"({camera.height_px}, {camera.width_px})"
        )
    if img.dtype.kind not in "uif":
        raise ValueError(f"image: must be numeric, got dtype {img.dtype}")
    if img.dtype not in (np.uint8, np.uint16, np.float32):
        img = img.astype(np.float32)  # the types OpenCV filters take directly

    # Step 1: dark-sky level and noise from a subsample (robust: median and MAD).
    background, mad = _median_and_mad(img[::4, ::4])
    # The quantisation step bounds the noise estimate from below (MAD of integer data
    # can be 0 when the read noise is under a DN).
    noise = max(1.4826 * mad, 1.0 / math.sqrt(12.0))

    # Step 2: smoothed peak (a 3x3 mean; integer images round it to the nearest DN).
    # Step 3: threshold; the blobs are the 8-connected components of the mask, found by
    # their outer borders (Suzuki-Abe border following): on a mask this sparse that is
    # ~40x faster than labelling the whole frame.
    found = (_integer_blobs if img.dtype.kind == "u" else _float_blobs)(
        img, background, p.min_snr * noise, p.threshold_fraction
    )
    if found is None:
        return None
    peak, contours = found

    # Step 4: plausible size, clear of the edges; keep the largest.
    area_min = p.area_min_factor * expected_area_px(camera, SUN_ANGULAR_RADIUS_MIN_RAD)
    area_max = p.area_max_factor * expected_area_px(camera, SUN_ANGULAR_RADIUS_MAX_RAD)
    m = p.edge_margin_px
    g = p.centroid_margin_px
    best: NDArray[np.uint8] | None = None
    best_area = 0
    best_x0 = best_y0 = 0
    for contour in contours:
        x0, y0, w, h = cv2.boundingRect(contour)
        if w * h < area_min:
            continue  # cannot hold enough pixels
        if x0 < m or y0 < m or x0 + w > camera.width_px - m or y0 + h > camera.height_px - m:
            continue  # cut by (or too near) the edge: its centroid would be biased
        # The component's pixels (holes filled), in a window padded for step 5's growth.
        blob = np.zeros((h + 2 * g, w + 2 * g), dtype=np.uint8)
        cv2.drawContours(blob, [contour], -1, 1, thickness=cv2.FILLED, offset=(g - x0, g - y0))
        area = int(np.count_nonzero(blob))
        if area_min <= area <= area_max and area > best_area:
            best, best_area, best_x0, best_y0 = blob, area, x0 - g, y0 - g
    if best is None:
        return None

    # Step 5: intensity-weighted centroid over the grown component.
    if g > 0:
        kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * g + 1, 2 * g + 1))
        best = cv2.dilate(best, kernel).astype(np.uint8)
    rows = slice(best_y0, best_y0 + best.shape[0])
    cols = slice(best_x0, best_x0 + best.shape[1])
    weight = (img[rows, cols].astype(np.float64) - background) * best
    total = float(weight.sum())
    if total <= 0.0:
        return None
    vv, uu = np.mgrid[rows, cols]
    u_c = float((weight * uu).sum() / total)
    v_c = float((weight * vv).sum() / total)

    # Step 6: pixel -> camera ray -> body.
    ray_cam = camera.unproject(u_c, v_c)
    sun_b = R @ ray_cam
    sun_b /= np.linalg.norm(sun_b)
    return SunFix(
        sun_b=sun_b,
        centroid_uv_px=np.array([u_c, v_c]),
        area_px=best_area,
        peak_dn=float(peak),
        background_dn=background,
        noise_dn=noise,
    )


def _median_and_mad(sub: Image) -> tuple[float, float]:
    """The median of ``sub`` and the median of its absolute deviations from it: float32
    ``np.median`` of ``sub`` and of ``|sub - median|``.

    Integer pixels take a histogram instead of two partial sorts: the median of an even
    count is the mean of the two middle values, exact here in float32 (integers and halves
    below 2^17), so both figures are those of ``np.median`` to the bit.
    """
    if sub.dtype.kind != "u":
        sub32 = sub.astype(np.float32)
        background = float(np.median(sub32))
        return background, float(np.median(np.abs(sub32 - background)))
    counts = np.bincount(sub.ravel())
    values = np.flatnonzero(counts)
    counts = counts[values]
    background = _weighted_median(values.astype(np.float64), counts)
    deviation = np.abs(values - background)
    order = np.argsort(deviation, kind="stable")
    return background, _weighted_median(deviation[order], counts[order])


def _weighted_median(sorted_values: FloatArray, counts: NDArray[np.intp]) -> float:
    """Median of ``sorted_values`` (ascending) each repeated ``counts`` times: the middle
    value, or the mean of the two middle values of an even count."""
    cumulative = np.cumsum(counts)
    n = int(cumulative[-1])
    upper = float(sorted_values[np.searchsorted(cumulative, n // 2, side="right")])
    if n % 2:
        return upper
    lower = float(sorted_values[np.searchsorted(cumulative, n // 2 - 1, side="right")])
    return 0.5 * (lower + upper)


# A frame in data numbers, as OpenCV takes it; the smoothed peak and the blobs' outer borders.
Image = NDArray[np.integer[Any] | np.floating[Any]]
Blobs = tuple[float, Sequence[Any]]


def _float_blobs(img: Image, background: float, min_rise: float, fraction: float) -> Blobs | None:
    """Steps 2 and 3 over the whole frame: the smoothed peak and the outer borders of the
    mask at ``fraction`` of the way up to it; None if the peak is under ``min_rise``."""
    smooth = cv2.blur(img, (3, 3))
    _, peak, _, _ = cv2.minMaxLoc(smooth)
    if peak - background < min_rise:
        return None
    threshold = background + fraction * (peak - background)
    mask = (smooth > threshold).view(np.uint8)
    contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    return peak, contours


def _integer_blobs(img: Image, background: float, min_rise: float, fraction: float) -> Blobs | None:
    """``_float_blobs`` for integer pixels, the same figures and contours, smoothing only
    the rows that can matter.

    The smoothed value is the mean of 9 integers rounded, so it never exceeds their
    maximum and exceeds ``k`` only if one of them reaches ``k + 1``. Hence: no peak if the
    brightest pixel is not high enough (most search images); the peak lies within a row of
    the rows reaching the smoothed value at the brightest pixel (a value the peak reaches);
    the mask ``smooth > floor(threshold)`` (the same as ``> threshold`` for integers, and
    compared in the image's own type) within a row of the rows reaching its level + 1.
    Those bands are smoothed whole-width, and the contours traced in a band with a clear
    row around the mask, so they are those of the whole frame.
    """
    row_max = img.max(axis=1)
    if float(row_max.max()) - background < min_rise:
        return None
    r = int(row_max.argmax())
    floor_peak = int(_smooth_rows(img, r, r + 1)[0, int(img[r].argmax())])
    rows = _rows_reaching(row_max, floor_peak, 1)
    peak = float(_smooth_rows(img, rows.start, rows.stop).max())
    if peak - background < min_rise:
        return None
    threshold = background + fraction * (peak - background)
    level = math.floor(threshold)
    if level < 0:  # every pixel is in the mask: the whole frame, as is
        return _float_blobs(img, background, min_rise, fraction)
    band = _rows_reaching(row_max, level + 1, 2)
    mask = (_smooth_rows(img, band.start, band.stop) > level).view(np.uint8)
    contours, _ = cv2.findContours(
        mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE, offset=(0, band.start)
    )
    return peak, contours


def _smooth_rows(img: Image, r0: int, r1: int) -> Image:
    """Rows ``r0:r1`` of ``cv2.blur(img, (3, 3))``, from those rows and one either side (the
    frame's own edges keep their reflection)."""
    b0, b1 = max(r0 - 1, 0), min(r1 + 1, img.shape[0])
    out: Image = cv2.blur(img[b0:b1], (3, 3))[r0 - b0 : r1 - b0]
    return out


def _rows_reaching(row_max: Image, value: int, margin: int) -> slice:
    """The rows from ``margin`` before the first whose maximum reaches ``value`` to
    ``margin`` after the last, within the frame."""
    reaching = np.flatnonzero(row_max >= value)
    first, last = int(reaching[0]), int(reaching[-1])
    return slice(max(first - margin, 0), min(last + 1 + margin, row_max.size))
