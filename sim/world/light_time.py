"""Light time between Earth and Mars, as a navigation team computes it from JPL's ephemeris.

Every command the ground radiates and every frame the rover sends crosses 3 to 22 minutes
of space (Mishkin, Limonadi, Laubach and Bass 2006): the ground plans across that delay.
This module gives the delay from DE421 (Folkner, Williams and Boggs 2008,
``sim.world.ephemeris``): ground knowledge, the ephemeris as a mission's navigation team
has it.

Geometry: centre of Earth to centre of Mars, barycentric positions (ICRF, km), ``c`` exact.
Left out: Mars' radius (up to ~11 ms of light between the rover and Mars' centre), the
station's place on Earth (~21 ms), the Shapiro delay near conjunction (< 0.25 ms) and
TDB - TT (< 2 ms of clock, km of geometry): together well under a tenth of a second.

Three questions, three light-time equations, each solved by fixed-point iteration to
better than 1e-6 s (each pass shrinks the error by the bodies' speed over ``c``, ~1e-4):

- ``one_way_light_time_s(t)``: the light reaching Mars' centre at ``t`` left Earth's
  centre at ``t - τ``, ``τ = |x_Mars(t) - x_Earth(t - τ)| / c`` (the light time that
  ``sim.world.ephemeris`` applies to Earth's direction).
- ``uplink_arrival_t_s(t_radiated)``: the signal Earth radiates at ``t_radiated`` reaches
  Mars at ``t_a`` with ``t_a - τ(t_a) = t_radiated``.
- ``downlink_arrival_t_s(t_sent)``: the signal Mars sends at ``t_sent`` reaches Earth at
  ``t_sent + τ'``, ``τ' = |x_Earth(t_sent + τ') - x_Mars(t_sent)| / c``.

Time is ``t_s``, TT seconds since J2000 (used as TDB). A non-finite time, or one whose
light path leaves DE421's coverage, raises ``InputError`` naming the argument.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sim.errors import InputError
from sim.world.ephemeris import _EARTH, _MARS, C_KM_S, _position, check_t_s

FloatArray = NDArray[np.float64]

TOLERANCE_S = 1.0e-7  # a pass changing τ by less than this ends the iteration
_MAX_PASSES = 10  # the error shrinks by ~1e-4 a pass: three or four passes suffice


def _checked(name: str, t_s: ArrayLike) -> FloatArray:
    """``check_t_s``, its ``InputError`` naming ``name`` rather than ``utc``."""
    if isinstance(t_s, bool):
        raise InputError(name, f"must be TT seconds since J2000, got {t_s!r}")
    try:
        return check_t_s(t_s)
    except (TypeError, ValueError) as err:
        problem = err.problem if isinstance(err, InputError) else str(err)
        raise InputError(name, problem) from None


def _scalar(name: str, t_s: float) -> float:
    if isinstance(t_s, bool) or not isinstance(t_s, int | float | np.floating | np.integer):
        raise InputError(name, f"must be a number of TT seconds since J2000, got {t_s!r}")
    if not math.isfinite(t_s):
        raise InputError(name, f"must be finite, got {t_s!r}")
    return float(_checked(name, t_s))


def _distance_s(a_km: FloatArray, b_km: FloatArray) -> FloatArray:
    """Light seconds between positions of shape (3, N)."""
    out: FloatArray = np.linalg.norm(a_km - b_km, axis=0) / C_KM_S
    return out


def _converge(name: str) -> InputError:  # not reached on DE421's planets: a guard
    return InputError(name, f"light time did not converge in {_MAX_PASSES} passes")


def one_way_light_time_s(t_s: ArrayLike) -> FloatArray:
    """One-way light time (s) of the light that reaches Mars' centre at ``t_s`` from Earth's.

    ``τ = |x_Mars(t_s) - x_Earth(t_s - τ)| / c``; shape ``t_s.shape`` (0-d for a scalar,
    so ``float(...)`` works).

    >>> 180.0 < float(one_way_light_time_s(0.0)) < 1340.0
    True
    """
    t = _checked("t_s", t_s)
    flat = t.reshape(-1)
    mars = _position(_MARS, flat)
    tau = _distance_s(mars, _position(_EARTH, flat))
    for _ in range(_MAX_PASSES):
        _checked("t_s", flat - tau)  # the light left Earth inside the ephemeris
        following = _distance_s(mars, _position(_EARTH, flat - tau))
        change = float(np.max(np.abs(following - tau), initial=0.0))
        tau = following
        if change < TOLERANCE_S:
            out: FloatArray = tau.reshape(t.shape)
            return out
    raise _converge("t_s")


def uplink_arrival_t_s(t_radiated_s: float) -> float:
    """When (TT s) a signal radiated from Earth's centre at ``t_radiated_s`` reaches Mars'
    centre: ``t_a`` with ``t_a - τ(t_a) = t_radiated_s`` (``τ`` of ``one_way_light_time_s``).

    >>> t = uplink_arrival_t_s(0.0)
    >>> abs(t - float(one_way_light_time_s(t))) < 1e-6
    True
    """
    t_radiated = _scalar("t_radiated_s", t_radiated_s)
    arrival = t_radiated + _light_time_or(t_radiated, "t_radiated_s")
    for _ in range(_MAX_PASSES):
        following = t_radiated + _light_time_or(arrival, "t_radiated_s")
        change = abs(following - arrival)
        arrival = following
        if change < TOLERANCE_S:
            return arrival
    raise _converge("t_radiated_s")


def _light_time_or(t_s: float, name: str) -> float:
    """``one_way_light_time_s(t_s)``, an ``InputError`` naming the caller's argument."""
    try:
        return float(one_way_light_time_s(t_s))
    except InputError as err:
        raise InputError(name, err.problem) from None


def downlink_arrival_t_s(t_sent_s: float) -> float:
    """When (TT s) a signal leaving Mars' centre at ``t_sent_s`` reaches Earth's centre:
    ``t_sent_s + τ'``, ``τ' = |x_Earth(t_sent_s + τ') - x_Mars(t_sent_s)| / c``.

    >>> t = downlink_arrival_t_s(0.0)
    >>> abs((t - 0.0) - float(one_way_light_time_s(0.0))) < 0.2
    True
    """
    t_sent = _scalar("t_sent_s", t_sent_s)
    at = np.array([t_sent])
    mars = _position(_MARS, at)
    tau = float(_distance_s(_position(_EARTH, at), mars)[0])
    for _ in range(_MAX_PASSES):
        arrival = _checked("t_sent_s", at + tau)  # Earth hears it inside the ephemeris
        following = float(_distance_s(_position(_EARTH, arrival), mars)[0])
        change = abs(following - tau)
        tau = following
        if change < TOLERANCE_S:
            return t_sent + tau
    raise _converge("t_sent_s")
