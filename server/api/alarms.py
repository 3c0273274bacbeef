"""Alarm limits per channel (``server.limits``) and the alarms they raise
(``server.alarms``): list, change, reset, acknowledge, shelve and unshelve."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import Query, Request
from pydantic import BaseModel, ConfigDict, Field

from sequences.commands import MAX_WAIT_S
from server.access.auth import Operator, Viewer
from server.access.truth_view import ground_channels, is_truth_channel, truth_refused
from server.api.answers import Alarm, Limits
from server.api.deps import (
    AUTH_ERRORS,
    BAD_REQUEST,
    NOT_FOUND,
    TOO_LARGE,
    AlarmId,
    Channel,
    RoverName,
    SeesTruth,
    ServerDep,
    error_doc,
    router,
)

LimitLevel = float | str | list[str] | None


class LimitsBody(BaseModel):
    """``PUT /api/rovers/{rover}/limits/{channel}``: a channel's levels (``server.limits``):
    numbers (numeric), a level's name (ordinal, e.g. AQF), a list of states (state), or
    null for no level; ``hysteresis`` (numeric only) in the channel's units."""

    model_config = ConfigDict(extra="forbid", strict=True)
    warning: LimitLevel = Field(description="the warning level, or null")
    critical: LimitLevel = Field(description="the critical level, or null")
    hysteresis: float | None = Field(default=None, ge=0.0, allow_inf_nan=False)


class ShelveBody(BaseModel):
    """``POST /api/alarms/{id}/shelve``: for how long of the rover's clock (up to two sols,
    the longest WAIT) and why."""

    model_config = ConfigDict(extra="forbid", strict=True)
    duration_s: float = Field(gt=0.0, le=MAX_WAIT_S, allow_inf_nan=False,
                              description="seconds of the rover's clock")  # fmt: skip
    reason: str = Field(default="", max_length=200, description="why, for the others")


routes = router()


@routes.get("/api/rovers/{rover}/limits", response_model=list[Limits], responses=NOT_FOUND)
def get_limits(
    server: ServerDep, rover: RoverName, _: Viewer, truth: SeesTruth
) -> list[dict[str, Any]]:
    """Every channel's alarm limits for the rover: kind, direction, units, truth view
    or not, why, the levels now and by default, and who last changed them (those of
    truth channels only in the truth view)."""
    server.rover(rover)
    limits = server.alarms.limits(rover)
    return limits if truth else ground_channels(limits)


TRUTH_REFUSED: dict[int | str, dict[str, Any]] = {
    403: error_doc("a truth channel's, and the caller is not in the truth view")
}


@routes.put(
    "/api/rovers/{rover}/limits/{channel}",
    response_model=Limits,
    responses={**AUTH_ERRORS, **NOT_FOUND, **TOO_LARGE, **BAD_REQUEST, **TRUTH_REFUSED},
)
def put_limits(
    server: ServerDep,
    rover: RoverName,
    channel: Channel,
    body: LimitsBody,
    request: Request,
    who: Operator,
    truth: SeesTruth,
) -> dict[str, Any]:
    """Change a channel's levels (stored; judged at once against the latest frame); a
    truth channel's only in the truth view."""
    runtime = server.rover(rover)
    if not truth and is_truth_channel(channel):
        raise truth_refused("this channel")
    levels = body.model_dump(exclude_none=False)
    if body.hysteresis is None:
        levels.pop("hysteresis")
    request.state.audit_action = f"set limits of {channel}: " + ", ".join(
        f"{k}={v}" for k, v in levels.items()
    )
    return server.alarms.set_limits(rover, channel, levels, who.name, runtime.last_frame)


@routes.delete(
    "/api/rovers/{rover}/limits/{channel}",
    response_model=Limits,
    responses={**AUTH_ERRORS, **NOT_FOUND, **TRUTH_REFUSED},
)
def reset_limits(
    server: ServerDep,
    rover: RoverName,
    channel: Channel,
    request: Request,
    _: Operator,
    truth: SeesTruth,
) -> dict[str, Any]:
    """Back to the default levels for a channel (a truth channel's: the truth view)."""
    runtime = server.rover(rover)
    if not truth and is_truth_channel(channel):
        raise truth_refused("this channel")
    request.state.audit_action = f"reset limits of {channel} to the defaults"
    return server.alarms.reset_limits(rover, channel, runtime.last_frame)


