"""The Navcam stereo pair as the flight software knows it: a rectified pinhole pair on the
mast head, pointed by the mast's azimuth and elevation.

MER's Navcams (Maki et al. 2003, JGR 108(E12) 8071; Cheng, Maimone and Matthies 2005 sec. 4): 1024 x
1024 pixels, a 45 deg square field of view, a 20 cm stereo baseline, on the mast head about 1.5 m
above the ground. VO on Mars ran on images downsampled to 256 x 256 to save time (Cheng, Maimone and
Matthies 2005 sec. 4); ``NAVCAM.at_resolution(256)`` is that camera.

The pair is modelled rectified (both eyes share one orientation, the right eye displaced
along the image ``x`` axis by the baseline), the ideal the CAHVOR calibration and
epipolar rectification produce: a point images on the same row in both eyes, with
disparity ``d = u_left - u_right = f B / z > 0``. Frames (docs/CONVENTIONS.md): ``navcam_l``
and ``navcam_r`` have z along the boresight, x right, y down in the image. The mast
pointing is that of ``estimation.camera_model.R_b_pancam`` (azimuth clockwise from body
+x about Down, elevation up from the body x-y plane).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from estimation.camera_model import PinholeCamera, R_b_pancam

FloatArray = NDArray[np.float64]

NAVCAM_WIDTH_PX = 1024
NAVCAM_FOV_RAD = math.radians(45.0)
NAVCAM_BASELINE_M = 0.20
# The point midway between the eyes, body frame (x forward, y right, z down; the body
# origin is 0.30 m above level ground, sim.rover.geometry): 1.52 m above the ground, on
# the left front of the deck as on MER. Approximate, not a flight drawing.
NAVCAM_HEAD_B = (0.45, -0.30, -1.22)


@dataclass(frozen=True)
class StereoRig:
    """A rectified stereo pair on the mast head (module docstring).

    ``camera``: both eyes' pinhole model; ``baseline_m``: eye separation along image x;
    ``head_b``: the midpoint of the eyes in the body frame when the mast is stowed at
    ``(az, el) = (0, 0)`` (the mast head's own offset as it turns is neglected: a few cm).
    """

    camera: PinholeCamera
    baseline_m: float = NAVCAM_BASELINE_M
    head_b: tuple[float, float, float] = field(default=NAVCAM_HEAD_B)

    def __post_init__(self) -> None:
        if not (math.isfinite(self.baseline_m) and self.baseline_m > 0.0):
            raise ValueError(f"baseline_m: must be positive, got {self.baseline_m}")

    def at_resolution(self, width_px: int) -> StereoRig:
        """The same rig imaged at ``width_px`` x ``width_px`` (same field of view)."""
        if width_px < 16:
            raise ValueError(f"width_px: must be at least 16, got {width_px}")
        fov = 2.0 * math.atan(0.5 * self.camera.width_px / self.camera.f_px)
        return StereoRig(
            PinholeCamera.from_fov(width_px, width_px, fov), self.baseline_m, self.head_b
        )

    @staticmethod
    def R_b_cam(az_rad: float, el_rad: float) -> FloatArray:
        """Rotation taking (either eye's) camera coordinates to body coordinates."""
        return R_b_pancam(az_rad, el_rad)

    def eye_centres_b(self, az_rad: float, el_rad: float) -> tuple[FloatArray, FloatArray]:
        """Optical centres of the left and right eye in the body frame."""
        x_cam_b = self.R_b_cam(az_rad, el_rad)[:, 0]
        head = np.asarray(self.head_b, dtype=np.float64)
        half = 0.5 * self.baseline_m * x_cam_b
        return head - half, head + half

    def disparity_px(self, depth_m: float) -> float:
        """Disparity of a point at ``depth_m`` along the boresight: ``f B / z``."""
        if not (math.isfinite(depth_m) and depth_m > 0.0):
            raise ValueError(f"depth_m: must be positive, got {depth_m}")
        return self.camera.f_px * self.baseline_m / depth_m


NAVCAM = StereoRig(PinholeCamera.from_fov(NAVCAM_WIDTH_PX, NAVCAM_WIDTH_PX, NAVCAM_FOV_RAD))
