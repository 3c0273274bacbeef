"""The Local-Level frame at the rover versus the Site frame it drives in.

A Site frame has the orientation of the Local-Level frame where it was planted (Ali et al. 2005,
Table 1) and stays fixed to the surface; the Local-Level frame travels with the rover and
stays aligned with the local North, East and ellipsoid normal. On the curved surface of
Mars the two separate by ``d / R``: 0.0017 deg after 100 m. Small, but it is real, so the
truth attitude the sensors see is taken relative to the LL frame at the rover.

The rover's displacement ``(dN, dE)`` in the Site frame maps to a change of planetographic
latitude and longitude through the ellipsoid's radii of curvature in the meridian ``M`` and
in the prime vertical ``N`` (standard geodesy, e.g. Torge, *Geodesy*, sec. 4.1)::

    dφ = dN / M,  dλ = dE / (N cos φ),
    M = a (1 - e²) / (1 - e² sin² φ)^(3/2),  N = a / (1 - e² sin² φ)^(1/2)

then ``R_ll_s = R_ll_mf(φ + dφ, λ + dλ) R_mf_ll(φ, λ)``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimation.mars_constants import MARS_EQUATORIAL_RADIUS_M, MARS_POLAR_RADIUS_M
from estimation.quaternion import quat_multiply
from sim.world.mars_frames import R_ll_mf

FloatArray = NDArray[np.float64]

_E2 = 1.0 - (MARS_POLAR_RADIUS_M / MARS_EQUATORIAL_RADIUS_M) ** 2  # first eccentricity squared


def R_ll_s(p_s: ArrayLike, site_lat_rad: float, site_lon_east_rad: float) -> FloatArray:
    """Rotation from Site to the Local-Level frame at Site-frame positions ``p_s`` (..., 3).

    ``site_lat_rad`` is the planetographic latitude of the Site origin. Returns (..., 3, 3).
    """
    p = np.asarray(p_s, dtype=np.float64)
    a = MARS_EQUATORIAL_RADIUS_M
    w = 1.0 - _E2 * np.sin(site_lat_rad) ** 2
    meridian_m = a * (1.0 - _E2) / w**1.5
    prime_vertical_m = a / np.sqrt(w)
    lat = site_lat_rad + p[..., 0] / meridian_m
    lon = site_lon_east_rad + p[..., 1] / (prime_vertical_m * np.cos(site_lat_rad))
    R_ll_mf_here = R_ll_mf(lat, lon)
    R_ll_mf_site = R_ll_mf(site_lat_rad, site_lon_east_rad)
    out: FloatArray = R_ll_mf_here @ R_ll_mf_site.T
    return out


def q_ll_b_from_site(
    q_s_b: ArrayLike, p_s: ArrayLike, site_lat_rad: float, site_lon_east_rad: float
) -> FloatArray:
    """Body attitude in the LL frame at the rover, from its attitude in the Site frame.

    ``q_s_b`` (N, 4) ``[x, y, z, w]``, ``p_s`` (N, 3) metres; returns ``q_ll_b`` (N, 4).
    """
    from scipy.spatial.transform import Rotation

    q_ll_s = Rotation.from_matrix(R_ll_s(p_s, site_lat_rad, site_lon_east_rad)).as_quat()
    return quat_multiply(q_ll_s, q_s_b)
