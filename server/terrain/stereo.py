"""Dense stereo on the ground: a downlinked Navcam pair to points on the terrain in the
mission frame, each with the 1σ of its height, and the pair's corner features.

- Disparity: OpenCV's ``StereoSGBM`` (its variant of the semi-global matching of Hirschmüller
  2008) on the rectified 8-bit pair. Bad disparities are rejected three ways: the left-right
  consistency check (``disp12MaxDiff`` = 1 px: the right image's own disparity must map back
  to the left pixel), the uniqueness ratio (the best match's cost ``UNIQUENESS_PCT`` % below
  the second best), and the speckle filter (connected blobs of fewer than ``speckle_px``
  pixels whose disparity jumps by more than 2 px from their surroundings are removed).
- Triangulation: the rectified pinhole relation ``z = f B / d`` (Cheng, Maimone and Matthies
  2005 sec. 2 triangulates by intersecting the rays of the two camera models; for a rectified
  pair that is this relation), the point ``P_cam = z (x, y, 1)`` with ``x = (u - c_u) / f``, in
  the mission frame ``P = p_mission + R_mission_b (c_left_b + R_b_cam P_cam)``.
- Height σ (first-order propagation): ``dP/dd = -(z / d) R_mission_cam (x, y, 1)``, so a
  disparity error ``σ_d`` moves the point's height by ``σ_up = (z / d) |(R_mission_cam (x, y,
  1))_down| σ_d``. ``σ_d`` per pixel is the refinement's least-squares covariance,
  ``σ_n sqrt(2 / Σ_w L_u²)`` over its window (Lucas and Kanade 1981; ``σ_n`` the image noise,
  estimated from the image, Immerkær 1996): large where the ground is smooth (Meridiani's
  sand), small on texture. Times ``LK_SIGMA_SCALE`` = 1.5: on rendered Gusev and Meridiani
  pairs the refined disparities' errors against the rendered depth were 1.3-1.6 times that
  σ at the 68th percentile, the same on both sites (the window's foreshortening and the
  interpolation the least-squares model leaves out; ``bench.vo.ground_map`` reports the
  figure as ``ground_map_disparity_z68``).
- Features: Shi-Tomasi corners (Shi and Tomasi 1994: the smaller eigenvalue of the gradient
  structure tensor over a block) on the left image, local maxima at least ``FEATURE_SPACING``
  pixels apart whose eigenvalue exceeds an absolute threshold (``FEATURE_MIN_EIG``: a
  trackable corner on an 8-bit image, not a fraction of the image's strongest, so a
  featureless image yields few), with their 3D points where the disparity is kept.

Frames: mission (N, E, Down; m), body (x forward, y right, z down), the cameras z along the
boresight, x right, y down (``estimation.vo.geometry``). ``R_mission_b`` is the rover's
estimated attitude: the Local Level axes are taken as the mission frame's (they differ by the
rover's distance from the landing over the Mars radius: 1e-5 rad per 30 m).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from estimation.vo.geometry import PointedPair
from estimation.vo.stereo_rig import NAVCAM, StereoRig

FloatArray = NDArray[np.float64]
UInt8Array = NDArray[np.uint8]

LK_SIGMA_SCALE = 1.5  # the refined disparities' error over their least-squares σ (docstring)
MIN_SIGMA_PX = 0.05
MAX_SIGMA_PX = 2.0
UNIQUENESS_PCT = 10
LR_MAX_DIFF_PX = 1
MIN_RANGE_M = 0.8  # nearer than the ground below the mast's lowest view
MAX_RANGE_M = 12.0  # farther, a pixel covers decimetres and the height σ exceeds ~10 cm
FEATURE_MIN_EIG = 40.0  # Shi-Tomasi minimum eigenvalue, 8-bit grey levels² (block 5, Sobel 3)
FEATURE_SPACING = 3  # features are local maxima in (2k+1)² windows, k this
SUPPORTED_WIDTHS = (256, 512, 1024)


@dataclass(frozen=True)
class StereoPoints:
    """What one pair measured, mission frame: ``p_mission_m`` (N, 3) the points (N, E, Down),
    ``sigma_up_m`` (N,) their height's 1σ from the disparity, ``grey`` (N,) their pixel's
    grey level in the left image (0-255); ``camera_mission_m`` (3,) the left eye; the
    features' points ``features_mission_m`` (M, 3); ``n_pixels`` the image's pixels and
    ``n_rejected`` those whose disparity was rejected or out of range."""

    p_mission_m: FloatArray
    sigma_up_m: FloatArray
    grey: FloatArray
    camera_mission_m: FloatArray
    features_mission_m: FloatArray
    n_pixels: int
    n_rejected: int


def _check_image(image: object, name: str, width: int) -> UInt8Array:
    arr = np.asarray(image)
    if arr.dtype != np.uint8 or arr.shape != (width, width):
        raise ValueError(
            f"{name}: must be a {width} x {width} uint8 image, got {arr.dtype} {arr.shape}"
        )
    return np.ascontiguousarray(arr)


def window_px_for(width: int) -> int:
    """SGBM's block and the refinement's window at an image width, px."""
    return 5 if width <= 256 else 7


def _matcher(rig: StereoRig) -> cv2.StereoSGBM:
    cam = rig.camera
    d_max = cam.f_px * rig.baseline_m / MIN_RANGE_M
    block = window_px_for(cam.width_px)
    scale = (cam.width_px / 256.0) ** 2
    return cv2.StereoSGBM.create(
        minDisparity=0,
        numDisparities=16 * math.ceil(d_max / 16.0),
        blockSize=block,
        P1=8 * block * block,
        P2=32 * block * block,
        disp12MaxDiff=LR_MAX_DIFF_PX,
        uniquenessRatio=UNIQUENESS_PCT,
        speckleWindowSize=round(50 * scale),
        speckleRange=2,
        mode=cv2.STEREO_SGBM_MODE_SGBM,
    )


def disparity_px(left: UInt8Array, right: UInt8Array, rig: StereoRig) -> FloatArray:
    """SGBM's disparity of the left image (H, W), px; NaN where rejected (module docstring)."""
    lo, hi = np.percentile(left, (1.0, 99.0))
    gain = 255.0 / max(float(hi - lo), 1.0)  # one stretch for both eyes: SGBM's costs to scale
    left_s, right_s = (np.clip((x - lo) * gain, 0, 255).astype(np.uint8) for x in (left, right))
    raw: FloatArray = np.asarray(_matcher(rig).compute(left_s, right_s), np.float64) / 16.0
    raw[raw <= 0.0] = np.nan  # SGBM's invalid marker is below minDisparity
    return raw