@routes.get(
    "/api/rovers/{rover}/alarms", response_model=list[Alarm], responses={**NOT_FOUND, **BAD_REQUEST}
)
def list_alarms(
    server: ServerDep,
    rover: RoverName,
    _: Viewer,
    truth: SeesTruth,
    active: Annotated[
        bool | None,
        Query(
            description="true: still listed (not both acknowledged and cleared); "
            "false: done; absent: all"
        ),
    ] = None,
    limit: Annotated[int, Query(ge=1, le=10_000)] = 500,
) -> list[dict[str, Any]]:
    """A rover's alarms, newest first (those of truth channels in the truth view only)."""
    server.rover(rover)
    return server.alarms.listed(rover, active, limit, truth)


@routes.post(
    "/api/alarms/{alarm_id}/acknowledge",
    response_model=Alarm,
    responses={**AUTH_ERRORS, **NOT_FOUND, **TRUTH_REFUSED, 409: error_doc("acknowledged already")},
)
def acknowledge_alarm(
    server: ServerDep, alarm_id: AlarmId, request: Request, who: Operator, truth: SeesTruth
) -> dict[str, Any]:
    """Acknowledge an alarm (who and when are kept; it leaves the list once cleared); an
    alarm of a truth channel only in the truth view."""
    request.state.audit_action = f"acknowledge alarm #{alarm_id}"
    if not truth and server.alarms.truth_alarm(alarm_id):
        raise truth_refused(f"alarm #{alarm_id}")
    alarm = server.alarms.acknowledge(alarm_id, who.name)
    request.state.audit_rover = alarm["rover"]
    request.state.audit_action = f"acknowledge alarm #{alarm_id} ({alarm['channel']})"
    return alarm


@routes.post(
    "/api/alarms/{alarm_id}/shelve", response_model=Alarm,
    responses={**AUTH_ERRORS, **NOT_FOUND, **TOO_LARGE, **BAD_REQUEST,
               409: error_doc("done: acknowledged and cleared")},
)  # fmt: skip
def shelve_alarm(
    server: ServerDep, alarm_id: AlarmId, body: ShelveBody, request: Request, who: Operator
) -> dict[str, Any]:
    """Shelve a listed alarm for a while of the rover's clock: neither raised again nor
    escalated until then (its latest value and a clear still count)."""
    request.state.audit_action = f"shelve alarm #{alarm_id} for {body.duration_s:g} s"
    found = server.store.alarms(alarm_id=alarm_id)
    runtime = server.rovers.get(found[0]["rover"]) if found else None
    frame = runtime.last_frame if runtime is not None else None
    now_t_s = float(frame["t_s"]) if frame else None
    alarm = server.alarms.shelve(alarm_id, body.duration_s, who.name, body.reason, now_t_s)
    request.state.audit_rover = alarm["rover"]
    request.state.audit_action = (
        f"shelve alarm #{alarm_id} ({alarm['channel']}) for {body.duration_s:g} s"
        + (f": {body.reason}" if body.reason else "")
    )
    return alarm


@routes.post(
    "/api/alarms/{alarm_id}/unshelve",
    response_model=Alarm,
    responses={**AUTH_ERRORS, **NOT_FOUND, 409: error_doc("not shelved, or done")},
)
def unshelve_alarm(
    server: ServerDep, alarm_id: AlarmId, request: Request, who: Operator
) -> dict[str, Any]:
    """End a shelf before its time: the alarm is judged again from the next frame."""
    request.state.audit_action = f"unshelve alarm #{alarm_id}"
    alarm = server.alarms.unshelve(alarm_id, who.name)
    request.state.audit_rover = alarm["rover"]
    request.state.audit_action = f"unshelve alarm #{alarm_id} ({alarm['channel']})"
    return alarm
