"""Rehearsal campaigns over REST: ``/api/rovers/{rover}/rehearsals`` (issue 25).

- ``POST ""`` (operator): ``{"sequence_text": ...}`` or ``{"sequence_id": ...}`` (exactly
  one), ``runs`` 1-1000 (100), ``seed`` 0-2**63-1 (0). The text is held to the upload limit
  (413) and validated as an upload is (``server.validation.pool``, in the client's
  validation slots): a sequence with errors is refused with 400 and its diagnostics (line
  and column each). A rover with no downlink record yet has nothing to start from: 409.
  Over ``MAX_RUNNING_PER_USER`` campaigns at once: 429 naming the limit. Else 202 with the
  campaign's summary; it runs in the background (``server.rehearsal.service``).
- ``GET ""``: the rover's campaigns, newest first; ``GET "/{id}"``: one with its ``risk``
  table (null until runs finish; a running campaign's is of its finished runs).
- ``POST "/{id}/cancel"`` (operator): 200 with the summary (``cancelled``), 409 if over.
- ``GET "/{id}/report"``: predicted against executed (``server.rehearsal.compare``) for the
  execution of the rehearsed sequence the ground has stored (``server.rehearsal.executed``),
  404 while it has not run; its ``truth`` only for a caller the truth view allows.

Any signed-in user may read (a viewer, or anyone while public reading is on).
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from fastapi import Path as PathParam
from fastapi import Request
from fastapi.responses import JSONResponse
from pydantic import BaseModel, ConfigDict, Field
from starlette.concurrency import run_in_threadpool
from starlette.requests import HTTPConnection

from server.access.auth import Operator, Viewer
from server.api.deps import (
    AUTH_ERRORS,
    BUSY,
    MAX_ID,
    NOT_FOUND,
    TOO_LARGE,
    ErrorMessage,
    RequestErrors,
    RoverName,
    SeesTruth,
    ServerDep,
    error_doc,
    router,
)
from server.api.sequences import diagnostics_json
from server.errors import ConflictError, InvalidError, NotFoundError
from server.rehearsal.compare import predicted_vs_executed
from server.rehearsal.executed import executed_sequence, executed_steps, executed_truth
from server.rehearsal.gather import runtime_inputs
from server.rehearsal.outcomes import outcomes_from_dicts
from server.rehearsal.service import MAX_RUNNING_PER_USER, CampaignLimitError, RehearsalService
from server.storage.rehearsals import get_rehearsal
from server.validation.context import rover_site
from server.validation.uploads import too_large

MAX_RUNS = 1000
MAX_SEED = 2**63 - 1
State = Literal["queued", "running", "done", "cancelled", "failed"]


def get_rehearsals(connection: HTTPConnection) -> RehearsalService:
    """The app's rehearsal service (``server.app.create_app`` puts it in ``app.state``)."""
    service: RehearsalService = connection.app.state.rehearsals
    return service


class RehearsalBody(BaseModel):
    """A campaign to start: the sequence (its text, or a stored sequence's id), how many
    runs, and the campaign's seed (the same seed, inputs and runs: the same results)."""

    model_config = ConfigDict(extra="forbid", strict=True)
    sequence_text: str | None = Field(default=None, min_length=1)
    sequence_id: int | None = Field(default=None, ge=1, le=MAX_ID)
    runs: int = Field(default=100, ge=1, le=MAX_RUNS)
    seed: int = Field(default=0, ge=0, le=MAX_SEED)


class RehearsalSummary(BaseModel):
    """A campaign: who asked, its state and progress (``done`` of ``runs``, ``eta_s``),
    its seed, sequence, times (UTC), the workers' start and warm-up (s) and an error."""

    id: int
    rover: str
    user: str
    state: State
    runs: int
    done: int
    eta_s: float | None
    seed: int
    created_t_utc: str
    finished_t_utc: str | None
    sequence_id: int | None
    sequence_text: str
    error: str | None
    warmup_s: float | None


class RehearsalDetail(RehearsalSummary):
    """A campaign and its risk table (``server.rehearsal.risk``; null until runs finish)."""

    risk: dict[str, Any] | None


class RehearsalReport(BaseModel):
    """Predicted against executed (``server.rehearsal.compare``): the campaign, the
    executed sequence's id, each line's figures placed in their distributions, flags, and
    the truth part (null outside the truth view)."""

    model_config = ConfigDict(extra="allow")
    rehearsal_id: int
    sequence_id: int
    lines: list[dict[str, Any]]
    flags: list[str]
    truth: dict[str, Any] | None


class SequenceRefused(ErrorMessage):
    """A rehearsed sequence with errors: each with its line and column."""

    errors: list[dict[str, Any]]
    warnings: list[dict[str, Any]]


RehearsalId = Annotated[int, PathParam(ge=1, le=MAX_ID, description="a rehearsal's id")]
REFUSED: dict[int | str, dict[str, Any]] = {
    400: {"model": SequenceRefused, "description": "the sequence has errors"},
    409: error_doc("the rover has no downlink record yet, or the server is stopping"),
    422: {"model": RequestErrors, "description": "the request's problems"},
    429: error_doc(f"the user already runs {MAX_RUNNING_PER_USER} campaigns at once"),
}

routes = router()


def _campaign(server: Any, rover: str, rehearsal_id: int) -> dict[str, Any]:
    server.rover(rover)
    found = get_rehearsal(server.store, rehearsal_id)
    if found is None or found["rover"] != rover:
        raise NotFoundError(f"no rehearsal {rehearsal_id} of {rover}")
    return found