def refine_disparity(
    left: UInt8Array, right: UInt8Array, d_px: FloatArray, window_px: int, iterations: int = 2
) -> FloatArray:
    """Sub-pixel refinement of a disparity map along the epipolar line: Lucas and Kanade
    1981's least-squares step, ``δ = Σ_w (R(u - d) - L(u)) L_u / Σ_w L_u²`` over a
    ``window_px`` square, ``d ← d - δ``, iterated (module docstring). Steps larger than a
    pixel are not taken (the pixel is left as SGBM gave it)."""
    lf, rf = left.astype(np.float32), right.astype(np.float32)
    h, w = lf.shape
    uu, vv = np.meshgrid(np.arange(w, dtype=np.float32), np.arange(h, dtype=np.float32))
    gx = np.asarray(cv2.Sobel(lf, cv2.CV_32F, 1, 0, ksize=3), np.float32) / np.float32(8.0)
    box = (window_px, window_px)
    den = cv2.boxFilter(np.asarray(gx * gx, np.float32), -1, box, normalize=False)
    valid = np.isfinite(d_px)
    d = np.where(valid, d_px, 0.0).astype(np.float32)
    for _ in range(iterations):
        warped = cv2.remap(rf, uu - d, vv, cv2.INTER_CUBIC, borderMode=cv2.BORDER_REPLICATE)
        diff = np.asarray(warped, np.float32) - lf
        num = cv2.boxFilter(np.asarray(diff * gx, np.float32), -1, box, normalize=False)
        step = np.where(den > 1e-3, num / np.maximum(den, 1e-3), 0.0)
        step = np.where(np.abs(step) < 1.0, step, 0.0)
        d = d + step.astype(np.float32)  # R(u - d - δ) ≈ R(u - d) - δ R_u, R_u ≈ L_u
    out: FloatArray = np.where(valid, d.astype(np.float64), np.nan)
    return out


def image_noise(image: UInt8Array) -> float:
    """The image's noise σ in grey levels, Immerkær 1996's estimator: the mean absolute
    response to the mask ``[[1, -2, 1], [-2, 4, -2], [1, -2, 1]]`` (blind to planes and
    edges) times ``sqrt(π/2) / 6``. Fine texture counts as noise: an upper bound."""
    img = image.astype(np.float32)
    mask = np.array([[1, -2, 1], [-2, 4, -2], [1, -2, 1]], np.float32)
    response = np.asarray(cv2.filter2D(img, -1, mask), np.float64)[1:-1, 1:-1]
    return math.sqrt(0.5 * math.pi) * float(np.mean(np.abs(response))) / 6.0


