"""A visual-odometry baseline from OpenCV's own parts, to set beside MER's method in
``roverops bench vo`` (a benchmark tool, not flight software).

Per stereo pair: ORB features on the left image (``cv2.ORB``; Rublee, Rabaud, Konolige and
Bradski 2011), a dense disparity map from ``cv2.StereoSGBM`` (OpenCV's variant of the
semi-global matching of Hirschmüller 2008) and, for each feature with a disparity, its 3D
point in the left camera by the rectified pinhole relation ``z = f B / d``. Per step: the
previous pair's features are matched to the new left image's by their ORB descriptors
(Hamming distance, mutual best matches), and ``cv2.solvePnPRansac`` finds the camera motion
that puts the previous 3D points on the new pixels (RANSAC, Fischler and Bolles 1981, then
a refinement on the inliers). No prediction from
wheel odometry, no covariances, no sanity checks: what MER's method adds (Cheng, Maimone and
Matthies 2005 sec. 2) is what this lacks.

Frames as ``estimation.vo.odometry``: the camera motion ``P_c1 = R P_c0 + t`` (left eye)
becomes the body motion through the rig's mounting (``R_b_cam``, the left eye's centre
``e_b``): ``P_b1 = A P_b0 + a`` with ``A = R_b_cam R R_b_camᵀ``,
``a = R_b_cam t + e_b - A e_b``; then ``R_b0_b1 = Aᵀ`` and ``p_b1_b0 = -Aᵀ a``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimation.vo.stereo_rig import StereoRig

FloatArray = NDArray[np.float64]

DN_PER_8BIT = 16.0  # the Navcam's 12-bit DN to OpenCV's 8-bit images
NEAREST_RANGE_M = 1.0  # the closest ground a Navcam pointed 35 deg down sees (~1 m)
REFERENCE_WIDTH_PX = 256  # pixel thresholds below are for MER's VO images


@dataclass(frozen=True)
class BaselineParams:
    """``n_features`` ORB features per left image; a step needs ``min_inliers`` PnP
    inliers (MER VO's own minimum, ``estimation.vo.params``) within
    ``reprojection_px`` (at 256 px; scaled with the width) after ``ransac_iterations``."""

    n_features: int = 500
    min_inliers: int = 12
    reprojection_px: float = 1.0
    ransac_iterations: int = 200
    sgbm_block_px: int = 5

    def __post_init__(self) -> None:
        for name in ("n_features", "min_inliers", "ransac_iterations", "sgbm_block_px"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f"{name}: must be a positive integer, got {value!r}")
        if self.min_inliers < 4:
            raise ValueError("min_inliers: PnP needs at least 4 points")
        if not (math.isfinite(self.reprojection_px) and self.reprojection_px > 0.0):
            raise ValueError(f"reprojection_px: must be positive, got {self.reprojection_px}")


@dataclass(frozen=True)
class BaselineResult:
    """One step: ``motion`` ``(R_b0_b1, p_b1_b0)`` when it converged, else None and the
    ``reason``; the counts: features with 3D points, descriptor matches, PnP inliers."""

    converged: bool
    reason: str
    motion: tuple[FloatArray, FloatArray] | None
    n_features: int
    n_matched: int
    n_inliers: int


@dataclass(frozen=True)
class _Frame:
    descriptors: NDArray[np.uint8]
    p_cam: FloatArray  # (M, 3) left-camera points of the features with a disparity


class OrbPnpBaseline:
    """The OpenCV baseline for one stereo rig (module docstring); ``step`` per pair."""

    def __init__(self, rig: StereoRig, params: BaselineParams | None = None) -> None:
        self.rig = rig
        self.params = params if params is not None else BaselineParams()
        cam = rig.camera
        self.scale = cam.width_px / REFERENCE_WIDTH_PX
        max_disparity = cam.f_px * rig.baseline_m / NEAREST_RANGE_M
        self.orb = cv2.ORB.create(nfeatures=self.params.n_features)
        block = self.params.sgbm_block_px
        self.sgbm = cv2.StereoSGBM.create(
            minDisparity=0,
            numDisparities=16 * math.ceil(max_disparity / 16.0),
            blockSize=block,
            P1=8 * block * block,
            P2=32 * block * block,
            uniquenessRatio=10,
            mode=cv2.STEREO_SGBM_MODE_SGBM,
        )
        self.matcher = cv2.BFMatcher(cv2.NORM_HAMMING, crossCheck=True)
        self.K = np.array([[cam.f_px, 0.0, cam.c_u_px], [0.0, cam.f_px, cam.c_v_px], [0, 0, 1.0]])
        self._previous: _Frame | None = None

    def reset(self) -> None:
        """Forget the previous pair."""
        self._previous = None

    def step(
        self, left: ArrayLike, right: ArrayLike, mast_az_rad: float, mast_el_rad: float
    ) -> BaselineResult:
        """Process a pair (12-bit DN images of the rig's size); the motion since the
        previous pair when PnP found one with enough inliers."""
        left8, right8 = _to_8bit(left, self.rig), _to_8bit(right, self.rig)
        keypoints, found = self.orb.detectAndCompute(left8, None)
        descriptors = None if found is None else np.asarray(found, dtype=np.uint8)
        uv = np.array([k.pt for k in keypoints], dtype=np.float64).reshape(-1, 2)
        new = self._frame(uv, descriptors, left8, right8)
        previous, self._previous = self._previous, new
        n_new = len(new.p_cam)
        if previous is None:
            return BaselineResult(False, "first pair", None, n_new, 0, 0)
        need = self.params.min_inliers
        if len(previous.p_cam) < need or descriptors is None or len(uv) < need:
            return BaselineResult(False, "too few features", None, n_new, 0, 0)
        matches = self.matcher.match(previous.descriptors, descriptors)
        if len(matches) < need:
            return BaselineResult(False, f"{len(matches)} matches", None, n_new, len(matches), 0)
        object_points = previous.p_cam[[m.queryIdx for m in matches]]
        image_points = uv[[m.trainIdx for m in matches]]
        ok, rvec, tvec, inliers = cv2.solvePnPRansac(
            object_points, image_points, self.K, None,
            iterationsCount=self.params.ransac_iterations,
            reprojectionError=self.params.reprojection_px * self.scale, confidence=0.999,
            flags=cv2.SOLVEPNP_ITERATIVE,
        )  # fmt: skip
        n_inliers = 0 if inliers is None else len(inliers)
        if not ok or n_inliers < need:
            reason = f"{n_inliers} PnP inliers of {len(matches)} matches, need {need}"
            return BaselineResult(False, reason, None, n_new, len(matches), n_inliers)
        R_c1_c0, _ = cv2.Rodrigues(rvec)
        motion = body_motion_from_camera(
            self.rig, mast_az_rad, mast_el_rad, R_c1_c0, np.asarray(tvec, dtype=np.float64)
        )
        reason = f"{n_inliers} inliers of {len(matches)} matches"
        return BaselineResult(True, reason, motion, n_new, len(matches), n_inliers)

    def _frame(
        self,
        uv: FloatArray,
        descriptors: NDArray[np.uint8] | None,
        left8: NDArray[np.uint8],
        right8: NDArray[np.uint8],
    ) -> _Frame:
        """The features with a valid disparity, as left-camera points."""
        if descriptors is None or len(uv) == 0:
            return _Frame(np.zeros((0, 32), np.uint8), np.zeros((0, 3)))
        disparity = self.sgbm.compute(left8, right8).astype(np.float64) / 16.0  # fixed point
        cols = np.clip(np.rint(uv[:, 0]).astype(int), 0, left8.shape[1] - 1)
        rows = np.clip(np.rint(uv[:, 1]).astype(int), 0, left8.shape[0] - 1)
        d = disparity[rows, cols]
        ok = d >= 1.0  # SGBM marks failures below minDisparity; far points are useless
        cam = self.rig.camera
        z = cam.f_px * self.rig.baseline_m / d[ok]
        p_cam = np.column_stack(
            [(uv[ok, 0] - cam.c_u_px) * z / cam.f_px, (uv[ok, 1] - cam.c_v_px) * z / cam.f_px, z]
        )
        return _Frame(descriptors[ok], p_cam)


def _to_8bit(image: ArrayLike, rig: StereoRig) -> NDArray[np.uint8]:
    arr = np.asarray(image, dtype=np.float64)
    cam = rig.camera
    if arr.shape != (cam.height_px, cam.width_px) or not np.all(np.isfinite(arr)):
        raise ValueError(
            f"image: must be finite and ({cam.height_px}, {cam.width_px}), got {arr.shape}"
        )
    return np.clip(np.rint(arr / DN_PER_8BIT), 0, 255).astype(np.uint8)


def body_motion_from_camera(
    rig: StereoRig, az_rad: float, el_rad: float, R_c1_c0: ArrayLike, t_c1: ArrayLike
) -> tuple[FloatArray, FloatArray]:
    """``(R_b0_b1, p_b1_b0)`` of the body from the left camera's ``P_c1 = R P_c0 + t``
    (module docstring) with the mast at ``(az_rad, el_rad)``."""
    R_b_cam = rig.R_b_cam(az_rad, el_rad)
    eye_b = rig.eye_centres_b(az_rad, el_rad)[0]
    A = R_b_cam @ np.asarray(R_c1_c0, dtype=np.float64) @ R_b_cam.T
    a = R_b_cam @ np.asarray(t_c1, dtype=np.float64).reshape(3) + eye_b - A @ eye_b
    return A.T, -A.T @ a
