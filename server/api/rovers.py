"""The rovers: their list and state, the command dictionary, immediate commands and the
clock (pause, resume, speed)."""

from __future__ import annotations

import json
import math
from typing import Annotated, Any, Literal

from fastapi import HTTPException, Request
from pydantic import BaseModel, ConfigDict, Field

from sequences import commands as cmd
from sequences.validate import validate
from server.access.auth import Operator, Viewer
from server.api.answers import Clock, CommandSpec, Queued, RoverState, RoverSummary
from server.api.deps import (
    AUTH_ERRORS,
    BAD_REQUEST,
    NOT_FOUND,
    TOO_LARGE,
    RoverName,
    SeesTruth,
    ServerDep,
    router,
)
from server.api.sequences import diagnostics_json, request_errors, steps_json
from server.runtime import MAX_SPEED


class ClockBody(BaseModel):
    """``POST /api/rovers/{rover}/clock``: pause/resume and the speed factor. Strict: a
    boolean is not a speed (``{"speed": true}`` is a 422, not 1.0)."""

    model_config = ConfigDict(extra="forbid", strict=True)
    action: Literal["pause", "resume"] | None = None
    speed: (
        Annotated[float, Field(ge=1.0, le=MAX_SPEED, allow_inf_nan=False)] | Literal["max"] | None
    ) = Field(default=None, description=f"speed factor, 1 to {MAX_SPEED:g}, or 'max'")


class CommandBody(BaseModel):
    """``POST /api/rovers/{rover}/commands``: one immediate command."""

    model_config = ConfigDict(extra="forbid", strict=True)
    command: str = Field(description="a keyword of the command dictionary, e.g. DRIVE_STRAIGHT")
    args: dict[str, Any] = Field(default_factory=dict)


routes = router()


@routes.get("/api/rovers", response_model=list[RoverSummary])
def list_rovers(server: ServerDep, _: Viewer) -> list[dict[str, Any]]:
    """The rovers and their clocks."""
    return [{k: v for k, v in r.state().items() if k != "frame"} for r in server.rovers.values()]


@routes.get("/api/rovers/{rover}/state", response_model=RoverState, responses=NOT_FOUND)
def rover_state(server: ServerDep, rover: RoverName, _: Viewer, truth: SeesTruth) -> dict[str, Any]:
    """Clock, queue, the executing command and the latest telemetry frame (the downlink
    record, merged with its truth record in the truth view); ``truth`` says which."""
    runtime = server.rover(rover)
    with runtime.lock:  # the state and its downlink record of one moment
        state = runtime.state()
        if not truth:
            state["frame"] = runtime.last_frame
    return {**state, "truth": truth}


@routes.get("/api/commands", response_model=list[CommandSpec])
def command_dictionary(_: Viewer) -> list[dict[str, Any]]:
    """The command dictionary: every command with its arguments, each from the spec that
    construction checks (``sequences.commands.ArgSpec``): ``type`` (number, boolean,
    string, number_or_boolean), ``unit``, ``min``, ``max``, ``min_exclusive``, ``range``
    (as the error messages write it), ``default``, ``required`` and a ``note`` on what
    the range cannot say. Absent unit, bounds, range and note are null."""
    return [
        {
            "command": name,
            "doc": (kind.__doc__ or "").strip(),
            "args": [
                {
                    "name": a.name,
                    "type": a.spec.kind,
                    "unit": a.spec.unit or None,
                    "min": a.spec.lo,
                    "max": a.spec.hi,
                    "min_exclusive": a.spec.lo_open,
                    "range": a.spec.range_text() or None,
                    "default": a.default,
                    "required": a.required,
                    "note": a.spec.note or None,
                }
                for a in kind.argument_table()
            ],
        }
        for name, kind in cmd.COMMANDS.items()
    ]


@routes.post(
    "/api/rovers/{rover}/commands",
    response_model=Queued,
    status_code=201,
    responses={**AUTH_ERRORS, **NOT_FOUND, **TOO_LARGE, **BAD_REQUEST},
)
def immediate_command(
    server: ServerDep, rover: RoverName, body: CommandBody, request: Request, who: Operator
) -> dict[str, Any]:
    """One command, run before the next queued step."""
    runtime = server.rover(rover)
    request.state.audit_action = f"immediate command {body.command}"
    source = {
        "name": f"immediate_{body.command}",
        "steps": [{"command": body.command, "args": body.args}],
    }
    result = validate(source, server.context(runtime))
    if result.errors or result.sequence is None:
        raise HTTPException(422, request_errors(result))
    seq_id = server.store.add_sequence(
        rover,
        f"immediate_{body.command}",
        json.dumps(source),
        "command",
        "queued",
        [],
        diagnostics_json(result)["warnings"],
        steps_json(result.sequence),
        who.name,
    )
    runtime.enqueue(seq_id, result.sequence, immediate=True)
    request.state.audit_action = f"immediate command {body.command} (#{seq_id}): queued"
    return {"id": seq_id, "status": "queued", **diagnostics_json(result)}


@routes.post(
    "/api/rovers/{rover}/clock",
    response_model=Clock,
    responses={**AUTH_ERRORS, **NOT_FOUND, **TOO_LARGE, **BAD_REQUEST},
)
def set_clock(
    server: ServerDep, rover: RoverName, body: ClockBody, request: Request, _: Operator
) -> dict[str, Any]:
    """Pause, resume, or set the speed factor (1 to MAX_SPEED, or 'max')."""
    runtime = server.rover(rover)
    request.state.audit_action = "clock " + " ".join(
        f"{k}={v}" for k, v in body.model_dump(exclude_none=True).items()
    )
    speed: float | None = None
    if body.speed == "max":
        speed = math.inf
    elif body.speed is not None:
        speed = float(body.speed)  # ClockBody bounds it
    running = None if body.action is None else body.action == "resume"
    runtime.set_clock(running=running, speed=speed)
    clock: dict[str, Any] = runtime.state()["clock"]
    return clock
