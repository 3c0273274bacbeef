"""Sequences: upload (validated in a worker process, stored, queued), validation alone, the
list, one sequence, and cancelling a queued or running one."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from fastapi import Query, Request
from fastapi.responses import JSONResponse
from pydantic import BaseModel
from starlette.concurrency import run_in_threadpool

from sequences.language import Sequence, SequenceStep
from sequences.validate import ValidationResult
from server.access.auth import Operator, Viewer
from server.api.answers import CancelledSequence, Diagnostic, SequenceRecord, StoredSequence
from server.api.deps import (
    AUTH_ERRORS,
    BAD_REQUEST,
    BUSY,
    NOT_FOUND,
    TOO_LARGE,
    RequestErrors,
    RoverName,
    SequenceId,
    ServerDep,
    error_doc,
    router,
)
from server.comm.hosting import CancelSent
from server.comm.view import when
from server.errors import ConflictError, NotFoundError
from server.runtime import RoverRuntime
from server.state import Server
from server.validation.context import rover_site
from server.validation.pool import Checked
from server.validation.uploads import read_body


class ValidationReport(BaseModel):
    """``POST /api/sequences/validate``: nothing stored."""

    valid: bool
    errors: list[Diagnostic]
    warnings: list[Diagnostic]


class SequenceReport(BaseModel):
    """An uploaded sequence as stored: ``queued`` (201), or ``rejected`` with its errors
    (422; it is stored, to be looked at later)."""

    id: int
    status: Literal["queued", "rejected"]
    errors: list[Diagnostic]
    warnings: list[Diagnostic]


SEQUENCE_BODY: dict[str, Any] = {
    "required": True,
    "description": 'A sequence: its text, JSON, or a file. JSON may be `{"text": ...}`, '
    '`{"sequence": ...}`, a sequence object (`name`, `steps`), or a list of steps; JSON '
    "nested deeper than server.validation.uploads.MAX_JSON_DEPTH is refused.",
    "content": {
        "text/plain": {"schema": {"type": "string"}},
        "application/json": {
            "schema": {
                # what the validator judges (a sequence's name and steps) is not
                # constrained here: a wrong one is a sequence with errors, not a bad request
                "anyOf": [
                    {
                        "type": "object",
                        "properties": {
                            "text": {"type": "string"},
                            "sequence": {"type": ["object", "array"]},
                        },
                    },
                    {"type": "array"},
                ]
            }
        },
        "multipart/form-data": {
            "schema": {
                "type": "object",
                "properties": {"file": {"type": "string", "format": "binary"}},
                "required": ["file"],
            }
        },
    },
}


def diagnostics_json(result: ValidationResult) -> dict[str, Any]:
    def as_list(items: list[Any]) -> list[dict[str, Any]]:
        return [
            {"line": d.line, "column": d.column, "code": d.code, "message": d.message}
            for d in items
        ]

    return {"errors": as_list(result.errors), "warnings": as_list(result.warnings)}


REJECTED_SHOWN = 3  # errors a rejected sequence's detail quotes (all are in its errors)


def _rejected(errors: list[dict[str, Any]]) -> str:
    """A rejected sequence's detail, as the sequences list shows it: how many errors, and
    the first with their lines (``rejected: 2 errors: line 2: ...; line 4: ...``)."""
    count = f"{len(errors)} error{'' if len(errors) == 1 else 's'}"
    quoted = [f"line {e['line']}: {e['message']}" for e in errors[:REJECTED_SHOWN]]
    more = [f"{len(errors) - REJECTED_SHOWN} more"] if len(errors) > REJECTED_SHOWN else []
    return f"rejected: {count}: " + "; ".join(quoted + more) if errors else "rejected"


def request_errors(result: ValidationResult) -> list[dict[str, Any]]:
    """A sequence's errors as a 422 ``detail`` (``RequestErrors``): the diagnostic's code as
    ``type``, its message as ``msg``."""
    return [
        {"loc": ["body"], "msg": d.message, "type": d.code, "line": d.line, "column": d.column}
        for d in result.errors
    ]


def steps_json(sequence: Sequence) -> list[dict[str, Any]]:
    return [step_json(s) for s in sequence.steps]


def step_json(step: SequenceStep) -> dict[str, Any]:
    return {
        "line": step.line,
        "command": step.command.name,
        "args": step.command.arguments(),
        "time": step.time_tag.kind,
    }


routes = router()


async def read_and_check(
    server: Server, request: Request, runtime: RoverRuntime | None, named: bool = False
) -> Checked:
    """The body read (413 past the limit) and checked in a validation process
    (``server.validation.pool``), in one of the client's validation slots (429 when it
    has none left)."""
    with server.slots.hold(request):
        body = await read_body(request, server.config.max_upload_bytes)
        content_type = request.headers.get("content-type", "")
        site = rover_site(runtime) if runtime else None
        return await server.validation.check(body, content_type, site, named)


@routes.post(
    "/api/rovers/{rover}/sequences",
    status_code=201,
    response_model=SequenceReport,
    responses={
        **AUTH_ERRORS,
        **NOT_FOUND,
        **TOO_LARGE,
        422: {
            "model": SequenceReport | RequestErrors,
            "description": "a sequence with errors (stored as rejected), or a body "
            "that is not a sequence",
        },
        **BUSY,
    },
    openapi_extra={"requestBody": SEQUENCE_BODY},
)
async def upload_sequence(
    server: ServerDep, rover: RoverName, request: Request, who: Operator
) -> JSONResponse:
    """Validate, store and queue a sequence (text, JSON, or a multipart file)."""
    runtime = server.rover(rover)
    request.state.audit_action = "upload a sequence"
    checked = await read_and_check(server, request, runtime, named=True)
    name = checked.name
    result, diags = checked.result, diagnostics_json(checked.result)
    if result.errors or result.sequence is None:

        def store_rejected() -> int:
            seq_id = server.store.add_sequence(
                rover, name, checked.text, checked.fmt, "rejected", diags["errors"],
                diags["warnings"], [], who.name,
            )  # fmt: skip
            server.store.set_sequence_status(seq_id, "rejected", _rejected(diags["errors"]))
            return seq_id

        seq_id = await run_in_threadpool(store_rejected)
        request.state.audit_action = f"upload sequence {name} (#{seq_id}): rejected"
        return JSONResponse({"id": seq_id, "status": "rejected", **diags}, status_code=422)
    steps = steps_json(result.sequence)
    seq_id = await run_in_threadpool(
        server.store.add_sequence,
        rover, name, checked.text, checked.fmt, "queued", [], diags["warnings"], steps,
        who.name,
    )  # fmt: skip
    # off the event loop: queueing rewrites the last checkpoint (tens of ms)
    await run_in_threadpool(runtime.enqueue, seq_id, result.sequence)
    request.state.audit_action = f"upload sequence {name} (#{seq_id}): queued"
    return JSONResponse({"id": seq_id, "status": "queued", **diags}, status_code=201)


@routes.post(
    "/api/sequences/validate",
    response_model=ValidationReport,
    responses={**NOT_FOUND, **TOO_LARGE, **BAD_REQUEST, **BUSY},
    openapi_extra={"requestBody": SEQUENCE_BODY},
)
async def validate_only(
    server: ServerDep,
    request: Request,
    _: Viewer,
    rover: Annotated[
        str | None, Query(description="add this rover's warnings (its state now)")
    ] = None,
) -> dict[str, Any]:
    """Validation only: nothing stored. ``?rover=`` adds that rover's warnings."""
    runtime = server.rover(rover) if rover is not None else None
    checked = await read_and_check(server, request, runtime)
    return {"valid": not checked.result.errors, **diagnostics_json(checked.result)}


