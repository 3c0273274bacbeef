"""The pointed stereo pair in the rover body frame: rays through pixels and projections of
body-frame points, for the visual odometry of Cheng, Maimone and Matthies 2005.

Cheng, Maimone and Matthies 2005 sec. 2 triangulates "by intersecting rays projected through the
camera models" and scores RANSAC hypotheses by reprojecting features "to the current image frame";
both need the pair's geometry at the mast pointing of the moment. This module fixes it once per
pair: the rig's pinhole model (``estimation.vo.stereo_rig``), ``R_b_cam`` (camera to body, the
same for both eyes of the rectified pair) and the eyes' optical centres in the body frame.

Frames (docs/CONVENTIONS.md): ``b`` the rover body (x forward, y right, z down); the cameras
``navcam_l``/``navcam_r`` have z along the boresight, x right, y down. Pixels ``(u, v)`` are
(column, row) as in ``estimation.camera_model``. Flight software: numpy only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimation.camera_model import PinholeCamera, check_rotation_matrix
from estimation.vo.stereo_rig import StereoRig

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class PointedPair:
    """A rectified stereo pair at one mast pointing, described in the body frame.

    ``camera`` both eyes' pinhole model; ``R_b_cam`` (3, 3) camera-to-body rotation;
    ``c_left_b``, ``c_right_b`` (3,) the optical centres in the body frame, m.
    """

    camera: PinholeCamera
    R_b_cam: FloatArray
    c_left_b: FloatArray
    c_right_b: FloatArray

    @classmethod
    def from_rig(cls, rig: StereoRig, az_rad: float, el_rad: float) -> PointedPair:
        """The rig pointed at mast azimuth ``az_rad`` and elevation ``el_rad``."""
        c_left_b, c_right_b = rig.eye_centres_b(az_rad, el_rad)
        return cls(rig.camera, rig.R_b_cam(az_rad, el_rad), c_left_b, c_right_b)

    def __post_init__(self) -> None:
        check_rotation_matrix(self.R_b_cam, "R_b_cam")
        for name in ("c_left_b", "c_right_b"):
            value = np.asarray(getattr(self, name), dtype=np.float64)
            if value.shape != (3,) or not np.all(np.isfinite(value)):
                raise ValueError(f"{name}: must be a finite 3-vector, got {value!r}")

    @property
    def baseline_b(self) -> FloatArray:
        """``B = C_2 - C_1``, left to right eye, body frame, m (Cheng, Maimone and Matthies 2005 eq.
        5)."""
        out: FloatArray = self.c_right_b - self.c_left_b
        return out

    def rays_b(self, uv_px: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Unit rays (N, 3) in the body frame through pixels ``uv_px`` (N, 2), and their
        derivatives with respect to ``(u, v)`` (N, 3, 2), per pixel.

        With ``w = R_b_cam (x, y, 1)``, ``x = (u - c_u) / f``: ``r = w / |w|`` and
        ``dr/dw = (I - r rᵀ) / |w|``, ``dw/du = R_b_cam[:, 0] / f``, ``dw/dv = R_b_cam[:, 1] / f``.
        """
        uv = _points(uv_px, 2, "uv_px")
        cam = self.camera
        x = (uv[:, 0] - cam.c_u_px) / cam.f_px
        y = (uv[:, 1] - cam.c_v_px) / cam.f_px
        w_cam = np.stack([x, y, np.ones_like(x)], axis=1)
        w_b = w_cam @ self.R_b_cam.T
        norm = np.linalg.norm(w_b, axis=1)
        r = w_b / norm[:, None]
        projector = (np.eye(3)[None] - r[:, :, None] * r[:, None, :]) / norm[:, None, None]
        dw = self.R_b_cam[:, :2] / cam.f_px  # (3, 2): dw/du, dw/dv
        d_r: FloatArray = projector @ dw
        return r, d_r

    def project(self, p_b: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Pixels ``(u, v)`` of body-frame points ``p_b`` (N, 3) in the left and right eyes,
        each (N, 2); NaN for points at or behind an eye's image plane."""
        p = _points(p_b, 3, "p_b")
        out = []
        for centre in (self.c_left_b, self.c_right_b):
            p_cam = (p - centre) @ self.R_b_cam  # R_cam_b = R_b_camᵀ, applied row-wise
            u, v = self.camera.project(p_cam)
            out.append(np.stack([u, v], axis=1))
        return out[0], out[1]

    def project_many(self, p_b: FloatArray) -> tuple[FloatArray, FloatArray]:
        """As :meth:`project` for a stack of point sets ``p_b`` (K, N, 3): (K, N, 2) each.

        Used to score many motion hypotheses at once; no NaN handling beyond a depth
        guard (points behind the eye get a huge pixel value, never a match).
        """
        if p_b.ndim != 3 or p_b.shape[-1] != 3:
            raise ValueError(f"p_b: must be (K, N, 3), got {p_b.shape}")
        cam = self.camera
        out = []
        for centre in (self.c_left_b, self.c_right_b):
            p_cam = (p_b - centre) @ self.R_b_cam
            z = p_cam[..., 2]
            safe = np.where(z > 1e-6, z, 1e-12)
            u = cam.f_px * p_cam[..., 0] / safe + cam.c_u_px
            v = cam.f_px * p_cam[..., 1] / safe + cam.c_v_px
            out.append(np.stack([u, v], axis=-1))
        return out[0], out[1]


def _points(values: ArrayLike, width: int, name: str) -> FloatArray:
    arr = np.asarray(values, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != width:
        raise ValueError(f"{name}: must be (N, {width}), got shape {arr.shape}")
    return arr