async def _sequence_text(server: Any, rover: str, body: RehearsalBody) -> str:
    if (body.sequence_text is None) == (body.sequence_id is None):
        raise InvalidError("give exactly one of sequence_text and sequence_id")
    if body.sequence_text is not None:
        return body.sequence_text
    assert body.sequence_id is not None
    found = await run_in_threadpool(server.store.get_sequence, body.sequence_id)
    if found is None or found["rover"] != rover:
        raise NotFoundError(f"no sequence {body.sequence_id} of {rover}")
    return str(found["source"])


@routes.post(
    "/api/rovers/{rover}/rehearsals",
    status_code=202,
    response_model=RehearsalSummary,
    responses={**AUTH_ERRORS, **NOT_FOUND, **TOO_LARGE, **BUSY, **REFUSED},
)
async def start_rehearsal(
    server: ServerDep, rover: RoverName, body: RehearsalBody, request: Request, who: Operator
) -> Any:
    """Start a rehearsal campaign of a sequence (module docstring): 202 at once."""
    runtime = server.rover(rover)
    request.state.audit_action = f"rehearse a sequence on {rover}"
    text = await _sequence_text(server, rover, body)
    data = text.encode("utf-8")
    if len(data) > server.config.max_upload_bytes:
        raise too_large(server.config.max_upload_bytes)
    with server.slots.hold(request):
        checked = await server.validation.check(data, "text/plain", rover_site(runtime), False)
    result = checked.result
    if result.errors or result.sequence is None:
        diags = diagnostics_json(result)
        quoted = "; ".join(f"line {d.line}: {d.message}" for d in result.errors[:3])
        count = len(result.errors)
        detail = f"the sequence has {count} error{'s' * (count != 1)}: {quoted}"
        return JSONResponse({"detail": detail, **diags}, status_code=400)
    if runtime.last_frame is None:
        raise ConflictError(f"no downlink record of {rover} on the ground yet: nothing to "
                            "start a rehearsal from")  # fmt: skip
    service = get_rehearsals(request)
    try:
        summary = await run_in_threadpool(
            service.submit, rover, who.name, body.runs, body.seed, body.sequence_id, text,
            lambda: runtime_inputs(runtime, server.store, text),
        )  # fmt: skip
    except CampaignLimitError as error:
        return JSONResponse({"detail": str(error)}, status_code=429)
    request.state.audit_action = f"rehearse a sequence on {rover} (#{summary['id']})"
    return JSONResponse(RehearsalSummary(**summary).model_dump(), status_code=202)


@routes.get(
    "/api/rovers/{rover}/rehearsals", response_model=list[RehearsalSummary], responses=NOT_FOUND
)
def list_rehearsals(
    server: ServerDep, rover: RoverName, request: Request, _: Viewer
) -> list[dict[str, Any]]:
    """The rover's campaigns, newest first."""
    server.rover(rover)
    return get_rehearsals(request).campaigns(rover)


@routes.get(
    "/api/rovers/{rover}/rehearsals/{rehearsal_id}",
    response_model=RehearsalDetail,
    responses=NOT_FOUND,
)
def get_rehearsal_detail(
    server: ServerDep, rover: RoverName, rehearsal_id: RehearsalId, request: Request, _: Viewer
) -> dict[str, Any]:
    """One campaign with its risk table."""
    _campaign(server, rover, rehearsal_id)
    return get_rehearsals(request).summary(rehearsal_id, with_risk=True)


@routes.post(
    "/api/rovers/{rover}/rehearsals/{rehearsal_id}/cancel",
    response_model=RehearsalSummary,
    responses={**AUTH_ERRORS, **NOT_FOUND, 409: error_doc("the campaign is over")},
)
def cancel_rehearsal(
    server: ServerDep, rover: RoverName, rehearsal_id: RehearsalId, request: Request,
    who: Operator,
) -> dict[str, Any]:  # fmt: skip
    """Cancel a campaign (the runs finished are kept)."""
    request.state.audit_action = f"cancel rehearsal #{rehearsal_id}"
    _campaign(server, rover, rehearsal_id)
    return get_rehearsals(request).cancel(rehearsal_id)


@routes.get(
    "/api/rovers/{rover}/rehearsals/{rehearsal_id}/report",
    response_model=RehearsalReport,
    responses={**NOT_FOUND, 409: error_doc("the campaign has no risk table")},
)
def rehearsal_report(
    server: ServerDep, rover: RoverName, rehearsal_id: RehearsalId, sees_truth: SeesTruth
) -> dict[str, Any]:
    """Predicted against executed, for the execution of the rehearsed sequence."""
    _campaign(server, rover, rehearsal_id)
    found = get_rehearsal(server.store, rehearsal_id, with_outcomes=True)
    assert found is not None
    if found["risk"] is None or not found["outcomes"]:
        raise ConflictError(f"rehearsal {rehearsal_id} is {found['state']}: no risk table yet")
    sequence = executed_sequence(server.store, found)
    if sequence is None:
        raise NotFoundError(
            f"the sequence of rehearsal {rehearsal_id} has not run yet (neither sequence "
            f"{found['sequence_id']} nor a later one with the same text has completed)"
            if found["sequence_id"] is not None
            else f"the sequence of rehearsal {rehearsal_id} has not run yet (no sequence "
            "with its text accepted after it has completed)"
        )
    executed = executed_steps(server.store, sequence)
    truth = executed_truth(server.store, sequence) if sees_truth else None
    outcomes = outcomes_from_dicts(found["outcomes"])
    answer = predicted_vs_executed(found["risk"], outcomes, executed, truth=truth)
    if not sees_truth:
        answer["truth"] = None
    return {"rehearsal_id": rehearsal_id, "sequence_id": int(sequence["id"]), **answer}
