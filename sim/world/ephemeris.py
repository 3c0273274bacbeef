"""Truth ephemeris: the Sun and the Earth as seen from Mars, from JPL DE421, offline.

The kernel is the ``de421.bsp`` that the ``skyfield-data`` package ships (coverage
1899-07-29 .. 2053-10-09), read with ``jplephem`` and opened once per process. DE421:
Folkner, Williams and Boggs 2008, JPL IOM 343R-08-003.

What is included, and what is not (all positions ICRF/J2000 equatorial, km):

- Geometry: Mars centre is the DE421 chain SSB -> Mars barycentre -> Mars (499); Earth
  is SSB -> Earth-Moon barycentre -> Earth (399); the Sun is body 10.
- Light time (``astrometric_from_mars_j2000_km``): the body is taken where it was when the
  light that reaches Mars' centre at ``t`` left it, ``x_B(t - τ) - x_Mars(t)``, with
  ``τ = |...| / c`` iterated to convergence (three passes; sub-millisecond).
- Stellar aberration (``apparent_dir_from_mars_j2000``): the direction is shifted by
  Mars' barycentric velocity, ``u' ∝ u + v/c`` (first order in ``v/c``; the second-order
  term is below 1e-8 rad). About 17" for Mars' 24 km/s.
- Omitted: gravitational light bending by the Sun (< 2" even at conjunction), the
  rotation of Mars in the observer velocity (diurnal aberration, ~0.2"), and TDB - TT
  (< 2 ms, i.e. tens of metres). ``sim.world.mars_frames`` adds the surface parallax.

Time is ``t_s``, TT seconds since J2000 (used as TDB). Everything vectorises over ``t_s``:
outputs have shape ``t_s.shape + (3,)``.
"""

from __future__ import annotations

import functools
from datetime import UTC, datetime, timedelta
from importlib.resources import files
from pathlib import Path
from typing import Any, Literal

import numpy as np
from jplephem.spk import SPK
from numpy.typing import ArrayLike, NDArray

from sim.errors import InputError

FloatArray = NDArray[np.float64]
Body = Literal["sun", "earth"]

AU_KM = 149_597_870.7  # IAU 2012 Resolution B2, exact
C_KM_S = 299_792.458  # speed of light, exact
JD_J2000 = 2_451_545.0
SECONDS_PER_DAY = 86_400.0

_SUN, _EARTH, _EMB, _MARS_BARY, _MARS = 10, 399, 3, 4, 499  # NAIF ids
_LIGHT_TIME_PASSES = 3  # τ converges by a factor v/c ~ 1e-4 per pass
# Segment chains from the solar-system barycentre (0) to each body we use.
_CHAINS = {
    _SUN: [(0, _SUN)],
    _EARTH: [(0, _EMB), (_EMB, _EARTH)],
    _MARS: [(0, _MARS_BARY), (_MARS_BARY, _MARS)],
}


def de421_path() -> Path:
    """Path of the DE421 kernel inside the installed ``skyfield_data`` package."""
    return Path(str(files("skyfield_data") / "data" / "de421.bsp"))


@functools.lru_cache(maxsize=1)
def _kernel() -> Any:
    # Loaded once: SPK.open memory-maps the file, so later calls cost nothing.
    return SPK.open(str(de421_path()))


@functools.lru_cache(maxsize=1)
def coverage_t_s() -> tuple[float, float]:
    """First and last ``t_s`` at which every needed DE421 segment is valid, with 1 day spare.

    The spare day keeps light-time lookups (at most ~25 minutes back) inside the kernel.
    """
    segments = [s for s in _kernel().segments if s.target in (_SUN, _EARTH, _EMB, _MARS_BARY)]
    start = max(float(s.start_jd) for s in segments) + 1.0
    end = min(float(s.end_jd) for s in segments) - 1.0
    return (start - JD_J2000) * SECONDS_PER_DAY, (end - JD_J2000) * SECONDS_PER_DAY


def check_t_s(t_s: ArrayLike) -> FloatArray:
    """``t_s`` as a float array; ``InputError("utc", ...)`` if any instant is outside DE421."""
    t = np.asarray(t_s, dtype=float)
    first, last = coverage_t_s()
    if not np.all(np.isfinite(t)) or np.any(t < first) or np.any(t > last):
        j2000 = datetime(2000, 1, 1, 12, tzinfo=UTC)  # TT; minutes are all the message needs
        span = " .. ".join(
            (j2000 + timedelta(seconds=t)).strftime("%Y-%m-%dT%H:%M TT") for t in (first, last)
        )
        raise InputError("utc", f"outside the DE421 ephemeris ({span}); cannot compute truth")
    return t


