"""The Earth-Mars light time computed a second way, to check ``sim.world.light_time``.

The simulator solves its three light-time equations by fixed-point iteration over its own
reading of DE421 (``sim.world.ephemeris``). Here the same equations are solved with a
bracketing root finder (``scipy.optimize.brentq``) over a reading of the kernel of this
module's own: the ``de421.bsp`` of the ``skyfield-data`` package opened again with
``jplephem``, the positions of Earth (SSB -> Earth-Moon barycentre -> Earth) and of Mars
(SSB -> Mars barycentre -> Mars) summed from the kernel's segments here, the epoch split in
a whole Julian date and its fraction. DE421: Folkner, Williams and Boggs 2008.

The equations (times TT seconds since J2000, used as TDB; ``c`` exact):

- one way, the light reaching Mars at ``t``: ``c τ = |x_Mars(t) - x_Earth(t - τ)|``;
- uplink, radiated at ``t_r``: arrival ``t_a`` with ``c (t_a - t_r) = |x_Mars(t_a) -
  x_Earth(t_r)|``;
- downlink, sent at ``t_s``: arrival ``t_a`` with ``c (t_a - t_s) = |x_Earth(t_a) -
  x_Mars(t_s)|``;
- and back from Earth: the light received at ``t_a`` left Mars at ``t_e`` with
  ``c (t_a - t_e) = |x_Earth(t_a) - x_Mars(t_e)|`` (``emitted_t_s``: what arrives at
  ``t_a`` was made no later than this).

Each is a root of a function that is monotonic in the unknown (the bodies move at 1e-4
of ``c``), bracketed between 100 s and 1,500 s of light (Earth-Mars is 182-1,342 s).
"""

from __future__ import annotations

import functools
import itertools
from datetime import UTC, datetime
from typing import Any

import numpy as np
from jplephem.spk import SPK
from scipy.optimize import brentq

from sim.world.ephemeris import de421_path
from sim.world.light_time import (
    downlink_arrival_t_s,
    one_way_light_time_s,
    uplink_arrival_t_s,
)
from sim.world.marsclock import utc_to_t_s

C_KM_S = 299_792.458  # speed of light, exact (SI definition of the metre)
JD_J2000 = 2_451_545.0  # the Julian date of J2000 (TT)
DAY_S = 86_400.0
BRACKET_S = (100.0, 1_500.0)  # every Earth-Mars light time lies inside
XTOL_S = 1e-9  # brentq's tolerance on the light time
EARTH_CHAIN = ((0, 3), (3, 399))  # NAIF: SSB -> Earth-Moon barycentre -> Earth
MARS_CHAIN = ((0, 4), (4, 499))  # SSB -> Mars barycentre -> Mars
SPAN_UTC = (datetime(2004, 1, 1, tzinfo=UTC), datetime(2030, 12, 31, tzinfo=UTC))
SAMPLES = 50
SEED = 23


@functools.lru_cache(maxsize=1)
def _kernel() -> Any:
    return SPK.open(str(de421_path()))


def _position_km(chain: tuple[tuple[int, int], ...], t_s: float) -> np.ndarray:
    """Barycentric position (km, ICRF) of the body at the end of ``chain`` at ``t_s``."""
    days = t_s / DAY_S
    whole = float(np.floor(days))
    out = np.zeros(3)
    for center, target in chain:
        out += np.asarray(_kernel()[center, target].compute(JD_J2000 + whole, days - whole))
    return out


def _earth(t_s: float) -> np.ndarray:
    return _position_km(EARTH_CHAIN, t_s)


def _mars(t_s: float) -> np.ndarray:
    return _position_km(MARS_CHAIN, t_s)


def _root(f: Any) -> float:
    root: float = brentq(f, *BRACKET_S, xtol=XTOL_S)
    return root


def one_way_s(t_s: float) -> float:
    """τ of the light reaching Mars' centre at ``t_s`` from Earth's (module docstring)."""
    mars = _mars(t_s)
    return _root(lambda tau: C_KM_S * tau - float(np.linalg.norm(mars - _earth(t_s - tau))))


def uplink_s(t_radiated_s: float) -> float:
    """The light time of a signal radiated from Earth's centre at ``t_radiated_s`` to Mars'
    centre: it arrives ``t_radiated_s`` plus this."""
    earth = _earth(t_radiated_s)
    return _root(
        lambda tau: C_KM_S * tau - float(np.linalg.norm(_mars(t_radiated_s + tau) - earth))
    )


def downlink_s(t_sent_s: float) -> float:
    """The light time of a signal leaving Mars' centre at ``t_sent_s`` to Earth's centre."""
    mars = _mars(t_sent_s)
    return _root(lambda tau: C_KM_S * tau - float(np.linalg.norm(_earth(t_sent_s + tau) - mars)))


def emitted_t_s(t_received_s: float) -> float:
    """When the light that reaches Earth's centre at ``t_received_s`` left Mars' centre:
    anything received then was sent (so made) no later."""
    earth = _earth(t_received_s)
    tau = _root(lambda tau: C_KM_S * tau - float(np.linalg.norm(earth - _mars(t_received_s - tau))))
    return t_received_s - tau


def sample_times_s(samples: int = SAMPLES, seed: int = SEED) -> list[float]:
    """``samples`` times over ``SPAN_UTC``: one drawn at random in each of as many equal
    stretches (every phase of the synodic cycle, conjunctions and oppositions alike)."""
    first, last = (utc_to_t_s(u) for u in SPAN_UTC)
    edges = np.linspace(first, last, samples + 1)
    rng = np.random.default_rng(seed)
    return [float(rng.uniform(a, b)) for a, b in itertools.pairwise(edges)]


def light_time_metrics(samples: int = SAMPLES, seed: int = SEED) -> dict[str, float]:
    """The simulator's light times against this module's at ``sample_times_s``: the worst
    difference of each, s; and the span of one-way light times met."""
    times = sample_times_s(samples, seed)
    ours = np.asarray(one_way_light_time_s(np.asarray(times)), dtype=float)
    theirs = np.array([one_way_s(t) for t in times])
    # the simulator's arrival times less the departure: its light times, to the float
    # resolution of a time of 1e8-1e9 s (3e-8 to 1.2e-7 s)
    up = [abs((uplink_arrival_t_s(t) - t) - uplink_s(t)) for t in times]
    down = [abs((downlink_arrival_t_s(t) - t) - downlink_s(t)) for t in times]
    return {
        "owlt_samples": len(times),
        "owlt_max_error_s": float(np.max(np.abs(ours - theirs))),
        "uplink_arrival_max_error_s": max(up),
        "downlink_arrival_max_error_s": max(down),
        "owlt_min_s": float(theirs.min()),
        "owlt_max_s": float(theirs.max()),
    }
