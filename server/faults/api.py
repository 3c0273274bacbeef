"""The fault routes (``server.faults.service``): inject, list, reveal; the conductor's only.

Faults are the simulator's truth, so every route needs the conductor role (whatever the
truth view), and the two that change something are audited with the fault in words.
"""

from __future__ import annotations

from datetime import datetime
from typing import Any, Literal, get_args

from fastapi import Request
from pydantic import BaseModel, ConfigDict, Field

from server.access.auth import Conductor
from server.api.answers import FaultEntry, Faults
from server.api.deps import (
    AUTH_ERRORS,
    BAD_REQUEST,
    MAX_SOL,
    NOT_FOUND,
    TOO_LARGE,
    RoverName,
    ServerDep,
    router,
)
from server.faults.service import (
    FaultRequestError,
    fault_json,
    fault_time,
    inject,
    listing,
    reveal,
)
from sim.faults.records import KINDS

FaultKind = Literal["wheel", "gyro_bias", "accel_bias", "navcam", "pancam_dust", "sand_trap",
                    "hga_stuck"]  # fmt: skip
assert set(get_args(FaultKind)) == set(KINDS), "the route's kinds are sim.faults.records.KINDS"


class FaultBody(BaseModel):
    """``POST /api/rovers/{rover}/faults``: a fault's ``kind`` and its ``parameters``, and
    when: ``at_utc`` (ISO 8601), or ``at_sol`` with ``at_lmst_h``, or neither for now."""

    model_config = ConfigDict(extra="forbid", strict=True)
    kind: FaultKind = Field(description="what fails (docs/DESIGN.md, 'Faults and training')")
    parameters: dict[str, str | float] = Field(
        default_factory=dict,
        description="wheel: wheel (LF..RR), mode (stall|fail); gyro_bias: axis (x|y|z), "
        "bias_deg_per_h; accel_bias: axis, bias_ug; pancam_dust: tau (0 to 10); sand_trap: "
        "x_m, y_m (mission frame), radius_m; navcam, hga_stuck: none",
    )
    at_utc: str | None = Field(default=None, max_length=64, description="ISO 8601 date-time")
    at_sol: int | None = Field(default=None, ge=0, le=MAX_SOL)
    at_lmst_h: float | None = Field(default=None, ge=0.0, lt=24.0, allow_inf_nan=False)


routes = router()


@routes.post(
    "/api/rovers/{rover}/faults",
    response_model=FaultEntry,
    status_code=201,
    responses={**AUTH_ERRORS, **NOT_FOUND, **TOO_LARGE, **BAD_REQUEST},
)
def inject_fault(
    server: ServerDep, rover: RoverName, body: FaultBody, request: Request, _: Conductor
) -> dict[str, Any]:
    """Inject a fault into the rover's simulation, truth side only: at ``at_utc``, or
    ``at_sol`` and ``at_lmst_h``, or now. It takes effect at the first command (or idle
    step) that starts at or after that time, and is an event of the truth record; the
    rover reports only what its sensors then measure. The fault's id and times."""
    runtime = server.rover(rover)
    at_utc = None
    if body.at_utc is not None:
        try:
            at_utc = datetime.fromisoformat(body.at_utc)
        except ValueError:
            raise FaultRequestError(("at_utc",), "at_utc: an ISO 8601 date and time") from None
    at_t_s = fault_time(runtime, at_utc, body.at_sol, body.at_lmst_h)
    request.state.audit_action = f"inject fault: {body.kind} {body.parameters}"
    entry = inject(runtime, body.kind, body.parameters, at_t_s)
    answer = fault_json(runtime, entry)
    request.state.audit_action = (
        f"inject fault #{entry.fault_id}: {answer['description']} at {answer['at']['utc']}"
    )
    return answer


@routes.get("/api/rovers/{rover}/faults", response_model=Faults, responses=NOT_FOUND)
def list_faults(server: ServerDep, rover: RoverName, _: Conductor) -> dict[str, Any]:
    """The rover's faults in the order injected, each pending, applied or failed, and
    whether it is revealed."""
    return {"rover": rover, "faults": listing(server.rover(rover))}


@routes.post(
    "/api/rovers/{rover}/faults/reveal",
    response_model=Faults,
    responses={**AUTH_ERRORS, **NOT_FOUND},
)
def reveal_faults(
    server: ServerDep, rover: RoverName, request: Request, _: Conductor
) -> dict[str, Any]:
    """Reveal the rover's faults, for the debrief: from now on every reader (viewers and
    operators too) sees the applied ones on the sol timeline."""
    runtime = server.rover(rover)
    fresh = reveal(runtime)
    request.state.audit_action = f"reveal the faults ({fresh} not revealed before)"
    return {"rover": rover, "faults": listing(runtime), "revealed": fresh}
