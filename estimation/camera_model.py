"""Pinhole camera model (CAHV-equivalent) and the Pancam mast pointing.

The MER cameras are calibrated with JPL's CAHV(OR) models (Yakimovsky and Cunningham 1978;
Gennery 2001). A CAHV model with no distortion is exactly a pinhole camera: with ``C`` the
optical centre, ``A`` the unit boresight, and ``H = f x_cam + c_u A``,
``V = f y_cam + c_v A``, a point ``P`` images at::

    u = (P - C) . H / (P - C) . A        v = (P - C) . V / (P - C) . A

which is the usual ``u = f x/z + c_u``, ``v = f y/z + c_v`` in the camera frame. Pancam's
narrow field (16 deg) has negligible distortion for the sun finder, whose error budget
(Eisenman, Liebe and Perez 2002, Ali et al. 2005 ref. [3]) is dominated by centroiding.

Frames (docs/CONVENTIONS.md): the camera frame has ``z`` along the boresight, ``x`` right and
``y`` down in the image. Pixel coordinates ``(u, v)`` are (column, row) with the centre of
the first pixel at ``(0, 0)``, so a ``W x H`` image spans ``[-0.5, W - 0.5]`` and its centre
is ``((W - 1) / 2, (H - 1) / 2)``.

This is flight software: numpy only, and bad arguments raise ``ValueError`` naming the
parameter (``sim.errors.InputError`` is off limits here, see docs/DESIGN.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]

# Pancam (Bell et al. 2003, JGR 108(E12) 8063; docs/REFERENCES.md): 1024 x 1024 active pixels,
# 16 deg square field of view, 0.27-0.28 mrad/pixel, eyes 30 cm apart on the mast head.
PANCAM_WIDTH_PX = 1024
PANCAM_HEIGHT_PX = 1024
PANCAM_FOV_RAD = math.radians(16.0)  # full field, edge to edge (Bell et al. 2003)

# The sun is at infinity, so where on the mast the camera sits causes no parallax: only
# the pointing (R_b_pancam) matters here.


@dataclass(frozen=True)
class PinholeCamera:
    """A distortion-free pinhole camera with square pixels.

    ``f_px`` is the focal length in pixels; ``(c_u_px, c_v_px)`` the principal point in
    pixel coordinates (see the module docstring for the pixel convention).
    """

    width_px: int
    height_px: int
    f_px: float
    c_u_px: float
    c_v_px: float

    def __post_init__(self) -> None:
        if self.width_px <= 0 or self.height_px <= 0:
            raise ValueError(
                f"width_px/height_px: must be positive, got {self.width_px} x {self.height_px}"
            )
        if not (math.isfinite(self.f_px) and self.f_px > 0.0):
            raise ValueError(f"f_px: must be positive and finite, got {self.f_px}")

    @classmethod
    def from_fov(cls, width_px: int, height_px: int, fov_rad: float) -> PinholeCamera:
        """Camera whose horizontal field, edge to edge, is ``fov_rad``; centred principal point.

        >>> cam = PinholeCamera.from_fov(1024, 1024, math.radians(16.0))
        >>> round(cam.ifov_centre_rad * 1e3, 4)  # mrad per pixel at the centre
        0.2745
        """
        if not (0.0 < fov_rad < math.pi):
            raise ValueError(f"fov_rad: must be in (0, pi), got {fov_rad}")
        f_px = 0.5 * width_px / math.tan(0.5 * fov_rad)
        return cls(width_px, height_px, f_px, 0.5 * (width_px - 1), 0.5 * (height_px - 1))

    @property
    def ifov_centre_rad(self) -> float:
        """Angular size of one pixel at the principal point, radians."""
        return 1.0 / self.f_px

    def project(self, v_cam: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Pixel coordinates ``(u, v)`` of direction(s) or point(s) ``v_cam`` (..., 3).

        Any positive scale of ``v_cam`` gives the same pixel. Rays with ``z <= 0`` (at or
        behind the image plane) have no image: their ``u, v`` are NaN.
        """
        p = np.asarray(v_cam, dtype=np.float64)
        if p.shape[-1:] != (3,):
            raise ValueError(f"v_cam: last axis must have length 3, got shape {p.shape}")
        z = p[..., 2]
        ok = z > 0.0
        safe_z = np.where(ok, z, 1.0)
        u = np.where(ok, self.f_px * p[..., 0] / safe_z + self.c_u_px, np.nan)
        v = np.where(ok, self.f_px * p[..., 1] / safe_z + self.c_v_px, np.nan)
        return u, v

    def unproject(self, u_px: ArrayLike, v_px: ArrayLike) -> FloatArray:
        """Unit ray(s) in the camera frame through pixel coordinates ``(u, v)``; shape (..., 3)."""
        u = np.asarray(u_px, dtype=np.float64)
        v = np.asarray(v_px, dtype=np.float64)
        x = (u - self.c_u_px) / self.f_px
        y = (v - self.c_v_px) / self.f_px
        x, y = np.broadcast_arrays(x, y)
        ray = np.stack([x, y, np.ones_like(x)], axis=-1)
        out: FloatArray = ray / np.linalg.norm(ray, axis=-1, keepdims=True)
        return out

    def in_image(self, u_px: ArrayLike, v_px: ArrayLike) -> NDArray[np.bool_]:
        """True where ``(u, v)`` falls on the detector (``[-0.5, W - 0.5]`` etc.)."""
        u = np.asarray(u_px, dtype=np.float64)
        v = np.asarray(v_px, dtype=np.float64)
        inside: NDArray[np.bool_] = (
            (u >= -0.5) & (u <= self.width_px - 0.5) & (v >= -0.5) & (v <= self.height_px - 0.5)
        )
        return inside

    def cahv(
        self, R_w_cam: ArrayLike, c_w: ArrayLike
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """The equivalent JPL CAHV vectors ``(C, A, H, V)`` in a world frame ``w``.

        ``R_w_cam`` (3, 3) takes camera coordinates to ``w``; ``c_w`` (3,) is the optical
        centre in ``w``. Image coordinates follow this module's pixel convention.
        """
        R = check_rotation_matrix(R_w_cam, "R_w_cam")
        C = np.asarray(c_w, dtype=np.float64).reshape(3)
        A = R[:, 2].copy()
        H = self.f_px * R[:, 0] + self.c_u_px * A
        V = self.f_px * R[:, 1] + self.c_v_px * A
        return C, A, H, V


PANCAM = PinholeCamera.from_fov(PANCAM_WIDTH_PX, PANCAM_HEIGHT_PX, PANCAM_FOV_RAD)


def R_b_pancam(az_rad: float, el_rad: float) -> FloatArray:
    """Rotation taking Pancam camera coordinates to body coordinates, (3, 3).

    ``az_rad`` turns the mast clockwise about body Down (+z) from body +x (so +90 deg looks
    right, along body +y); ``el_rad`` raises the boresight up from the body x-y plane. The
    boresight is ``(cos el cos az, cos el sin az, -sin el)`` in the body frame; the image
    ``x`` (right) axis stays horizontal, ``(-sin az, cos az, 0)``, and ``y`` (down in the
    image) completes the right-handed frame, ``y = z x x``. The 1 deg stereo toe-in of each
    eye is a calibration detail folded into this matrix.

    >>> np.round(R_b_pancam(0.0, 0.0) @ [0.0, 0.0, 1.0], 12)  # boresight along body +x
    array([1., 0., 0.])
    """
    if not (math.isfinite(az_rad) and math.isfinite(el_rad)):
        raise ValueError(f"az_rad/el_rad: must be finite, got {az_rad}, {el_rad}")
    ca, sa = math.cos(az_rad), math.sin(az_rad)
    ce, se = math.cos(el_rad), math.sin(el_rad)
    z_b = np.array([ce * ca, ce * sa, -se])
    x_b = np.array([-sa, ca, 0.0])
    y_b = np.cross(z_b, x_b)
    return np.column_stack([x_b, y_b, z_b])


def mast_az_el_for(d_b: ArrayLike) -> tuple[float, float]:
    """Mast ``(az_rad, el_rad)`` that puts the Pancam boresight along body direction ``d_b``.

    Inverse of the boresight of :func:`R_b_pancam`; at the poles (straight up or down) the
    azimuth is arbitrary and returned as 0.
    """
    d = np.asarray(d_b, dtype=np.float64).reshape(-1)
    n = float(np.linalg.norm(d)) if d.shape == (3,) else 0.0
    if not (math.isfinite(n) and n > 0.0):
        raise ValueError(f"d_b: must be a finite non-zero 3-vector, got {d_b!r}")
    x, y, z = d / n
    el = math.atan2(-z, math.hypot(x, y))
    az = math.atan2(y, x) if math.hypot(x, y) > 1e-15 else 0.0
    return az, el


def check_rotation_matrix(R: ArrayLike, name: str) -> FloatArray:
    """Validate a 3x3 rotation matrix (orthonormal, det +1, to 1e-6)."""
    m = np.asarray(R, dtype=np.float64)
    if m.shape != (3, 3) or not np.all(np.isfinite(m)):
        raise ValueError(f"{name}: must be a finite 3x3 matrix, got shape {m.shape}")
    if not np.allclose(m.T @ m, np.eye(3), atol=1e-6) or np.linalg.det(m) < 0.0:
        raise ValueError(f"{name}: is not a proper rotation matrix")
    return m