@routes.get(
    "/api/rovers/{rover}/sequences", response_model=list[StoredSequence], responses=NOT_FOUND
)
def list_sequences(server: ServerDep, rover: RoverName, _: Viewer) -> list[dict[str, Any]]:
    """Sequences of a rover, newest first, each with who submitted it."""
    server.rover(rover)
    return server.store.list_sequences(rover)


@routes.get("/api/sequences/{sequence_id:int}", response_model=SequenceRecord, responses=NOT_FOUND)
def get_sequence(server: ServerDep, sequence_id: SequenceId, _: Viewer) -> dict[str, Any]:
    """One sequence with its source, steps, status, errors and warnings."""
    found = server.store.get_sequence(sequence_id)
    if found is None:
        raise NotFoundError(f"no sequence {sequence_id}")
    if found.get("stages") and found["rover"] in server.rovers:  # each stage's moment
        found["stages"] = [{**g, "when": when(server.rovers[found["rover"]], g["t_s"])}
                           for g in found["stages"]]  # fmt: skip
    return found


@routes.delete(
    "/api/sequences/{sequence_id:int}",
    response_model=CancelledSequence,
    responses={**AUTH_ERRORS, **NOT_FOUND, 409: error_doc("the sequence is not queued")},
)
def cancel_sequence(
    server: ServerDep, sequence_id: SequenceId, request: Request, who: Operator
) -> dict[str, Any]:
    """Cancel a queued sequence (a running one stops after its current command, which
    runs to its end); ``detail`` says where it stopped, as the sequence's record does."""
    request.state.audit_action = f"cancel sequence #{sequence_id}"
    found = server.store.get_sequence(sequence_id)
    if found is None:
        raise NotFoundError(f"no sequence {sequence_id}")
    request.state.audit_rover = found["rover"]
    runtime = server.rover(found["rover"])
    stopped = runtime.cancel(sequence_id)
    if stopped is None:
        raise ConflictError(f"sequence {sequence_id} is {found['status']}, not queued")
    if isinstance(stopped, CancelSent):  # across light time: the rover answers later
        detail = (f"cancel accepted by the ground from {who.name}: it goes up in the next "
                  "uplink window; the rover reports where the sequence stopped")  # fmt: skip
        return {"id": sequence_id, "status": "cancel-sent", "detail": detail}
    detail = f"cancelled by {who.name} {stopped.where()}"
    server.store.set_sequence_status(sequence_id, "cancelled", detail)
    return {"id": sequence_id, "status": "cancelled", "detail": detail}
