"""Onboard ephemeris (the IVP "conic approximation"): Sun and Earth directions in LL.

Flight software (Ali et al. 2005: the rover computes the Sun's expected position
onboard for Sun finding and Sungaze, and the Earth's for HGA pointing). It never sees the
truth ephemeris; it needs only the onboard clock ``t_s`` (TT seconds since J2000) and the
site. Method:

1. Keplerian elements of the Earth-Moon barycentre and of Mars from Standish, "Keplerian
   Elements for Approximate Positions of the Major Planets" (JPL SSD), Table 1 (valid
   1800-2050; quoted errors for Mars 40" and 25,000 km; against DE421 over 1990-2050 we
   measure up to 101" in heliocentric longitude and 38,000 km in range), J2000 ecliptic,
   linear in ``T`` (Julian centuries of TDB, taken as TT). Standish's recipe, steps 1-6:
   (1) the elements at ``T``; (2) ``ω = ϖ - Ω``, ``M = L - ϖ``; (3) Kepler's equation
   ``M = E - e sin E`` by Newton; (4) orbital plane ``x' = a (cos E - e)``,
   ``y' = a sqrt(1 - e^2) sin E``; (5) rotation by ``ω, I, Ω`` to the J2000 ecliptic;
   (6) rotation by the obliquity ``ε = 23.43928°`` to the ICRF equator.
2. Sun from Mars is ``-r_Mars``; Earth from Mars is ``r_EMB(t - τ) - r_Mars(t)`` with the
   light time ``τ`` (the Earth-Moon barycentre stands in for the Earth: < 0.004°).
   Stellar aberration by Mars' heliocentric velocity (from the conic) is applied to both.
3. The IAU 2009 Mars pole and prime meridian (Archinal et al. 2011) to Mars-fixed, the
   parallax of a site on the reference ellipsoid, and the Local-Level frame (x North,
   y East, z Down along the ellipsoid normal at the planetographic latitude).

This module keeps its own copy of the IAU rotation and of the LL frame: flight software
imports nothing from ``sim``. Shapes: ``t_s`` broadcasts, outputs ``t_s.shape + (3,)``.
Bad input raises ``ValueError`` naming the parameter (``sim.errors.InputError`` is a
``ValueError`` too, but flight code cannot import it).
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

FloatArray = NDArray[np.float64]

AU_M = 149_597_870_700.0  # IAU 2012 Resolution B2, exact
C_AU_S = 299_792_458.0 / AU_M  # speed of light in AU/s
SECONDS_PER_CENTURY = 86_400.0 * 36_525.0
OBLIQUITY_J2000_RAD = math.radians(23.43928)  # Standish, J2000 obliquity of the ecliptic

# Standish Table 1 (1800-2050): value at J2000 and rate per Julian century of
# a (AU), e, I (deg), L (deg), ϖ (deg, longitude of perihelion), Ω (deg, ascending node).
EMB_ELEMENTS = (
    (1.00000261, 0.00000562),
    (0.01671123, -0.00004392),
    (-0.00001531, -0.01294668),
    (100.46457166, 35999.37244981),
    (102.93768193, 0.32327364),
    (0.0, 0.0),
)
MARS_ELEMENTS = (
    (1.52371034, 0.00001847),
    (0.09339410, 0.00007882),
    (1.84969142, -0.00813131),
    (-4.55343205, 19140.30268499),
    (-23.94362959, 0.44441088),
    (49.55953891, -0.29257343),
)
_B2_OVER_A2 = (MARS_POLAR_RADIUS_M / MARS_EQUATORIAL_RADIUS_M) ** 2


def _times(t_s: ArrayLike) -> FloatArray:
    t = np.asarray(t_s, dtype=float)
    if not np.all(np.isfinite(t)):
        raise ValueError("t_s: must be finite")
    return t


def solve_kepler(M_rad: ArrayLike, e: ArrayLike) -> FloatArray:
    """Eccentric anomaly ``E`` with ``M = E - e sin E`` (Newton; converges to 1e-14 rad).

    >>> round(float(solve_kepler(1.0, 0.1)), 9)
    1.088597752
    """
    M = np.asarray(M_rad, dtype=float)
    ecc = np.asarray(e, dtype=float)
    E: FloatArray = M + ecc * np.sin(M)  # Standish step 3, starting value
    for _ in range(8):  # quadratic convergence; e < 0.1 needs 3-4 steps
        E = E - (E - ecc * np.sin(E) - M) / (1.0 - ecc * np.cos(E))
    return E


def heliocentric_state_j2000(
    elements: tuple[tuple[float, float], ...], t_s: ArrayLike
) -> tuple[FloatArray, FloatArray]:
    """Heliocentric position (AU) and velocity (AU/s), ICRF/J2000 equatorial, (..., 3).

    ``elements`` is a Standish Table 1 set: ``EMB_ELEMENTS`` or ``MARS_ELEMENTS``.
    """
    T = _times(t_s) / SECONDS_PER_CENTURY
    a, e, I_deg, L_deg, varpi_deg, Omega_deg = (v0 + rate * T for v0, rate in elements)
    inc, Om = np.radians(I_deg), np.radians(Omega_deg)
    w = np.radians(varpi_deg - Omega_deg)  # step 2, argument of perihelion
    M = np.radians((L_deg - varpi_deg + 180.0) % 360.0 - 180.0)  # steps 2-3, in [-180, 180)
    E = solve_kepler(M, e)  # step 3
    sq = np.sqrt(1.0 - e**2)
    xp, yp = a * (np.cos(E) - e), a * sq * np.sin(E)  # step 4
    # Velocity in the orbital plane: dE/dt = n / (1 - e cos E), n from the rate of L.
    n = np.radians(elements[3][1]) / SECONDS_PER_CENTURY
    Edot = n / (1.0 - e * np.cos(E))
    vxp, vyp = -a * np.sin(E) * Edot, a * sq * np.cos(E) * Edot
    cw, sw, cO, sO, cI, sI = np.cos(w), np.sin(w), np.cos(Om), np.sin(Om), np.cos(inc), np.sin(inc)
    # step 5: orbital plane -> J2000 ecliptic
    m11, m12 = cw * cO - sw * sO * cI, -sw * cO - cw * sO * cI
    m21, m22 = cw * sO + sw * cO * cI, -sw * sO + cw * cO * cI
    m31, m32 = sw * sI, cw * sI
    ce, se = math.cos(OBLIQUITY_J2000_RAD), math.sin(OBLIQUITY_J2000_RAD)

    def to_eq(u: FloatArray, v: FloatArray) -> FloatArray:
        xe, ye, ze = m11 * u + m12 * v, m21 * u + m22 * v, m31 * u + m32 * v
        out: FloatArray = np.stack([xe, ce * ye - se * ze, se * ye + ce * ze], axis=-1)  # step 6
        return out

    return to_eq(xp, yp), to_eq(vxp, vyp)


def R_mf_j2000(t_s: ArrayLike) -> FloatArray:
    """IAU 2009 Mars rotation, J2000 -> Mars-fixed, (..., 3, 3) (onboard copy).

    Built as the Mars-fixed axes in J2000: ``z`` the pole ``(α0, δ0)``, ``x`` the prime
    meridian at ``W`` east of the node of the Mars equator on the ICRF equator.
    """
    t = _times(t_s)
    d = t / 86_400.0
    T = d / 36_525.0
    a0 = np.radians(317.68143 - 0.1061 * T)  # IAU 2009 (Archinal et al. 2011)
    d0 = np.radians(52.88650 - 0.0609 * T)
    W = np.radians((176.630 + 350.89198226 * d) % 360.0)
    pole = np.stack([np.cos(d0) * np.cos(a0), np.cos(d0) * np.sin(a0), np.sin(d0)], -1)
    node = np.stack([-np.sin(a0), np.cos(a0), np.zeros_like(a0)], -1)  # RA α0 + 90°
    q = np.cross(pole, node)  # completes the equatorial pair (node, q) of the Mars equator
    x = np.cos(W)[..., None] * node + np.sin(W)[..., None] * q
    y = np.cross(pole, x)
    out: FloatArray = np.stack([x, y, pole], axis=-2)
    return out


def _check_site(lat_rad: float, lon_east_rad: float) -> None:
    if not (math.isfinite(lat_rad) and abs(lat_rad) <= math.pi / 2):
        raise ValueError(f"lat_rad: must be in [-pi/2, pi/2], got {lat_rad!r}")
    if not math.isfinite(lon_east_rad):
        raise ValueError(f"lon_east_rad: must be finite, got {lon_east_rad!r}")


def R_ll_mf(lat_rad: float, lon_east_rad: float) -> FloatArray:
    """Mars-fixed -> Local-Level (N, E, Down), planetographic latitude, East longitude."""
    _check_site(lat_rad, lon_east_rad)
    sp, cp = math.sin(lat_rad), math.cos(lat_rad)
    sl, cl = math.sin(lon_east_rad), math.cos(lon_east_rad)
    return np.array([[-sp * cl, -sp * sl, cp], [-sl, cl, 0.0], [-cp * cl, -cp * sl, -sp]])


def _site_mf_au(lat_rad: float, lon_east_rad: float) -> FloatArray:
    # Point of the reference ellipsoid at the planetographic latitude (parallax, 13" max).
    n = MARS_EQUATORIAL_RADIUS_M / math.sqrt(
        math.cos(lat_rad) ** 2 + _B2_OVER_A2 * math.sin(lat_rad) ** 2
    )
    cp = math.cos(lat_rad)
    xyz = [n * cp * math.cos(lon_east_rad), n * cp * math.sin(lon_east_rad)]
    return np.array([*xyz, _B2_OVER_A2 * n * math.sin(lat_rad)]) / AU_M


def _to_ll(
    p_j2000_au: FloatArray, v_mars_au_s: FloatArray, t: FloatArray, lat: float, lon: float
) -> FloatArray:
    R = R_mf_j2000(t)
    p_mf = np.einsum("...ij,...j->...i", R, p_j2000_au) - _site_mf_au(lat, lon)
    v_mf = np.einsum("...ij,...j->...i", R, v_mars_au_s)
    u = p_mf / np.linalg.norm(p_mf, axis=-1, keepdims=True) + v_mf / C_AU_S  # aberration
    u_mf = u / np.linalg.norm(u, axis=-1, keepdims=True)
    out: FloatArray = u_mf @ R_ll_mf(lat, lon).T
    return out


def sun_from_mars_j2000_au(t_s: ArrayLike) -> FloatArray:
    """Sun relative to Mars' centre, ICRF/J2000, AU, (..., 3) (the Sun is the conic's focus)."""
    r_mars, _ = heliocentric_state_j2000(MARS_ELEMENTS, _times(t_s))
    return -r_mars


def earth_from_mars_j2000_au(t_s: ArrayLike) -> FloatArray:
    """Light-time corrected Earth(-Moon barycentre) relative to Mars' centre, J2000, AU.

    ``r_EMB(t - τ) - r_Mars(t)`` with ``τ = |...| / c`` (light arriving at Mars at ``t``).
    """
    t = _times(t_s)
    r_mars, _ = heliocentric_state_j2000(MARS_ELEMENTS, t)
    rel = heliocentric_state_j2000(EMB_ELEMENTS, t)[0] - r_mars
    for _ in range(3):  # τ ~ 3-22 min; each pass gains a factor v/c ~ 1e-4
        tau_s = np.linalg.norm(rel, axis=-1) / C_AU_S
        rel = heliocentric_state_j2000(EMB_ELEMENTS, t - tau_s)[0] - r_mars
    return rel


def sun_ll(t_s: ArrayLike, lat_rad: float, lon_east_rad: float) -> FloatArray:
    """Onboard Sun unit vector in LL (N, E, Down) at the site; shape ``t_s.shape + (3,)``.

    >>> u = sun_ll(0.0, 0.0, 0.0)
    >>> round(float(np.linalg.norm(u)), 12)
    1.0
    """
    _check_site(lat_rad, lon_east_rad)
    t = _times(t_s)
    v_mars = heliocentric_state_j2000(MARS_ELEMENTS, t)[1]
    return _to_ll(sun_from_mars_j2000_au(t), v_mars, t, lat_rad, lon_east_rad)


def earth_ll(t_s: ArrayLike, lat_rad: float, lon_east_rad: float) -> FloatArray:
    """Onboard Earth unit vector in LL (N, E, Down) at the site; shape ``t_s.shape + (3,)``."""
    _check_site(lat_rad, lon_east_rad)
    t = _times(t_s)
    v_mars = heliocentric_state_j2000(MARS_ELEMENTS, t)[1]
    return _to_ll(earth_from_mars_j2000_au(t), v_mars, t, lat_rad, lon_east_rad)


def mars_rotation_ll(lat_rad: float) -> FloatArray:
    """Mars' spin vector in LL (rad/s): ``Ω (cos φ, 0, -sin φ)``, ``φ`` planetographic.

    The LL Down axis is the ellipsoid normal, at angle ``φ`` (planetographic) from the
    equatorial plane, and the spin axis lies in the meridian plane (onboard copy).
    """
    if not (math.isfinite(lat_rad) and abs(lat_rad) <= math.pi / 2):
        raise ValueError(f"lat_rad: must be in [-pi/2, pi/2], got {lat_rad!r}")
    w = MARS_ROTATION_RATE_RAD_S
    return np.array([w * math.cos(lat_rad), 0.0, -w * math.sin(lat_rad)])
