"""A rehearsal's inputs from what the ground knows (issue 25, "the honesty rule").

``rehearsal_inputs`` builds ``sim.rehearsal.inputs.RehearsalInputs`` over plain arguments
only: the rover's last downlink record that came down (``sim.loop.downlink.DownlinkDict``),
what its events reported of its onboard tables (``server.validation.reported.ReportedState``:
NATE parameters, keep-out zones, mobility fault), its spec (site, mission) and the ground's
terrain map (``server.terrain.ground_map.GroundMap``), cropped to ``CROP_HALF_M`` around the
rover's reported position so that the inputs a campaign pickles to every Dask worker stay
small. The VO rig is the one a reported ``vo.rig`` parameter names, else 256.

Two thin adapters fill those arguments:

- ``runtime_inputs``: a server's rover, read under ``runtime.lock`` as validation reads it
  (``server.validation.context.rover_site``): ``runtime.last_frame``, the newest downlink
  record played out; across light time it is the newest that reached the ground
  (``server.comm``: the runtime publishes a downlink only when it comes down), so a
  rehearsal starts from the last state that came down. The map is the rover's ground map
  (``server.terrain.feed.ground_feed``: the one the 3D view and the VO advisor read),
  caught up with the stereo pairs stored so far.
- ``stored_inputs``: a database without a server (``roverops rehearse --db``): the last
  stored downlink record, the events stored up to it, and the map rebuilt from the stored
  pairs (``server.terrain.feed.GroundFeed`` over a new ``GroundMapService``).

Never the live session, and never a checkpoint: both hold the truth.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from server.rovers import ROVERS, RoverSpec
from server.terrain.feed import GROUND_HALF_M, GroundFeed, ground_feed
from server.terrain.ground_map import GroundMap
from server.terrain.service import GroundMapService
from server.validation.reported import ReportedState
from sim.rehearsal.inputs import GroundMapData, Priors, RehearsalInputs, ReportedStart

if TYPE_CHECKING:
    from server.runtime import RoverRuntime
    from server.storage.store import Store

CROP_HALF_M = 40.0  # the map sent to the workers: this far around the rover, m
VO_RIGS = (256, 1024)
VO_RIG_PARAM = "vo.rig"  # SET_PARAM's name of the VO pairs' width (docs/sequences.md)
# Where a server places a rover's start (``sim.loop.rover_sim.RoverSim``'s default
# placement, which ``server.runtime.RoverRuntime`` keeps): the landing the mission localised,
# around which its ground map is made (``server.terrain.feed.ground_feed``).
LANDING_NE_M = (0.0, 0.0)


class NoReportError(ValueError):
    """The ground has no downlink record of the rover yet: nothing to start from."""


def reported_vo_rig(params: Mapping[str, float]) -> int:
    """The VO rig a reported ``vo.rig`` parameter names (256 or 1024), else 256."""
    value = params.get(VO_RIG_PARAM)
    if value is not None and math.isfinite(value) and int(value) in VO_RIGS:
        return int(value)
    return 256


def crop_map(ground_map: GroundMap, north_m: float, east_m: float, half_m: float) -> GroundMapData:
    """The cells of ``ground_map`` within ``half_m`` (a square) of (``north_m``, ``east_m``)
    (mission frame) as ``GroundMapData``; at least 2 x 2 cells, taken at the map's nearest
    edge when the point lies outside it. Copies: the worker's arrays share nothing."""
    if not (math.isfinite(half_m) and half_m > 0.0):
        raise ValueError(f"half_m: must be positive, got {half_m!r}")
    ny, nx = ground_map.shape
    reach = half_m / ground_map.cell_m
    i, j = ground_map.cell_of(np.float64(north_m), np.float64(east_m))

    def span(centre: float, n: int) -> tuple[int, int]:
        lo = int(np.clip(math.floor(centre - reach), 0, n - 2))
        hi = int(np.clip(math.ceil(centre + reach) + 1, lo + 2, n))
        return lo, hi

    i0, i1 = span(float(i), ny)
    j0, j1 = span(float(j), nx)
    cut = (slice(i0, i1), slice(j0, j1))
    return GroundMapData(
        north0_m=float(ground_map.north0_m + i0 * ground_map.cell_m),
        east0_m=float(ground_map.east0_m + j0 * ground_map.cell_m),
        cell_m=float(ground_map.cell_m),
        height_m=np.array(ground_map.height_m[cut], dtype=np.float64),
        sigma_m=np.array(ground_map.sigma_m[cut], dtype=np.float64),
        albedo=np.array(ground_map.albedo[cut], dtype=np.float64),
        imaged=np.array(ground_map.imaged[cut], dtype=np.bool_),
    )


