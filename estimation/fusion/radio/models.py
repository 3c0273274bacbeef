"""Models of the radio + terrain-matching EKF (Jiang, Li et al. 2014), with Jacobians.

State ``X = [L, λ, v_N, v_E]`` (sec. 4.1): planetographic latitude and East longitude of
the rover's body origin (rad) and its North and East velocity on the surface (m/s).

- Eq. 1: the body-to-navigation rotation from the 3-2-1 Euler angles. The paper's
  navigation frame is East-North-Up; ours is the Local-Level frame (North, East, Down,
  docs/CONVENTIONS.md), where the same yaw-pitch-roll sequence gives
  ``R_ll_b = R_z(ψ) R_y(θ) R_x(φ)`` (yaw clockwise from North, pitch nose up, roll right).
- Eq. 2: ``dp/dt = D v``, ``dv/dt = Ξ[R_ll_b (ã - b_a)]_{3→2}``. The accelerometers read
  specific force; gravity lies along LL Down, so the first two (North, East) components of
  ``R_ll_b f_b`` are the horizontal acceleration exactly as eq. 2 extracts them. The paper
  takes Mars as a sphere, ``D = diag(1/R_M, 1/(R_M cos L))``; we use the reference
  ellipsoid's radii of curvature at the planetographic latitude,
  ``D = diag(1/(M + h), 1/((N + h) cos L))`` (the sphere is the case ``M = N = R_M``):
  with a sphere the latitude scale would be off by up to 0.6 %, 0.6 m per 100 m.
- Eq. 4: the gyro's yaw rate. The paper's state has no heading; a rover drives where it
  points, so its yaw rate is the turn rate of its velocity,
  ``ω = (v_N a_E - v_E a_N) / (v_N² + v_E²)`` with ``a`` the eq. 2 acceleration. That makes
  eq. 4 a function of the state (our reading; the paper gives no ``h``).
- Eqs. 7-9: range to an orbiting beacon, ``R = |r - r_o|`` in Mars-fixed axes (the same
  length as in the paper's inertial axes); ``r = f(p)`` is the geodetic position of the
  body origin at height ``h`` above the ellipsoid, which the onboard 3D map supplies.
- Eqs. 10-11: pinhole pixels ``(u, v) = f (x_c, y_c) / z_c`` of a matched landmark in the
  camera frame (z boresight, x right, y down), the camera on a mast that pans about body z.

Shapes: state (4,); Jacobians (m, 4). Inputs are validated by the filter
(``estimation.fusion.radio.ekf``); these functions assume valid arrays.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from estimation.mars_constants import MARS_EQUATORIAL_RADIUS_M, MARS_POLAR_RADIUS_M

FloatArray = NDArray[np.float64]

E2 = 1.0 - (MARS_POLAR_RADIUS_M / MARS_EQUATORIAL_RADIUS_M) ** 2  # first eccentricity²


def R_ll_b_from_euler(roll_rad: float, pitch_rad: float, yaw_rad: float) -> FloatArray:
    """Eq. 1 in LL (N, E, Down): ``R_ll_b = R_z(yaw) R_y(pitch) R_x(roll)``, 3-2-1 sequence.

    >>> np.round(R_ll_b_from_euler(0.0, 0.0, math.pi / 2) @ [1.0, 0.0, 0.0], 12) + 0.0
    array([0., 1., 0.])
    """
    cr, sr = math.cos(roll_rad), math.sin(roll_rad)
    cp, sp = math.cos(pitch_rad), math.sin(pitch_rad)
    cy, sy = math.cos(yaw_rad), math.sin(yaw_rad)
    return np.array(
        [
            [cp * cy, sr * sp * cy - cr * sy, cr * sp * cy + sr * sy],
            [cp * sy, sr * sp * sy + cr * cy, cr * sp * sy - sr * cy],
            [-sp, sr * cp, cr * cp],
        ]
    )


def euler_from_R_ll_b(R_ll_b: FloatArray) -> tuple[float, float, float]:
    """Inverse of ``R_ll_b_from_euler``: ``(roll, pitch, yaw)`` in radians."""
    pitch = math.asin(max(-1.0, min(1.0, -float(R_ll_b[2, 0]))))
    roll = math.atan2(float(R_ll_b[2, 1]), float(R_ll_b[2, 2]))
    yaw = math.atan2(float(R_ll_b[1, 0]), float(R_ll_b[0, 0]))
    return roll, pitch, yaw


def radii_of_curvature_m(lat_rad: float) -> tuple[float, float, float, float]:
    """Meridian ``M`` and prime-vertical ``N`` radii (m) and their latitude derivatives.

    ``M = a (1 - e²) / w^{3/2}``, ``N = a / w^{1/2}``, ``w = 1 - e² sin² L`` (standard
    geodesy, as ``sim.world.local_level``); returns ``(M, N, dM/dL, dN/dL)``.
    """
    s, c = math.sin(lat_rad), math.cos(lat_rad)
    w = 1.0 - E2 * s * s
    M = MARS_EQUATORIAL_RADIUS_M * (1.0 - E2) / w**1.5
    N = MARS_EQUATORIAL_RADIUS_M / math.sqrt(w)
    return M, N, 3.0 * M * E2 * s * c / w, N * E2 * s * c / w


def position_mf_m(lat_rad: float, lon_east_rad: float, height_m: float) -> FloatArray:
    """``r = f(p)`` (eq. 8): Mars-fixed position (m) of a point at planetographic latitude,
    East longitude and height above the reference ellipsoid."""
    _, N, _, _ = radii_of_curvature_m(lat_rad)
    cl, sl = math.cos(lat_rad), math.sin(lat_rad)
    return np.array(
        [
            (N + height_m) * cl * math.cos(lon_east_rad),
            (N + height_m) * cl * math.sin(lon_east_rad),
            (N * (1.0 - E2) + height_m) * sl,
        ]
    )


def R_ll_mf(lat_rad: float, lon_east_rad: float) -> FloatArray:
    """Mars-fixed -> LL (North, East, Down) at a planetographic latitude (rows: N, E, D)."""
    sp, cp = math.sin(lat_rad), math.cos(lat_rad)
    sl, cl = math.sin(lon_east_rad), math.cos(lon_east_rad)
    return np.array([[-sp * cl, -sp * sl, cp], [-sl, cl, 0.0], [-cp * cl, -cp * sl, -sp]])


def _dR_ll_mf(lat_rad: float, lon_east_rad: float) -> tuple[FloatArray, FloatArray]:
    """Derivatives of ``R_ll_mf`` with respect to latitude and longitude."""
    sp, cp = math.sin(lat_rad), math.cos(lat_rad)
    sl, cl = math.sin(lon_east_rad), math.cos(lon_east_rad)
    d_lat = np.array([[-cp * cl, -cp * sl, -sp], [0.0, 0.0, 0.0], [sp * cl, sp * sl, -cp]])
    d_lon = np.array([[sp * sl, -sp * cl, 0.0], [-cl, -sl, 0.0], [cp * sl, -cp * cl, 0.0]])
    return d_lat, d_lon


# ---- eq. 2: dynamics -----------------------------------------------------------------------


def dynamics(x: FloatArray, accel_ne_m_s2: FloatArray, height_m: float) -> FloatArray:
    """Eq. 2 / eq. 12: ``dX/dt = [D v, a_NE]`` for the horizontal acceleration ``a_NE``."""
    M, N, _, _ = radii_of_curvature_m(float(x[0]))
    return np.array(
        [
            x[2] / (M + height_m),  # dL/dt = v_N / (M + h)
            x[3] / ((N + height_m) * math.cos(float(x[0]))),  # dλ/dt = v_E / ((N + h) cos L)
            accel_ne_m_s2[0],
            accel_ne_m_s2[1],
        ]
    )


def dynamics_jacobian(x: FloatArray, height_m: float) -> FloatArray:
    """Eq. 22: ``F = ∂f/∂X`` of ``dynamics`` (the acceleration is an input), (4, 4)."""
    lat = float(x[0])
    M, N, dM, dN = radii_of_curvature_m(lat)
    c, s = math.cos(lat), math.sin(lat)
    east_radius = (N + height_m) * c
    F = np.zeros((4, 4))
    F[0, 0] = -x[2] * dM / (M + height_m) ** 2
    F[0, 2] = 1.0 / (M + height_m)
    F[1, 0] = -x[3] * (dN * c - (N + height_m) * s) / east_radius**2
    F[1, 3] = 1.0 / east_radius
    return F


def horizontal_accel_ne(
    specific_force_b: FloatArray, accel_bias_b: FloatArray, R_ll_b: FloatArray
) -> FloatArray:
    """Eq. 2's ``Ξ[T (ã - b_a)]_{3→2}``: North and East acceleration (m/s²), (2,)."""
    out: FloatArray = (R_ll_b @ (specific_force_b - accel_bias_b))[:2]
    return out


