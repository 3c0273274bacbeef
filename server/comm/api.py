"""The comm routes: a rover's link as the ground sees it, its mode and its plan.

``GET /api/rovers/{rover}/comm`` (viewer): ``server.comm.view``. ``PUT .../comm/mode``
(admin: it changes how the whole console works) and ``PUT .../comm/plan`` (operator: the
windows a team plans against) are audited, and checkpointed before they answer.
"""

from __future__ import annotations

from typing import Any, Literal

from fastapi import Query, Request
from fastapi.concurrency import run_in_threadpool
from pydantic import BaseModel, ConfigDict, Field

from server.access.auth import Admin, Operator, Viewer
from server.api.deps import (
    AUTH_ERRORS,
    BAD_REQUEST,
    NOT_FOUND,
    TOO_LARGE,
    RoverName,
    ServerDep,
    router,
)
from server.comm.answers import CommState
from server.comm.view import MAX_SPAN_S, comm_json
from server.errors import InvalidError
from sim.errors import InputError


class ModeBody(BaseModel):
    """``PUT .../comm/mode``: ``instant`` (everything at once) or ``mission`` (light time)."""

    model_config = ConfigDict(extra="forbid", strict=True)
    mode: Literal["instant", "mission"]


def _hours(text: str) -> Any:
    return Field(default=None, allow_inf_nan=False, description=text)


class PlanBody(BaseModel):
    """``PUT .../comm/plan``: the fields to change (``sim.comm.plan.CommPlan``, its ranges
    checked there); absent ones keep their values."""

    model_config = ConfigDict(extra="forbid", strict=True)
    uplink_lmst_h: float | None = _hours("the morning uplink window opens (LMST, hours)")
    uplink_minutes: float | None = _hours("its length")
    uplink_rate_bps: float | None = _hours("its rate")
    dte_lmst_h: float | None = _hours("the direct-to-Earth session opens (LMST, hours)")
    dte_minutes: float | None = _hours("its length")
    dte_rate_bps: float | None = _hours("its rate")
    earth_min_elev_deg: float | None = _hours("Earth at least this high for the HGA")
    relay_mask_deg: float | None = _hours("the orbiter in view above this elevation")
    relay_rate_bps: float | None = _hours("a relay pass's rate")
    relay_latency_s: float | None = _hours("the orbiter's store-and-forward delay")
    store_capacity_mbit: float | None = _hours("the onboard store's capacity")
    decimate_s: float | None = _hours("one decimated frame per this many seconds")
    planning_lmst_h: float | None = _hours("a drive's results due on the ground (LMST)")


class PlanError(InvalidError):
    """A plan field out of its range, or a span of windows too long (HTTP 422 naming it)."""

    def __init__(self, message: str, loc: tuple[str | int, ...] = ("query",)) -> None:
        super().__init__(message)
        self.loc = loc


routes = router()


@routes.get("/api/rovers/{rover}/comm", response_model=CommState, responses=NOT_FOUND)
def rover_comm(
    server: ServerDep,
    rover: RoverName,
    _: Viewer,
    from_t_s: float | None = Query(default=None, allow_inf_nan=False, description="windows from"),
    to_t_s: float | None = Query(default=None, allow_inf_nan=False, description="windows to"),
) -> dict[str, Any]:
    """The rover's link as the ground knows it: mode, plan, light time now, the windows
    (past ones with what they brought down), what waits to go up, the onboard store as
    last reported, and the newest data's time and age."""
    runtime = server.rover(rover)
    if from_t_s is not None and to_t_s is not None and not 0.0 <= to_t_s - from_t_s <= MAX_SPAN_S:
        raise PlanError(f"to_t_s - from_t_s must be in [0, {MAX_SPAN_S:.0f}] s")
    try:
        return comm_json(runtime, from_t_s, to_t_s)
    except InputError as error:  # a time the ephemeris does not cover
        raise PlanError(str(error)) from None


@routes.put(
    "/api/rovers/{rover}/comm/mode",
    response_model=CommState,
    responses={**AUTH_ERRORS, **NOT_FOUND, **TOO_LARGE, **BAD_REQUEST},
)
async def set_comm_mode(
    server: ServerDep, rover: RoverName, body: ModeBody, request: Request, _: Admin
) -> dict[str, Any]:
    """Change the rover's link: ``mission`` from now on, or ``instant`` (what is on its way
    goes through at once). Applied by the rover's clock and checkpointed before this answers."""
    runtime = server.rover(rover)
    request.state.audit_action = f"comm mode {body.mode}"
    await run_in_threadpool(runtime.comm.request, body.mode, None)
    await run_in_threadpool(server.commit)
    return await run_in_threadpool(comm_json, runtime)


@routes.put(
    "/api/rovers/{rover}/comm/plan",
    response_model=CommState,
    responses={**AUTH_ERRORS, **NOT_FOUND, **TOO_LARGE, **BAD_REQUEST},
)
async def set_comm_plan(
    server: ServerDep,
    rover: RoverName,
    body: PlanBody,
    request: Request,
    _: Operator,
) -> dict[str, Any]:
    """Change fields of the rover's comm plan (``sim.comm.plan.CommPlan``: windows, rates,
    the relay's delay, the store's capacity, the planning time); the others keep their
    values. Every field is checked; nothing changes unless all are good."""
    runtime = server.rover(rover)
    changes = body.model_dump(exclude_none=True)
    request.state.audit_action = "comm plan " + " ".join(f"{k}={v}" for k, v in changes.items())
    try:
        plan = runtime.comm.plan.replaced(changes)
    except InputError as error:
        raise PlanError(str(error), ("body", error.parameter)) from None
    await run_in_threadpool(runtime.comm.request, None, plan)
    await run_in_threadpool(server.commit)
    return await run_in_threadpool(comm_json, runtime)