def disparity_sigma_px(left: UInt8Array, window_px: int) -> FloatArray:
    """Per-pixel 1σ of the refined disparity (module docstring): the least-squares step's own,
    ``σ_n sqrt(2 / Σ_w L_u²)`` (both eyes' noise ``σ_n``, ``image_noise``), times
    ``LK_SIGMA_SCALE``, within ``[MIN_SIGMA_PX, MAX_SIGMA_PX]``."""
    img = left.astype(np.float32)
    gx = np.asarray(cv2.Sobel(img, cv2.CV_32F, 1, 0, ksize=3), np.float32) / np.float32(8.0)
    den = cv2.boxFilter(
        np.asarray(gx * gx, np.float32), -1, (window_px, window_px), normalize=False
    )
    sigma = LK_SIGMA_SCALE * image_noise(left) * np.sqrt(2.0 / np.maximum(den, 1e-6))
    out: FloatArray = np.clip(np.asarray(sigma, np.float64), MIN_SIGMA_PX, MAX_SIGMA_PX)
    return out


def features_uv(left: UInt8Array) -> NDArray[np.intp]:
    """Shi-Tomasi corners of the left image: ``(u, v)`` (M, 2) (module docstring)."""
    eig = cv2.cornerMinEigenVal(left.astype(np.float32), blockSize=5, ksize=3)
    k = FEATURE_SPACING
    peak = cv2.dilate(eig, np.ones((2 * k + 1, 2 * k + 1), np.uint8))
    # cornerMinEigenVal averages the tensor over the block with Sobel's gain of 8 per axis
    strong = (eig >= peak) & (eig * 64.0 >= FEATURE_MIN_EIG)
    strong[:k, :] = strong[-k:, :] = False
    strong[:, :k] = strong[:, -k:] = False
    v, u = np.nonzero(strong)
    return np.stack([u, v], axis=1).astype(np.intp)


def dense_points(
    left_u8: object,
    right_u8: object,
    width: int,
    mast_az_rad: float,
    mast_el_rad: float,
    p_mission_m: FloatArray,
    R_mission_b: FloatArray,
) -> StereoPoints:
    """Dense stereo of one downlinked pair (module docstring). ``width`` the square images'
    side (``SUPPORTED_WIDTHS``); ``p_mission_m`` (3,) the body origin and ``R_mission_b``
    (3, 3) the body's attitude at capture, as the ground estimates them. ValueError naming
    a bad argument."""
    if width not in SUPPORTED_WIDTHS:
        raise ValueError(f"width: must be one of {SUPPORTED_WIDTHS}, got {width!r}")
    left = _check_image(left_u8, "left_u8", width)
    right = _check_image(right_u8, "right_u8", width)
    for name, value in (("mast_az_rad", mast_az_rad), ("mast_el_rad", mast_el_rad)):
        if not (isinstance(value, int | float) and math.isfinite(value)):
            raise ValueError(f"{name}: must be a finite number, got {value!r}")
    p_m = np.asarray(p_mission_m, dtype=np.float64)
    R_m_b = np.asarray(R_mission_b, dtype=np.float64)
    if p_m.shape != (3,) or not np.all(np.isfinite(p_m)):
        raise ValueError(f"p_mission_m: must be a finite 3-vector, got {p_mission_m!r}")
    if R_m_b.shape != (3, 3) or not np.allclose(R_m_b @ R_m_b.T, np.eye(3), atol=1e-6):
        raise ValueError("R_mission_b: must be a rotation matrix")
    rig = NAVCAM.at_resolution(width)
    pair = PointedPair.from_rig(rig, float(mast_az_rad), float(mast_el_rad))
    cam = pair.camera
    d = refine_disparity(left, right, disparity_px(left, right, rig), window_px_for(width))
    sigma_d = disparity_sigma_px(left, window_px_for(width))
    v, u = np.nonzero(np.isfinite(d))
    dd = d[v, u]
    z = cam.f_px * rig.baseline_m / dd
    ray_cam = np.stack(
        [(u - cam.c_u_px) / cam.f_px, (v - cam.c_v_px) / cam.f_px, np.ones_like(z)], 1
    )
    R_m_cam = R_m_b @ pair.R_b_cam
    ray_m = ray_cam @ R_m_cam.T
    eye_m = p_m + R_m_b @ pair.c_left_b
    p = eye_m + z[:, None] * ray_m
    rng = z * np.linalg.norm(ray_cam, axis=1)
    keep = (rng >= MIN_RANGE_M) & (rng <= MAX_RANGE_M)
    sigma_up = (z / dd) * np.abs(ray_m[:, 2]) * sigma_d[v, u]
    # the features that have a kept disparity
    f_uv = features_uv(left)
    index = np.full(d.shape, -1, dtype=np.intp)
    index[v[keep], u[keep]] = np.arange(int(np.count_nonzero(keep)))
    f_idx = index[f_uv[:, 1], f_uv[:, 0]] if f_uv.size else np.zeros(0, dtype=np.intp)
    kept_p = p[keep]
    return StereoPoints(
        p_mission_m=kept_p,
        sigma_up_m=sigma_up[keep],
        grey=left[v[keep], u[keep]].astype(np.float64),
        camera_mission_m=eye_m,
        features_mission_m=kept_p[f_idx[f_idx >= 0]],
        n_pixels=width * width,
        n_rejected=width * width - int(np.count_nonzero(keep)),
    )