# ---- eq. 4: gyro yaw rate ------------------------------------------------------------------


def yaw_rate(x: FloatArray, accel_ne_m_s2: FloatArray) -> tuple[float, FloatArray]:
    """Eq. 4's ``ω`` (rad/s, about LL Down) of a rover heading along its velocity, and its
    Jacobian (1, 4): ``ω = (v_N a_E - v_E a_N) / |v|²``."""
    vn, ve = float(x[2]), float(x[3])
    an, ae = float(accel_ne_m_s2[0]), float(accel_ne_m_s2[1])
    s = vn * vn + ve * ve
    cross = vn * ae - ve * an
    H = np.zeros((1, 4))
    H[0, 2] = (ae * s - 2.0 * vn * cross) / (s * s)
    H[0, 3] = (-an * s - 2.0 * ve * cross) / (s * s)
    return cross / s, H


# ---- eqs. 7-9: range to an orbiting beacon ------------------------------------------------


def beacon_range(
    x: FloatArray, height_m: float, beacon_mf_m: FloatArray
) -> tuple[float, FloatArray]:
    """Eq. 8: ``R = |r(p) - r_o|`` (m) with the beacon at ``beacon_mf_m`` (Mars-fixed, m),
    and its Jacobian (1, 4): ``∂R/∂L = u·(M + h) n_N``, ``∂R/∂λ = u·(N + h) cos L e_E``
    with ``u`` the unit vector from the beacon to the rover."""
    lat, lon = float(x[0]), float(x[1])
    d = position_mf_m(lat, lon, height_m) - beacon_mf_m
    rng = float(np.linalg.norm(d))
    M, N, _, _ = radii_of_curvature_m(lat)
    u_ll = R_ll_mf(lat, lon) @ (d / rng)  # the derivatives of r are along LL North and East
    H = np.zeros((1, 4))
    H[0, 0] = u_ll[0] * (M + height_m)
    H[0, 1] = u_ll[1] * (N + height_m) * math.cos(lat)
    return rng, H