def _state(target: int, t: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Barycentric position (km) and velocity (km/s) of ``target``, shapes (3, N)."""
    kernel = _kernel()
    pos = np.zeros((3, t.size))
    vel = np.zeros((3, t.size))
    for center, tgt in _CHAINS[target]:
        # Whole and fractional Julian days separately keep the epoch's precision.
        p, v = kernel[center, tgt].compute_and_differentiate(JD_J2000, t / SECONDS_PER_DAY)
        pos += np.asarray(p, dtype=float).reshape(3, -1)
        vel += np.asarray(v, dtype=float).reshape(3, -1) / SECONDS_PER_DAY
    return pos, vel


def _position(target: int, t: FloatArray) -> FloatArray:
    """Barycentric position (km) of ``target``, shape (3, N)."""
    kernel = _kernel()
    pos = np.zeros((3, t.size))
    for center, tgt in _CHAINS[target]:
        pos += np.asarray(kernel[center, tgt].compute(JD_J2000, t / SECONDS_PER_DAY)).reshape(3, -1)
    return pos


def _target_id(body: str) -> int:
    if body == "sun":
        return _SUN
    if body == "earth":
        return _EARTH
    raise InputError("body", f"must be 'sun' or 'earth', got {body!r}")


def astrometric_from_mars_j2000_km(body: Body, t_s: ArrayLike) -> FloatArray:
    """Light-time corrected position of ``body`` relative to Mars' centre, J2000, km.

    Shape ``t_s.shape + (3,)``. The light arrives at Mars' centre at ``t_s``.
    """
    target = _target_id(body)
    t = check_t_s(t_s)
    flat = t.reshape(-1)
    mars, _ = _state(_MARS, flat)
    rel = _position(target, flat) - mars
    for _ in range(_LIGHT_TIME_PASSES):
        tau_s = np.linalg.norm(rel, axis=0) / C_KM_S
        rel = _position(target, flat - tau_s) - mars
    out: FloatArray = rel.T.reshape((*t.shape, 3))
    return out


def mars_velocity_j2000_km_s(t_s: ArrayLike) -> FloatArray:
    """Barycentric velocity of Mars' centre, J2000, km/s; shape ``t_s.shape + (3,)``."""
    t = check_t_s(t_s)
    _, vel = _state(_MARS, t.reshape(-1))
    out: FloatArray = vel.T.reshape((*t.shape, 3))
    return out


def aberrate(p_j2000: ArrayLike, v_observer_km_s: ArrayLike) -> FloatArray:
    """Apparent unit direction of a source at ``p`` seen by an observer moving at ``v``.

    Classical stellar aberration to first order in ``v/c``, ``u' = normalise(u + v/c)``;
    the relativistic terms left out are of order ``(v/c)^2`` < 1e-8 rad. Shapes (..., 3).
    """
    p = np.asarray(p_j2000, dtype=float)
    u = p / np.linalg.norm(p, axis=-1, keepdims=True)
    w = u + np.asarray(v_observer_km_s, dtype=float) / C_KM_S
    out: FloatArray = w / np.linalg.norm(w, axis=-1, keepdims=True)
    return out


def apparent_dir_from_mars_j2000(body: Body, t_s: ArrayLike) -> FloatArray:
    """Apparent unit direction of ``body`` from Mars' centre (light time + aberration), J2000.

    >>> u = apparent_dir_from_mars_j2000("sun", 0.0)
    >>> round(float(np.linalg.norm(u)), 12)
    1.0
    """
    p = astrometric_from_mars_j2000_km(body, t_s)
    return aberrate(p, mars_velocity_j2000_km_s(t_s))


def mars_heliocentric_distance_au(t_s: ArrayLike) -> FloatArray:
    """Distance Sun - Mars centre (light-time corrected), AU; shape ``t_s.shape``."""
    out: FloatArray = np.linalg.norm(astrometric_from_mars_j2000_km("sun", t_s), axis=-1) / AU_KM
    return out
