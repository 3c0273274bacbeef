"""When a rover's links are up, as the ground predicts them from published ephemerides.

Three kinds of window (``WindowKind``), each at the rate its plan gives (``CommPlan``,
``sim.comm.plan``):

- ``relay``: the relay orbiter above ``plan.relay_mask_deg`` at the site. The orbit is the
  Keplerian one of ``sim.sensors.orbiter`` (Mars Odyssey's mapping orbit, approximately,
  its elements at ``ORBIT_EPOCH``: the same orbit as ``sim.loop.side.radio``'s), seen
  from the site on the IAU/IAG ellipsoid
  (``sim.world.mars_frames``). This near-polar orbit 400 km up passes a MER site 1 to 4
  times a sol (2 or 3 mostly), up to 12 minutes above 10°; a pass that climbs a degree or
  two over the mask lasts a few minutes or less.
- ``uplink`` and ``dte``: the high-gain antenna's sessions, from ``plan.uplink_lmst_h``
  (``plan.dte_lmst_h``) of each sol for ``plan.uplink_minutes`` (``plan.dte_minutes``),
  while Earth stands at least ``plan.earth_min_elev_deg`` high (DE421 with light time and
  aberration, ``sim.world.mars_frames.earth_ll_truth``). A session can be cut short, split
  or lost on a sol when Earth is low.

Sols here are the site's own: they turn at local mean midnight (LMST 00:00, Mars24's C-2
and C-3 of Allison and McEwen 2000, ``sim.world.marsclock``) at the site's West longitude
``(360 - lon_east_deg) % 360``.

How: the orbiter's elevation is sampled every ``RELAY_STEP_S`` (20 s) on a grid fixed in
TT (multiples of 20 s since J2000, so neighbouring sols see the same samples) and each
crossing of the mask is refined by bisection, vectorised over the sol's crossings, to
``RELAY_EDGE_S``; the peak is refined on a 0.25 s grid about the highest sample with a
parabola. Earth's elevation is sampled every ``EARTH_STEP_S`` across each session and its
crossings bisected to ``EARTH_EDGE_S``. A refined edge is the inside end of its last
bracket, so the link is up at both edges of a window. A pass or a dip shorter than a
sample step can be missed (a pass that peaks less than about 0.01° over the mask: under
20 s). Each sol's windows are computed once per site and plan
(``functools.lru_cache`` on the sol's index): the runtime asks every few seconds.

Times are TT seconds since J2000 (``t_s``); the site's latitude is planetographic, its
longitude East, in degrees (the edges of a ``Mission``, ``sim.world.marsclock``).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from sim.comm.plan import CommPlan
from sim.errors import InputError
from sim.sensors.orbiter import ORBIT_EPOCH, KeplerOrbit, RelayOrbiter
from sim.world.ephemeris import check_t_s
from sim.world.mars_frames import earth_ll_truth, elevation_rad, site_mf_m
from sim.world.marsclock import SOL_S, msd_from_t_s, utc_to_t_s

FloatArray = NDArray[np.float64]
WindowKind = Literal["uplink", "relay", "dte"]
Span = tuple[float, float, float]  # start_t_s, end_t_s, peak_elev_deg

RELAY_STEP_S = 20.0  # the orbiter's elevation is sampled this often (TT grid from J2000)
RELAY_EDGE_S = RELAY_STEP_S / 2**10  # bisected to ~0.02 s: ~0.005° of elevation at 10°
RELAY_PAD_S = 3_600.0  # a pass rising in a sol is followed this far past its end
EARTH_STEP_S = 60.0  # Earth's elevation (at most 0.004°/s) is sampled this often
EARTH_EDGE_S = EARTH_STEP_S / 2**10  # bisected to ~0.06 s
PEAK_HALF_SPAN_S = 20.0  # the peak's fine grid spans the highest sample's neighbours
PEAK_STEP_S = 0.25
MAX_SPAN_S = 100.0 * SOL_S  # the longest stretch one call may ask about
_CACHED_SOLS = 1024  # per kind: several rovers' few sols, several plans


@dataclass(frozen=True)
class Window:
    """One window of a link: TT seconds since J2000, its rate, its highest elevation."""

    kind: WindowKind
    start_t_s: float
    end_t_s: float
    rate_bps: float  # uplink: plan.uplink_rate_bps; relay: plan.relay_rate_bps; dte: ...
    peak_elev_deg: float  # the orbiter's (relay) or Earth's (uplink, dte) highest in it

    @property
    def duration_s(self) -> float:
        """``end_t_s - start_t_s``."""
        return self.end_t_s - self.start_t_s

    @property
    def capacity_mbit(self) -> float:
        """What the window can carry at its rate: ``rate_bps * duration_s / 1e6``."""
        return self.rate_bps * self.duration_s / 1.0e6

    def as_json(self) -> dict[str, object]:
        """``kind``, ``start_t_s``, ``end_t_s``, ``minutes``, ``rate_bps``,
        ``peak_elev_deg`` and ``capacity_mbit``: plain JSON."""
        return {
            "kind": self.kind,
            "start_t_s": self.start_t_s,
            "end_t_s": self.end_t_s,
            "minutes": self.duration_s / 60.0,
            "rate_bps": self.rate_bps,
            "peak_elev_deg": self.peak_elev_deg,
            "capacity_mbit": self.capacity_mbit,
        }


def comm_windows(
    lat_deg: float, lon_east_deg: float, plan: CommPlan, t_from_s: float, t_to_s: float
) -> list[Window]:
    """Every window of ``plan`` at the site that overlaps ``[t_from_s, t_to_s]``, whole (a
    window in progress at ``t_from_s`` from its true start), sorted by start then kind.

    ``lat_deg`` planetographic, ``lon_east_deg`` East; times TT seconds since J2000, the
    span at most ``MAX_SPAN_S``. Bad arguments raise ``InputError`` naming them.
    """
    lat, lon_east = _site(lat_deg, lon_east_deg)
    if not isinstance(plan, CommPlan):
        raise InputError("plan", f"must be a CommPlan, got {type(plan).__name__}")
    t_from = _time("t_from_s", t_from_s)
    t_to = _time("t_to_s", t_to_s)
    if t_to < t_from:
        raise InputError("t_to_s", f"must not be before t_from_s ({t_from!r}), got {t_to!r}")
    if t_to - t_from > MAX_SPAN_S:
        raise InputError("t_to_s", f"at most {MAX_SPAN_S:.0f} s (100 sols) after t_from_s")
    lon_west = (360.0 - lon_east) % 360.0
    found: list[Window] = []
    # a window opens in its sol and lasts less than a sol: start from the sol before
    for sol in range(sol_index(t_from, lon_west) - 1, sol_index(t_to, lon_west) + 1):
        for span in _relay_passes(sol, lat, lon_east, plan.relay_mask_deg):
            found.append(Window("relay", *span[:2], plan.relay_rate_bps, span[2]))
        hga: tuple[tuple[WindowKind, float, float, float], ...] = (
            ("uplink", plan.uplink_lmst_h, plan.uplink_minutes, plan.uplink_rate_bps),
            ("dte", plan.dte_lmst_h, plan.dte_minutes, plan.dte_rate_bps),
        )
        for kind, lmst_h, minutes, rate_bps in hga:
            spans = _earth_windows(sol, lat, lon_east, lmst_h, minutes, plan.earth_min_elev_deg)
            found += [Window(kind, s[0], s[1], rate_bps, s[2]) for s in spans]
    inside = [w for w in found if w.start_t_s <= t_to and w.end_t_s >= t_from]
    return sorted(inside, key=lambda w: (w.start_t_s, w.kind))


def sol_index(t_s: float, lon_west_deg: float) -> int:
    """The site's local sol at ``t_s``: the whole part of its local mean solar date
    (Mars Sol Date less ``Λ/360``, C-2 and C-3), so it turns at LMST 00:00 there."""
    return math.floor(float(msd_from_t_s(t_s)) - lon_west_deg / 360.0)


def sol_start_t_s(sol: int, lon_west_deg: float) -> float:
    """``t_s`` of LMST 00:00 opening local sol ``sol`` at West longitude ``lon_west_deg``
    (``sol_index`` inverted: the Mars Sol Date runs at one a ``SOL_S``)."""
    return (sol + lon_west_deg / 360.0 - float(msd_from_t_s(0.0))) * SOL_S


# ---- the orbiter --------------------------------------------------------------------------


@functools.cache
def _orbiter() -> RelayOrbiter:
    """The relay orbiter as published: the elements of ``sim.sensors.orbiter`` at
    ``ORBIT_EPOCH`` (the same as ``sim.loop.side.radio``'s)."""
    return RelayOrbiter(KeplerOrbit(epoch_t_s=utc_to_t_s(ORBIT_EPOCH)))


def _relay_elev_deg(t_s: FloatArray, lat_deg: float, lon_east_deg: float) -> FloatArray:
    lat, lon = math.radians(lat_deg), math.radians(lon_east_deg)
    return _orbiter().elevation_deg(t_s, site_mf_m(lat, lon), lat, lon)


@functools.lru_cache(maxsize=_CACHED_SOLS)
def _relay_passes(
    sol: int, lat_deg: float, lon_east_deg: float, mask_deg: float
) -> tuple[Span, ...]:
    """The passes that rise in local sol ``sol``: (rise, set, peak elevation), rise order.

    A pass belongs to the sol holding the last sample before it rose, on the fixed TT grid,
    so each pass belongs to exactly one sol."""
    lon_west = (360.0 - lon_east_deg) % 360.0
    first = math.ceil(sol_start_t_s(sol, lon_west) / RELAY_STEP_S)
    end = math.ceil(sol_start_t_s(sol + 1, lon_west) / RELAY_STEP_S)
    last = end + math.ceil(RELAY_PAD_S / RELAY_STEP_S)
    t: FloatArray = np.arange(first, last + 1, dtype=np.float64) * RELAY_STEP_S
    elev = _relay_elev_deg(t, lat_deg, lon_east_deg)
    up = elev > mask_deg
    rises = np.flatnonzero(~up[:-1] & up[1:])
    rises = rises[rises < end - first]  # the sample before the rise is in this sol
    sets = np.flatnonzero(up[:-1] & ~up[1:])
    after = np.searchsorted(sets, rises)  # the first set after each rise
    if np.any(after >= sets.size):  # a pass outlasting the pad: not this orbit's
        raise InputError("relay_mask_deg", f"a pass of sol {sol} lasts over {RELAY_PAD_S} s")
    sets = sets[after]

    def above(times: FloatArray) -> NDArray[np.bool_]:
        return _relay_elev_deg(times, lat_deg, lon_east_deg) > mask_deg

    rise_t = _edge(above, t[rises + 1], t[rises], RELAY_EDGE_S)
    set_t = _edge(above, t[sets], t[sets + 1], RELAY_EDGE_S)
    peaks = []
    for r, s in zip(rises, sets, strict=True):
        peaks.append(float(t[r + 1 + np.argmax(elev[r + 1 : s + 1])]))
    peak_elev = _peak_elev_deg(np.array(peaks), lat_deg, lon_east_deg)
    return tuple(
        (float(a), float(b), float(p)) for a, b, p in zip(rise_t, set_t, peak_elev, strict=True)
    )


def _peak_elev_deg(t_peak_s: FloatArray, lat_deg: float, lon_east_deg: float) -> FloatArray:
    """The highest elevation near each sample ``t_peak_s``: a 0.25 s grid over its
    neighbours, and a parabola through the grid's top three points."""
    if t_peak_s.size == 0:
        return np.zeros(0)
    offsets = np.arange(-PEAK_HALF_SPAN_S, PEAK_HALF_SPAN_S + PEAK_STEP_S / 2, PEAK_STEP_S)
    elev = _relay_elev_deg(t_peak_s[:, None] + offsets, lat_deg, lon_east_deg)
    top = np.clip(np.argmax(elev, axis=1), 1, offsets.size - 2)
    rows = np.arange(elev.shape[0])
    left, mid, right = elev[rows, top - 1], elev[rows, top], elev[rows, top + 1]
    curvature = left - 2.0 * mid + right
    safe = np.where(curvature < 0.0, curvature, -1.0)
    vertex = np.where(curvature < 0.0, mid - (right - left) ** 2 / (8.0 * safe), mid)
    out: FloatArray = np.maximum(vertex, elev.max(axis=1))
    return out


# ---- Earth ----------------------------------------------------------------------------------


def _earth_elev_deg(t_s: FloatArray, lat_deg: float, lon_east_deg: float) -> FloatArray:
    v_ll = earth_ll_truth(t_s, math.radians(lat_deg), math.radians(lon_east_deg))
    return np.degrees(elevation_rad(v_ll))


@functools.lru_cache(maxsize=_CACHED_SOLS)
def _earth_windows(
    sol: int, lat_deg: float, lon_east_deg: float, lmst_h: float, minutes: float, min_deg: float
) -> tuple[Span, ...]:
    """The parts of local sol ``sol``'s session (``lmst_h`` for ``minutes``) with Earth at
    least ``min_deg`` high: (start, end, Earth's highest elevation), in order."""
    lon_west = (360.0 - lon_east_deg) % 360.0
    opens = sol_start_t_s(sol, lon_west) + lmst_h / 24.0 * SOL_S
    closes = opens + minutes * 60.0
    t = np.linspace(opens, closes, math.ceil((closes - opens) / EARTH_STEP_S) + 1)
    elev = _earth_elev_deg(check_t_s(t), lat_deg, lon_east_deg)
    up = elev >= min_deg
    if not np.any(up):
        return ()
    # runs of samples with Earth up: [begin, stop) each
    edges = np.flatnonzero(np.diff(np.concatenate(([0], up.astype(np.int8), [0]))))
    begins, stops = edges[0::2], edges[1::2]

    def above(times: FloatArray) -> NDArray[np.bool_]:
        return _earth_elev_deg(times, lat_deg, lon_east_deg) >= min_deg

    starts = t[begins].copy()
    rising = begins > 0  # Earth came up inside the session: refine, else it opens it
    starts[rising] = _edge(above, t[begins[rising]], t[begins[rising] - 1], EARTH_EDGE_S)
    ends = t[stops - 1].copy()
    setting = stops < t.size
    ends[setting] = _edge(above, t[stops[setting] - 1], t[stops[setting]], EARTH_EDGE_S)
    peaks = [float(elev[b:s].max()) for b, s in zip(begins, stops, strict=True)]
    return tuple((float(a), float(b), p) for a, b, p in zip(starts, ends, peaks, strict=True))


# ---- shared -------------------------------------------------------------------------------


def _edge(
    above: Callable[[FloatArray], NDArray[np.bool_]],
    t_in_s: FloatArray,
    t_out_s: FloatArray,
    tolerance_s: float,
) -> FloatArray:
    """Bisect each bracket (``above`` true at ``t_in_s``, false at ``t_out_s``) until it is
    within ``tolerance_s``, all brackets at once; the inside ends, where ``above`` holds."""
    inside = np.asarray(t_in_s, dtype=np.float64).copy()
    outside = np.asarray(t_out_s, dtype=np.float64).copy()
    if inside.size == 0:
        return inside
    while np.max(np.abs(inside - outside)) > tolerance_s:
        mid = 0.5 * (inside + outside)
        holds = above(mid)
        inside = np.where(holds, mid, inside)
        outside = np.where(holds, outside, mid)
    return inside


def _site(lat_deg: float, lon_east_deg: float) -> tuple[float, float]:
    lat = _number("lat_deg", lat_deg)
    if not -90.0 <= lat <= 90.0:
        raise InputError("lat_deg", f"must be in [-90, 90], got {lat_deg!r}")
    return lat, _number("lon_east_deg", lon_east_deg) % 360.0


def _time(name: str, t_s: float) -> float:
    value = _number(name, t_s)
    try:
        check_t_s(value)
    except InputError as err:
        raise InputError(name, err.problem) from None
    return value


def _number(name: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float | np.floating):
        raise InputError(name, f"must be a number, got {value!r}")
    out = float(value)
    if not math.isfinite(out):
        raise InputError(name, f"must be finite, got {value!r}")
    return out