# ---- eqs. 10-11: line-of-sight pixels of a landmark ----------------------------------------


def R_cam_b(pan_rad: float) -> FloatArray:
    """Body -> camera for a level camera panned ``pan_rad`` right of the body x axis.

    Camera z (boresight) ``= (cos pan, sin pan, 0)_b``, x (right) ``= (-sin pan, cos pan,
    0)_b``, y (down) ``= z_b``; rows are those axes in body coordinates.
    """
    c, s = math.cos(pan_rad), math.sin(pan_rad)
    return np.array([[-s, c, 0.0], [0.0, 0.0, 1.0], [c, s, 0.0]])


def landmark_pixels(
    x: FloatArray,
    height_m: float,
    landmark_mf_m: FloatArray,
    R_cam_ll: FloatArray,
    camera_offset_ll_m: FloatArray,
    focal_px: float,
) -> tuple[FloatArray, FloatArray, FloatArray, float]:
    """Eqs. 10-11 for one landmark: pixels ``(u, v)`` (2,) relative to the principal point,
    their Jacobian with respect to the state (2, 4), with respect to the landmark's LL
    position (2, 3) (to carry the map's error into the measurement covariance), and the
    landmark's depth ``z_c`` (m; not positive: behind the camera).

    ``landmark_mf_m`` Mars-fixed (m); ``R_cam_ll`` LL -> camera; ``camera_offset_ll_m`` the
    camera's optical centre relative to the body origin, LL axes (m).
    """
    lat, lon = float(x[0]), float(x[1])
    d_mf = landmark_mf_m - position_mf_m(lat, lon, height_m)
    R = R_ll_mf(lat, lon)
    c_ll = R @ d_mf - camera_offset_ll_m  # landmark relative to the camera, LL axes
    xc, yc, zc = R_cam_ll @ c_ll
    pixels = focal_px * np.array([xc / zc, yc / zc])  # eq. 10
    d_pix_d_cam = (focal_px / zc) * np.array([[1.0, 0.0, -xc / zc], [0.0, 1.0, -yc / zc]])
    d_pix_d_ll = d_pix_d_cam @ R_cam_ll
    M, N, _, _ = radii_of_curvature_m(lat)
    d_lat, d_lon = _dR_ll_mf(lat, lon)
    # ∂c_ll/∂L = (∂R/∂L) d - (M + h) e_N ; ∂c_ll/∂λ = (∂R/∂λ) d - (N + h) cos L e_E
    dc_dlat = d_lat @ d_mf - np.array([M + height_m, 0.0, 0.0])
    dc_dlon = d_lon @ d_mf - np.array([0.0, (N + height_m) * math.cos(lat), 0.0])
    H = np.zeros((2, 4))
    H[:, 0] = d_pix_d_ll @ dc_dlat
    H[:, 1] = d_pix_d_ll @ dc_dlon
    return pixels, H, d_pix_d_ll, float(zc)