def rehearsal_inputs(
    frame: Mapping[str, Any] | None,
    reported: ReportedState,
    spec: RoverSpec,
    ground_map: GroundMap,
    sequence_text: str,
    priors: Priors | None = None,
    crop_half_m: float = CROP_HALF_M,
) -> RehearsalInputs:
    """The inputs of a rehearsal of ``sequence_text`` (module docstring): from ``frame``
    (the last downlink record that came down; ``NoReportError`` if ``None``), ``reported``,
    ``spec`` and ``ground_map`` alone."""
    if frame is None:
        raise NoReportError(f"no downlink record of {spec.name} on the ground yet")
    params = {k: float(v) for k, v in sorted(reported.params.items())}
    zones = tuple(reported.zones[name] for name in sorted(reported.zones))
    start = ReportedStart.from_downlink(
        frame, spec.site, spec.mission, keepout_zones=zones, params=params,
        mobility_fault=reported.mobility_fault, vo_rig=reported_vo_rig(params),
    )  # fmt: skip
    north_m, east_m = start.p_mission_est[0], start.p_mission_est[1]
    return RehearsalInputs(
        start=start,
        ground_map=crop_map(ground_map, north_m, east_m, crop_half_m),
        sequence_text=sequence_text,
        priors=priors or Priors(),
    )


def _copied(reported: ReportedState) -> ReportedState:
    copy = ReportedState()
    copy.params = dict(reported.params)
    copy.zones = dict(reported.zones)
    copy.mobility_fault = reported.mobility_fault
    return copy


def runtime_inputs(
    runtime: RoverRuntime, store: Store, sequence_text: str, priors: Priors | None = None
) -> RehearsalInputs:
    """``rehearsal_inputs`` of a server's rover (module docstring): its last played-out
    downlink record and reported state read together under its lock, and its ground map
    caught up with the pairs stored (a dense-stereo solve per new pair: call it off the
    event loop)."""
    with runtime.lock:
        frame = runtime.last_frame  # a played-out record is never changed: no copy needed
        reported = _copied(runtime.reported)
    feed = ground_feed(runtime, store)
    feed.catch_up()
    return rehearsal_inputs(frame, reported, runtime.spec, feed.service.ground_map(),
                            sequence_text, priors)  # fmt: skip


def stored_ground_map(store: Store, spec: RoverSpec) -> GroundMap:
    """The rover's ground map rebuilt from the pairs stored in ``store``: the map a server
    restarted on that database builds (``server.terrain.feed``)."""
    service = GroundMapService(spec.site, spec.seed, *LANDING_NE_M, half_m=GROUND_HALF_M)
    GroundFeed(service, store, spec.name).catch_up()
    return service.ground_map()


def stored_inputs(
    store: Store, rover: str, sequence_text: str, priors: Priors | None = None
) -> RehearsalInputs:
    """``rehearsal_inputs`` of ``rover`` from a database alone (module docstring): its last
    stored downlink record, the events stored up to it, the map of its stored pairs.
    ``KeyError`` for a rover no server hosts, ``NoReportError`` without a stored frame."""
    spec = ROVERS[rover]
    frame = store.last_frame(rover)
    if frame is None:
        raise NoReportError(f"no downlink record of {rover} in the database: has a server run?")
    reported = ReportedState()
    reported.note(store.events(rover, -math.inf, float(frame["t_s"])))
    return rehearsal_inputs(frame, reported, spec, stored_ground_map(store, spec),
                            sequence_text, priors)  # fmt: skip
