"""Mars frames for the truth: IAU rotation, the Local-Level frame, truth Sun and Earth in LL.

- ``R_mf_j2000``: the IAU 2009 rotation model of Mars (IAU WGCCRE report, Archinal et al.
  2011, Celest. Mech. Dyn. Astr. 109, 101-135; docs/REFERENCES.md): pole
  ``α0 = 317.68143 - 0.1061 T``, ``δ0 = 52.88650 - 0.0609 T`` and prime meridian
  ``W = 176.630 + 350.89198226 d`` (degrees; ``T`` Julian centuries and ``d`` days of TDB
  since J2000, TT used for TDB). The body-fixed frame is
  ``R_z(W) R_x(90° - δ0) R_z(90° + α0)`` (frame rotations): the pole is the body ``z``
  axis and ``W`` is measured along the body equator from its ascending node on the ICRF
  equator (at right ascension ``α0 + 90°``), as the report defines it.
- ``R_ll_mf``: Local-Level (x North, y East, z Down) at a *planetographic* latitude, i.e.
  the Down axis is the inward normal of the IAU/IAG reference ellipsoid (3396.19 km by
  3376.20 km). The planetocentric latitude (angle at Mars' centre) differs from it by up to
  0.34°; ``planetocentric_from_planetographic`` and its inverse convert. Longitudes are
  East here; for an ellipsoid of revolution the longitude is the same in both systems.
- ``sun_ll_truth``, ``earth_ll_truth``: unit vectors from the ephemeris (light time and
  aberration, ``sim.world.ephemeris``), rotated by the IAU model, with the parallax of a site on
  the ellipsoid surface (up to 13" for the Earth, 3" for the Sun).

Mars24 (``sim.world.marsclock``) is *not* this geometry: it uses a planetographic solar
declination (D-1, with its ``+0.25° sin Ls`` term) in a spherical zenith formula (D-5)
with its own mean-sun clock. Its elevation and azimuth therefore differ from the rigorous
ones here by up to about 0.3°; the tests measure it. Use Mars24 for clocks and almanacs,
this module for truth.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimation.mars_constants import (
    MARS_EQUATORIAL_RADIUS_M,
    MARS_POLAR_RADIUS_M,
    MARS_ROTATION_RATE_RAD_S,
)
from sim.errors import InputError
from sim.world.ephemeris import (
    C_KM_S,
    Body,
    astrometric_from_mars_j2000_km,
    mars_velocity_j2000_km_s,
)

FloatArray = NDArray[np.float64]

SECONDS_PER_DAY = 86_400.0
DAYS_PER_CENTURY = 36_525.0
_B2_OVER_A2 = (MARS_POLAR_RADIUS_M / MARS_EQUATORIAL_RADIUS_M) ** 2  # ellipsoid (b/a)^2


def iau_mars_angles_rad(t_s: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
    """IAU 2009 Mars ``(α0, δ0, W)`` in radians at TT seconds ``t_s``; each ``t_s.shape``."""
    t = np.asarray(t_s, dtype=float)
    d = t / SECONDS_PER_DAY
    T = d / DAYS_PER_CENTURY
    alpha0 = np.radians(317.68143 - 0.1061 * T)  # IAU 2009 (Archinal et al. 2011)
    delta0 = np.radians(52.88650 - 0.0609 * T)
    W = np.radians((176.630 + 350.89198226 * d) % 360.0)  # mod first: keeps precision
    return alpha0, delta0, W


def _frame_rot(axis: int, angle: FloatArray) -> FloatArray:
    """Frame (passive) rotation matrices about ``axis`` by ``angle`` (rad), (..., 3, 3)."""
    c, s = np.cos(angle), np.sin(angle)
    one, zero = np.ones_like(c), np.zeros_like(c)
    if axis == 0:
        rows = [[one, zero, zero], [zero, c, s], [zero, -s, c]]
    else:  # axis 2
        rows = [[c, s, zero], [-s, c, zero], [zero, zero, one]]
    out: FloatArray = np.stack([np.stack(r, axis=-1) for r in rows], axis=-2)
    return out


def R_mf_j2000(t_s: ArrayLike) -> FloatArray:
    """Rotation taking J2000 (ICRF) coordinates to Mars-fixed at ``t_s``; (..., 3, 3).

    ``v_mf = R_mf_j2000(t_s) @ v_j2000``. Rows are the Mars-fixed axes in J2000.
    """
    alpha0, delta0, W = iau_mars_angles_rad(t_s)
    out: FloatArray = (
        _frame_rot(2, W) @ _frame_rot(0, np.pi / 2 - delta0) @ _frame_rot(2, np.pi / 2 + alpha0)
    )
    return out


def _check_site(lat_rad: float, lon_east_rad: float) -> None:
    if not (math.isfinite(lat_rad) and abs(lat_rad) <= math.pi / 2):
        raise InputError("lat_rad", f"must be in [-pi/2, pi/2], got {lat_rad!r}")
    if not math.isfinite(lon_east_rad):
        raise InputError("lon_east_rad", f"must be finite, got {lon_east_rad!r}")


def planetocentric_from_planetographic(lat_rad: ArrayLike) -> FloatArray:
    """Planetocentric latitude of a surface point with planetographic latitude ``lat_rad``.

    ``tan φc = (b/a)^2 tan φg`` on the reference ellipsoid.

    >>> round(math.degrees(float(planetocentric_from_planetographic(math.radians(-14.64)))), 3)
    -14.475
    """
    g = np.asarray(lat_rad, dtype=float)
    out: FloatArray = np.arctan2(_B2_OVER_A2 * np.sin(g), np.cos(g))
    return out


def planetographic_from_planetocentric(lat_rad: ArrayLike) -> FloatArray:
    """Inverse of ``planetocentric_from_planetographic``."""
    c = np.asarray(lat_rad, dtype=float)
    out: FloatArray = np.arctan2(np.sin(c), _B2_OVER_A2 * np.cos(c))
    return out


def site_mf_m(lat_rad: float, lon_east_rad: float) -> FloatArray:
    """Mars-fixed position (m) of the reference-ellipsoid point at planetographic latitude."""
    _check_site(lat_rad, lon_east_rad)
    a = MARS_EQUATORIAL_RADIUS_M
    n = a / math.sqrt(math.cos(lat_rad) ** 2 + _B2_OVER_A2 * math.sin(lat_rad) ** 2)
    return np.array(
        [
            n * math.cos(lat_rad) * math.cos(lon_east_rad),
            n * math.cos(lat_rad) * math.sin(lon_east_rad),
            _B2_OVER_A2 * n * math.sin(lat_rad),
        ]
    )


def mf_from_site_m(p_s_m: ArrayLike, lat_rad: float, lon_east_rad: float) -> FloatArray:
    """Mars-fixed positions (m) of Site-frame points ``p_s_m`` (..., 3) (North, East, Down)
    of a Site whose origin is the ellipsoid point at ``lat_rad``, ``lon_east_rad``: the Site
    frame is the LL frame of its origin."""
    p = np.asarray(p_s_m, dtype=np.float64)
    out: FloatArray = site_mf_m(lat_rad, lon_east_rad) + p @ R_ll_mf(lat_rad, lon_east_rad)
    return out


def R_ll_mf(lat_rad: ArrayLike, lon_east_rad: ArrayLike) -> FloatArray:
    """Rotation taking Mars-fixed coordinates to Local-Level (N, E, Down) at the site.

    ``lat_rad`` planetographic (Down = inward ellipsoid normal), ``lon_east_rad`` East;
    scalars give (3, 3), arrays broadcast to (..., 3, 3). Rows are the North, East and
    Down unit vectors in Mars-fixed coordinates.
    """
    lat = np.asarray(lat_rad, dtype=float)
    lon = np.asarray(lon_east_rad, dtype=float)
    if not (np.all(np.isfinite(lat)) and np.all(np.abs(lat) <= math.pi / 2)):
        raise InputError("lat_rad", f"must be in [-pi/2, pi/2], got {lat_rad!r}")
    if not np.all(np.isfinite(lon)):
        raise InputError("lon_east_rad", f"must be finite, got {lon_east_rad!r}")
    sp, cp = np.sin(lat), np.cos(lat)
    sl, cl = np.sin(lon), np.cos(lon)
    sp, cp, sl, cl = np.broadcast_arrays(sp, cp, sl, cl)
    rows = [
        np.stack([-sp * cl, -sp * sl, cp], axis=-1),  # North
        np.stack([-sl, cl, np.zeros_like(sl)], axis=-1),  # East
        np.stack([-cp * cl, -cp * sl, -sp], axis=-1),  # Down
    ]
    out: FloatArray = np.stack(rows, axis=-2)
    return out


def body_ll_truth(body: Body, t_s: ArrayLike, lat_rad: float, lon_east_rad: float) -> FloatArray:
    """Apparent unit vector to ``body`` in LL at a surface site; shape ``t_s.shape + (3,)``.

    Light-time corrected ephemeris position relative to Mars' centre, minus the site's
    position (parallax), then aberration by Mars' orbital velocity, in Mars-fixed axes.
    """
    _check_site(lat_rad, lon_east_rad)
    R = R_mf_j2000(t_s)
    p_mf_km = np.einsum("...ij,...j->...i", R, astrometric_from_mars_j2000_km(body, t_s))
    p_mf_km = p_mf_km - site_mf_m(lat_rad, lon_east_rad) / 1000.0
    v_mf_km_s = np.einsum("...ij,...j->...i", R, mars_velocity_j2000_km_s(t_s))
    # Aberration is a vector sum, valid in any axes; the rotation of the axes themselves
    # does not enter because v is Mars' inertial velocity expressed in them.
    u = p_mf_km / np.linalg.norm(p_mf_km, axis=-1, keepdims=True) + v_mf_km_s / C_KM_S
    u_mf = u / np.linalg.norm(u, axis=-1, keepdims=True)
    out: FloatArray = u_mf @ R_ll_mf(lat_rad, lon_east_rad).T
    return out


def sun_ll_truth(t_s: ArrayLike, lat_rad: float, lon_east_rad: float) -> FloatArray:
    """Truth apparent Sun unit vector in LL (N, E, Down); shape ``t_s.shape + (3,)``."""
    return body_ll_truth("sun", t_s, lat_rad, lon_east_rad)


def earth_ll_truth(t_s: ArrayLike, lat_rad: float, lon_east_rad: float) -> FloatArray:
    """Truth apparent Earth unit vector in LL (N, E, Down); shape ``t_s.shape + (3,)``."""
    return body_ll_truth("earth", t_s, lat_rad, lon_east_rad)


def elevation_rad(v_ll: ArrayLike) -> FloatArray:
    """Elevation above the local horizon (rad, positive up) of LL vectors (..., 3)."""
    v = np.asarray(v_ll, dtype=float)
    out: FloatArray = np.arcsin(np.clip(-v[..., 2] / np.linalg.norm(v, axis=-1), -1.0, 1.0))
    return out


def azimuth_rad(v_ll: ArrayLike) -> FloatArray:
    """Azimuth (rad, clockwise from North towards East, in [0, 2π)) of LL vectors (..., 3)."""
    v = np.asarray(v_ll, dtype=float)
    out: FloatArray = np.arctan2(v[..., 1], v[..., 0]) % (2 * np.pi)
    return out


def ll_from_elevation_azimuth(elev_rad: ArrayLike, az_rad: ArrayLike) -> FloatArray:
    """Unit LL vector (N, E, Down) of an elevation and azimuth (rad); shape (..., 3)."""
    e = np.asarray(elev_rad, dtype=float)
    a = np.asarray(az_rad, dtype=float)
    out: FloatArray = np.stack([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), -np.sin(e)], -1)
    return out


def mars_rotation_ll(lat_rad: float) -> FloatArray:
    """Mars' rotation vector (rad/s) in LL at planetographic ``lat_rad``: ``Ω(cos φ, 0, -sin φ)``.

    The spin axis lies in the site's meridian plane, and the LL Down axis is the ellipsoid
    normal, which makes the angle ``φ`` (planetographic = geodetic) with the equator, so
    the spin splits into ``Ω cos φ`` along North and ``Ω sin φ`` up (hence ``-`` on Down).
    Using the planetocentric latitude here would tilt it by up to 0.34°. A rover at rest
    reads exactly this on its gyros.
    """
    if not (math.isfinite(lat_rad) and abs(lat_rad) <= math.pi / 2):
        raise InputError("lat_rad", f"must be in [-pi/2, pi/2], got {lat_rad!r}")
    w = MARS_ROTATION_RATE_RAD_S
    return np.array([w * math.cos(lat_rad), 0.0, -w * math.sin(lat_rad)])
