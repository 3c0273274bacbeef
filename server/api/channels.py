"""Telemetry at a glance (``server.channels``): the numeric channels of a rover and one
channel's values over sols, decimated."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import Query

from server.access.auth import Viewer
from server.access.truth_view import ground_channels, truth_refused
from server.api.answers import ChannelInfo, ChannelSeries
from server.api.deps import MAX_SOL, SeesTruth, ServerDep, error_doc, router
from server.channels import (
    DEFAULT_POINTS,
    MAX_POINTS,
    MAX_SOLS,
    MIN_POINTS,
    Channel,
    channel_series,
    channels_of,
    series,
)
from server.errors import NotFoundError
from server.validation.uploads import request_error
from sim.world.marsclock import t_s_for_sol_lmst

# this router's own error descriptions (a channel, not a record, may be unknown)
NOT_FOUND: dict[int | str, dict[str, Any]] = {
    404: {"description": "no such rover or channel (the answer names the known channels)"}
}
BAD_REQUEST: dict[int | str, dict[str, Any]] = {422: {"description": "the request's problems"}}

routes = router()


def known(server: ServerDep, rover: str) -> dict[str, Channel]:
    runtime = server.rover(rover)
    return channels_of(runtime.last_frame)


@routes.get("/api/rovers/{rover}/channels", response_model=list[ChannelInfo], responses=NOT_FOUND)
def list_channels(
    server: ServerDep, rover: str, _: Viewer, truth: SeesTruth
) -> list[dict[str, Any]]:
    """The numeric telemetry channels: name, unit, and whether it is scored against
    the simulator's truth (a view no real operator has; listed only in the truth view)."""
    described = [c.describe() for c in known(server, rover).values()]
    return described if truth else ground_channels(described)


@routes.get(
    "/api/rovers/{rover}/channels/{channel}",
    response_model=ChannelSeries,
    responses={**NOT_FOUND, **BAD_REQUEST, 403: error_doc("a truth channel, not for this role")},
)
def channel_values(
    server: ServerDep,
    rover: str,
    channel: str,
    _: Viewer,
    truth: SeesTruth,
    sol_from: Annotated[int | None, Query(ge=0, le=MAX_SOL)] = None,
    sol_to: Annotated[int | None, Query(ge=0, le=MAX_SOL)] = None,
    max_points: Annotated[int, Query(ge=MIN_POINTS, le=MAX_POINTS)] = DEFAULT_POINTS,
) -> dict[str, Any]:
    """One channel over sols ``sol_from``-``sol_to`` (default: the rover's sol now; at
    most MAX_SOLS sols), as ``t_s``, ``sol``, ``lmst_h`` and ``values`` arrays (null:
    no value), at most ``max_points`` long: decimated keeping each bucket's min and
    max. A truth channel is the truth view's: 403 to anyone else."""
    runtime = server.rover(rover)
    channels = known(server, rover)
    if channel in channels and channels[channel].truth and not truth:
        raise truth_refused("this channel")
    if not truth:
        channels = {name: c for name, c in channels.items() if not c.truth}
    if channel not in channels:
        raise NotFoundError(f"unknown channel {channel!r}; known: {', '.join(channels)}")
    now = runtime.sol(runtime.t_s)
    lo = now if sol_from is None else sol_from
    hi = lo if sol_to is None else sol_to
    if hi < lo:
        raise request_error(("query", "sol_to"), "sol_to: must be >= sol_from", "range")
    if hi - lo + 1 > MAX_SOLS:
        raise request_error(
            ("query", "sol_to"), f"at most {MAX_SOLS} sols at once, asked {hi - lo + 1}",
            "range",
        )  # fmt: skip
    mission = runtime.spec.mission
    t0 = t_s_for_sol_lmst(mission, lo, 0.0)
    t1 = t_s_for_sol_lmst(mission, hi + 1, 0.0)
    arrays = server.store.channel(rover, channel, t0, t1)  # its column only
    if arrays is None:  # a side estimator's figure: in each frame's JSON
        stored = server.store.frames(rover, t0, t1, with_truth=channels[channel].truth)
        frames = [f for f in stored if lo <= int(f["sol"]) <= hi]
        answer = channel_series(frames, channels[channel], max_points)
    else:
        a = arrays.where((arrays.sol >= lo) & (arrays.sol <= hi))
        answer = series(a.t_s, a.sol, a.lmst_h, a.values, channels[channel], max_points)
    return {"rover": rover, "sol_from": lo, "sol_to": hi, **answer}
