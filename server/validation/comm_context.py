"""A rover's link across the light time, for validation (``sequences.comm_timing``).

When a rover's link crosses the light time (``runtime.comm.mode == "mission"``), validation
predicts when a sequence can be onboard and when a drive's results reach the ground. The
ground knows its link as a mission does: the comm plan (``sim.comm.plan``), the windows it
predicts from published ephemerides (``sim.comm.windows``) and the light time from DE421
(``sim.world.light_time``). ``rover_link`` reads the runtime's plan and its uplink queue
(under the runtime's lock, in microseconds: it runs on the event loop) as plain values,
``RoverLink``, which pickles to a validation process (``server.validation.pool``);
``RoverLink.timing`` computes there the ``CommTiming`` the walk reads:

- the windows from the validation moment to ``SEARCH_SOLS`` (10) sols after the moment the
  ground may radiate this sequence (the link's search for an uplink window) and
  ``DOWNLINK_SOLS`` (3) sols more for the drives' results; the windows are cached by sol
  (``sim.comm.windows``), so a rover's later validations cost little;
- ``uplink_from_t_s``: the uplinks already waiting on the ground go first, each radiated in
  turn as the link does (``sequences.comm_timing.radiation``; one that no window holds fails
  on the ground and blocks none); this sequence after them;
- the one-way light time both ways, sampled a quarter sol apart on a grid fixed in TT (each
  sample cached), interpolated by the walk within a few milliseconds.

Everything stays inside the ephemeris (DE421, ``sim.world.ephemeris.coverage_t_s``): near
its end the horizon is cut short, and past it there is no ``CommTiming`` (the walk's
``beyond-ephemeris`` error says why).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

from sequences.comm_timing import CommTiming, LinkWindow, radiation
from sim.comm.plan import CommPlan
from sim.comm.windows import MAX_SPAN_S, comm_windows
from sim.world.ephemeris import coverage_t_s
from sim.world.light_time import downlink_arrival_t_s, one_way_light_time_s
from sim.world.marsclock import SOL_S, get_mission

if TYPE_CHECKING:
    from server.runtime import RoverRuntime

SEARCH_SOLS = 10  # sim.comm.link.SEARCH_SOLS: how far ahead the link looks for a window
DOWNLINK_SOLS = 3  # the drives' results are predicted this far past the uplink search
LIGHT_STEP_S = SOL_S / 4.0  # the light time is sampled this often
_EDGE_S = 2.0 * SOL_S  # windows end within a sol of the span asked; light goes ~25 min back


@dataclass(frozen=True)
class RoverLink:
    """What validation needs of a rover's link, as plain values: the landing site
    (planetographic ``lat_deg``, ``lon_east_deg``), the ``plan``, the validation moment
    ``t_s``, when the link's last radiation ends (``up_t_s``) and the uplinks waiting on
    the ground (``waiting``: accepted at, bits; in order)."""

    lat_deg: float
    lon_east_deg: float
    plan: CommPlan
    t_s: float
    up_t_s: float
    waiting: tuple[tuple[float, int], ...] = ()

    def timing(self) -> CommTiming | None:
        """The ``CommTiming`` of this link (module docstring); ``None`` past the ephemeris."""
        first, last = coverage_t_s()
        limit = min(last - _EDGE_S, self.t_s + MAX_SPAN_S)
        if not first + _EDGE_S <= self.t_s <= limit:
            return None
        after = max(self.t_s, self.up_t_s)
        found = self._windows(self.t_s, min(after + SEARCH_SOLS * SOL_S, limit))
        for accepted_t_s, bits in self.waiting:  # the ground's queue goes first
            start = max(after, accepted_t_s)
            until = start + SEARCH_SOLS * SOL_S
            if until > limit:
                after = math.inf
                break
            found = self._windows(self.t_s, until)
            when = radiation(found, bits, start, until)
            if when is not None:  # one no window holds fails on the ground: the rest go on
                after = when[1]
        search_end = min(after + SEARCH_SOLS * SOL_S, limit)
        horizon = min(search_end + DOWNLINK_SOLS * SOL_S, limit)
        found = self._windows(self.t_s, horizon)
        light_end = min(horizon + self.plan.relay_latency_s + LIGHT_STEP_S, last - _EDGE_S / 2)
        times = [
            k * LIGHT_STEP_S
            for k in range(math.floor(self.t_s / LIGHT_STEP_S), math.ceil(light_end / LIGHT_STEP_S))
        ]
        samples = [_light_sample(t) for t in times]
        return CommTiming(
            uplink_from_t_s=after,
            uplink_until_t_s=search_end,
            windows=tuple(found),
            horizon_t_s=horizon,
            relay_latency_s=self.plan.relay_latency_s,
            planning_lmst_h=self.plan.planning_lmst_h,
            light_t_s=tuple(times),
            uplink_light_s=tuple(up for up, _ in samples),
            downlink_light_s=tuple(down for _, down in samples),
        )

    def _windows(self, t_from_s: float, t_to_s: float) -> list[LinkWindow]:
        return [
            LinkWindow(w.kind, w.start_t_s, w.end_t_s, w.rate_bps)
            for w in comm_windows(self.lat_deg, self.lon_east_deg, self.plan, t_from_s, t_to_s)
        ]


@functools.lru_cache(maxsize=4096)
def _light_sample(t_s: float) -> tuple[float, float]:
    """The light time that reaches Mars at ``t_s`` and the one that leaves it then, s."""
    return float(one_way_light_time_s(t_s)), downlink_arrival_t_s(t_s) - t_s


def rover_link(runtime: RoverRuntime) -> RoverLink | None:
    """The runtime's link as plain values, ``None`` when it is instant. The caller holds
    ``runtime.lock`` (``server.validation.context.rover_site``) so that the queue, the
    plan and the clock are of one moment."""
    mission = runtime.comm.mission
    if mission is None:
        return None
    link = mission.link
    site = get_mission(runtime.spec.mission)
    return RoverLink(
        site.lat_deg,
        site.lon_east_deg,
        link.plan,
        float(runtime.t_s),
        float(link.up_t_s),
        tuple((float(u.accepted_t_s), int(u.bits)) for u in link.waiting),
    )
