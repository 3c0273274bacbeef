"""The operations server: FastAPI over the rover runtimes, storage and live telemetry.

``create_app(config)`` builds the app; ``roverops serve`` runs it with uvicorn. Each route
needs a role (``server.accounts``: viewer, operator, conductor, admin; ``server.auth``):
viewing needs no token while ``public_read`` is on; uploading, commanding and clock control
need an operator's token (``Authorization: Bearer <token>``): missing 401, wrong or too low
403, and nothing changes; the token is checked before the body is read
(``server.routing``). Every mutating request is audited (``server.audit``).
Request bodies are validated: every 422's ``detail`` is a list of ``{"loc", "msg",
"type"}`` (FastAPI's shape), except a rejected upload, which is stored and answered with
its diagnostics (``SequenceReport``). Bodies above ``max_upload_bytes`` get 413 while they
stream in; a client running ``max_concurrent_validations`` validations at once gets 429
(``server.uploads``). OpenAPI at ``/docs``.
"""

from __future__ import annotations

import asyncio
import contextlib
import csv
import io
import json
import logging
import math
import time
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Annotated, Any, Literal

import anyio
from fastapi import FastAPI, HTTPException, Query, Request, WebSocket
from fastapi import Path as PathParam
from fastapi.responses import FileResponse, JSONResponse, RedirectResponse, Response
from fastapi.staticfiles import StaticFiles
from pydantic import BaseModel, ConfigDict, Field
from starlette.concurrency import run_in_threadpool
from starlette.websockets import WebSocketDisconnect

from sequences import commands as cmd
from sequences.language import Sequence, SequenceStep
from sequences.validate import ValidationContext, ValidationResult, validate
from server.accounts import (
    DEFAULT_EXPIRY_DAYS,
    ROLES,
    AccountError,
    Accounts,
    Principal,
    TokenRefusedError,
    UnknownUserError,
    UserExistsError,
)
from server.alarms import AlarmEngine, AlarmError
from server.audit import AuditLog, AuditMiddleware, as_csv
from server.auth import (
    COOKIE,
    Admin,
    Operator,
    Viewer,
    document_public_reads,
    websocket_principal,
)
from server.channels import add_routes as add_channel_routes
from server.eventlog import LOG_KINDS, MAX_LIMIT, EventFilter, FilterError, event_log
from server.hub import MAX_RATE_HZ, TelemetryHub, next_message
from server.limits import LimitsError
from server.origin import origin_allowed
from server.queue_view import QueueNotices, queue_json, recent_json
from server.routing import AuthFirstRoute, allow_every_method
from server.runtime import (
    MAX_SPEED,
    ROVERS,
    Cancelled,
    CheckpointFormatError,
    NotQueuedError,
    QueueError,
    RoverRuntime,
)
from server.scene3d import RoverScene
from server.sinks import FrameSink, StorageSink
from server.storage import BatchWriter, Store
from server.timeline import sol_timeline, stored_command
from server.uploads import ValidationSlots, read_body, request_error
from server.validation_context import rover_site, validation_context
from server.validation_pool import Checked, ValidationPool
from server.viser_proxy import fetch, relay
from sim.loop.side.kinematic import ESTIMATORS
from sim.world.marsclock import t_s_to_utc

MAX_UPLOAD_BYTES = 1_000_000
MAX_CONCURRENT_VALIDATIONS = 2  # per client address, and per token
VALIDATION_PROCESSES = 1  # one core of two for uploads, the other for the server
MAX_ID = 2**31 - 1  # ids are PostgreSQL's int4 (storage: Integer columns)
MAX_SOL = 100_000  # 270 Earth years of a mission; the bundled ephemeris covers fewer
WEB_DIR = Path(__file__).resolve().parent.parent / "web"  # the console, served as is


@dataclass
class ServerConfig:
    """Settings of one server (``roverops serve`` fills them from flags and ROVEROPS_*)."""

    database_url: str
    # the bootstrap admin token (--operator-token): in memory only, for scripts and tests;
    # None: only the users' tokens in the database are accepted
    operator_token: str | None = None
    # reading (telemetry, sequences, timelines, the 3D view) needs no token while on
    public_read: bool = True
    max_upload_bytes: int = MAX_UPLOAD_BYTES  # every request body, uploads or not
    max_concurrent_validations: int = MAX_CONCURRENT_VALIDATIONS
    # uploads validate in these worker processes (server.validation_pool); 0: in the
    # server's threadpool, sharing its interpreter lock (slower answers while one runs)
    validation_processes: int = VALIDATION_PROCESSES
    start_clocks: bool = True
    initial_speed: float = 1.0
    viewer_3d: bool = False  # a viser 3D view per rover under /viser/{rover}/
    # what runs beside SAPP on a new rover (sim.loop.side.kinematic); a rover restored from a
    # checkpoint keeps the estimators it was started with
    estimators: tuple[str, ...] = ("sapp",)


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


class MoveBody(BaseModel):
    """``POST /api/rovers/{rover}/queue/{sequence_id}/move``: the queued sequence's new
    position (0 runs next; ``GET .../queue`` lists positions)."""

    model_config = ConfigDict(extra="forbid", strict=True)
    to: int = Field(ge=0, le=MAX_ID, description="the new position, 0 at the head")


class Diagnostic(BaseModel):
    """One problem in a sequence (``sequences.language.Diagnostic``)."""

    line: int
    column: int
    code: str
    message: str


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


class ErrorMessage(BaseModel):
    """Every error but a 422: what went wrong, in one sentence."""

    detail: str


class RequestError(BaseModel):
    """One problem with a request (FastAPI's validation-error item; it may carry more)."""

    model_config = ConfigDict(extra="allow")
    loc: list[str | int]
    msg: str
    type: str


class RequestErrors(BaseModel):
    """A 422: every problem found with the request."""

    detail: list[RequestError]


def _error(text: str) -> dict[str, Any]:
    return {"model": ErrorMessage, "description": text}


AUTH_ERRORS: dict[int | str, dict[str, Any]] = {
    401: _error("no token where the route needs one (Authorization: Bearer <token>)"),
    403: _error("a wrong, expired or revoked token, or a role too low for the route"),
}
NOT_FOUND: dict[int | str, dict[str, Any]] = {404: _error("no such rover or record")}
TOO_LARGE: dict[int | str, dict[str, Any]] = {413: _error("body over the server's limit")}
BUSY: dict[int | str, dict[str, Any]] = {
    429: {
        **_error("this client already runs the most validations allowed at once"),
        "headers": {"Retry-After": {"schema": {"type": "integer"}, "description": "seconds"}},
    }
}
BAD_REQUEST: dict[int | str, dict[str, Any]] = {
    422: {"model": RequestErrors, "description": "the request's problems"}
}
SEQUENCE_BODY: dict[str, Any] = {
    "required": True,
    "description": 'A sequence: its text, JSON, or a file. JSON may be `{"text": ...}`, '
    '`{"sequence": ...}`, a sequence object (`name`, `steps`), or a list of steps; JSON '
    "nested deeper than server.uploads.MAX_JSON_DEPTH is refused.",
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
RoverName = Annotated[
    str, PathParam(description="a rover's name (GET /api/rovers)", examples=list(ROVERS))
]
SequenceId = Annotated[int, PathParam(ge=1, le=MAX_ID, description="a sequence's id")]
Sol = Annotated[int, PathParam(ge=0, le=MAX_SOL, description="a sol of the mission")]


LimitLevel = float | str | list[str] | None


class LimitsBody(BaseModel):
    """``PUT /api/rovers/{rover}/limits/{channel}``: a channel's levels (``server.limits``):
    numbers (numeric), a level's name (ordinal, e.g. AQF), a list of states (state), or
    null for no level; ``hysteresis`` (numeric only) in the channel's units."""

    model_config = ConfigDict(extra="forbid", strict=True)
    warning: LimitLevel = Field(description="the warning level, or null")
    critical: LimitLevel = Field(description="the critical level, or null")
    hysteresis: float | None = Field(default=None, ge=0.0, allow_inf_nan=False)


Channel = Annotated[str, PathParam(max_length=64, description="a channel (GET .../limits)")]
AlarmId = Annotated[int, PathParam(ge=1, le=MAX_ID, description="an alarm's id")]


class SessionBody(BaseModel):
    """``POST /api/session``: sign this browser in with a token (kept in a cookie)."""

    model_config = ConfigDict(extra="forbid")
    token: str = Field(min_length=1, max_length=512)


class NewUserBody(BaseModel):
    """``POST /api/users``: a user, its role and the lifetime of its first token."""

    model_config = ConfigDict(extra="forbid", strict=True)
    name: str = Field(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9_.-]+$")
    role: Literal["viewer", "operator", "conductor", "admin"]
    expires_days: float = Field(default=DEFAULT_EXPIRY_DAYS, gt=0, le=3650)


class RoleBody(BaseModel):
    """``PATCH /api/users/{name}``: a new role."""

    model_config = ConfigDict(extra="forbid", strict=True)
    role: Literal["viewer", "operator", "conductor", "admin"]


class TokenBody(BaseModel):
    """``POST /api/users/{name}/tokens``: the lifetime of the new token."""

    model_config = ConfigDict(extra="forbid", strict=True)
    expires_days: float = Field(default=DEFAULT_EXPIRY_DAYS, gt=0, le=3650)


def _account_error(error: AccountError) -> HTTPException:
    if isinstance(error, UnknownUserError):
        return HTTPException(404, str(error))
    if isinstance(error, UserExistsError):
        return HTTPException(409, str(error))
    return request_error(("body",), str(error), "account")


class Server:
    """The app's state: the runtimes, storage, the writer and the hub."""

    def __init__(self, config: ServerConfig) -> None:
        self.config = config
        self.store = Store(config.database_url)
        self.accounts = Accounts(self.store, config.operator_token)
        self.audit = AuditLog(self.store)
        self.writer = BatchWriter(self.store)
        self.hub = TelemetryHub()
        self.validation = ValidationPool(config.validation_processes)
        self.rovers: dict[str, RoverRuntime] = {}
        self.queue_notices = QueueNotices(
            self._queue_notice, self.hub.notify, lambda rover: self.hub.count(rover) > 0
        )
        self.alarms = AlarmEngine(self.store, self._when, self.hub.notify)
        self.alarms.on_event = self._server_event
        # every played-out batch, in order: stored, judged against the limits, sent live
        self.sinks: list[FrameSink] = [StorageSink(self.writer), self.alarms, self.hub]
        for name, spec in ROVERS.items():
            saved = self.store.load_checkpoint(name)
            try:
                runtime = RoverRuntime.restore(spec, saved[1]) if saved else None
            except CheckpointFormatError as error:  # an older format: the rover starts fresh
                logging.getLogger(__name__).warning("%s", error)
                saved = None
            if saved is None:
                runtime = RoverRuntime(spec, estimators=config.estimators)
            assert runtime is not None
            if saved is None:
                runtime.set_clock(speed=config.initial_speed)
            if saved is not None:
                self._resume(runtime)
            runtime.sinks.extend(self.sinks)
            runtime.on_command = self._command
            runtime.on_sequence = self._sequence
            runtime.on_checkpoint = self.writer.checkpoint
            runtime.commit = self.writer.flush  # a clock change is stored when it answers
            runtime.on_queue = self.queue_notices.changed
            self.rovers[name] = runtime
        self.scenes: dict[str, RoverScene] = {}
        if config.viewer_3d:
            self.scenes = {name: RoverScene(rt, self.store) for name, rt in self.rovers.items()}

    def _resume(self, runtime: RoverRuntime) -> None:
        """After a restart: no frame stored twice, and every accepted sequence the
        checkpoint does not hold (accepted or started after it) queued again, in order, an
        immediate command (format ``command``) first as when it was sent."""
        rover = runtime.spec.name
        last = self.store.last_frame(rover)
        if last is not None:
            runtime.watermark_t_s = float(last["t_s"])
            runtime.last_frame = last
        held = set(runtime.queued_ids())
        pending = [
            s
            for s in self.store.list_sequences(rover)
            if s["status"] in ("queued", "running") and s["id"] not in held
        ]
        for summary in sorted(pending, key=lambda s: s["id"]):
            stored = self.store.get_sequence(summary["id"])
            assert stored is not None
            text = stored["source"]
            source = json.loads(text) if stored["format"] in ("json", "command") else text
            result = validate(source)
            if result.sequence is None:  # cannot happen: it was accepted
                self.store.set_sequence_status(summary["id"], "failed", "unreadable after restart")
                continue
            runtime.enqueue(summary["id"], result.sequence, stored["format"] == "command")

    def _when(self, rover: str, t_s: float) -> dict[str, Any]:
        runtime = self.rovers[rover]
        return {"t_s": t_s, "utc": t_s_to_utc(t_s).isoformat(), "lmst_h": runtime.lmst_h(t_s),
                "sol": runtime.sol(t_s)}  # fmt: skip

    def _command(self, rover: str, report: dict[str, Any]) -> None:
        self.writer.command(rover, **report)
        if self.hub.count(rover):  # a live timeline shows it: written now, read back as listed
            self.writer.flush()
            entry = stored_command(self.store, self.rovers[rover], report)
            if entry is not None:
                self.hub.notify(rover, {"type": "command", "command": entry})

    def _sequence(self, sequence_id: int, status: str, detail: str | None) -> None:
        self.writer.flush()
        before = self.store.get_sequence(sequence_id)
        self.store.set_sequence_status(sequence_id, status, detail)
        if before is None or before["status"] == status:  # e.g. resumed after a restart
            return
        said = {"running": "started", "completed": "completed", "failed": "failed"}
        severity = "error" if status == "failed" else "warning" if detail else "info"
        text = f"sequence #{sequence_id} {before['name']} {said.get(status, status)}"
        self._server_event(
            before["rover"], None,
            {"text": text + (f": {detail}" if detail else ""), "kind": "sequence",
             "severity": severity},
        )  # fmt: skip

    def _server_event(self, rover: str, t_s: float | None, event: dict[str, str]) -> None:
        """An event the server makes (``estimation.events``: kinds ``sequence``, ``alarm``),
        at ``t_s`` or the rover's clock now: stored for the event log and sent as an
        ``event`` notice (it is in no frame)."""
        t = self.rovers[rover].t_s if t_s is None else t_s
        when = self._when(rover, t)
        self.writer.events(rover, [(t, event)])
        self.hub.notify(rover, {"type": "event", "event": {
            **event, "t_s": t, "sol": when["sol"], "lmst_h": when["lmst_h"]}})  # fmt: skip

    def _queue_notice(self, rover: str) -> dict[str, Any]:
        return {
            "type": "queue",
            "rover": rover,
            "queue": queue_json(self.rovers[rover], self.store),
        }

    def start(self) -> None:
        self.writer.start()
        self.queue_notices.start()
        self.validation.start(rover_site(next(iter(self.rovers.values()))))
        for scene in self.scenes.values():
            scene.start()
        if self.config.start_clocks:
            for runtime in self.rovers.values():
                runtime.start()

    def stop(self) -> None:
        """Each rover's clock stopped and checkpointed where it stopped, then everything
        written: a graceful stop (SIGTERM) loses nothing."""
        for runtime in self.rovers.values():
            runtime.stop()
        self.queue_notices.stop()
        for scene in self.scenes.values():
            scene.stop()
        self.validation.stop()
        self.writer.stop()
        self.store.close()

    def rover(self, name: str) -> RoverRuntime:
        if name not in self.rovers:
            raise HTTPException(404, f"unknown rover {name!r}; known: {', '.join(self.rovers)}")
        return self.rovers[name]

    def context(self, runtime: RoverRuntime) -> ValidationContext:
        """What validation warnings need to know of a rover, from its state now."""
        return validation_context(runtime)


def _diagnostics(result: ValidationResult) -> dict[str, Any]:
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


def _request_errors(result: ValidationResult) -> list[dict[str, Any]]:
    """A sequence's errors as a 422 ``detail`` (``RequestErrors``): the diagnostic's code as
    ``type``, its message as ``msg``."""
    return [
        {"loc": ["body"], "msg": d.message, "type": d.code, "line": d.line, "column": d.column}
        for d in result.errors
    ]


CSV_FILE: dict[str, Any] = {
    "description": "CSV, one row per frame",
    "content": {"text/csv": {"schema": {"type": "string"}}},
}


def cancelled_where(stopped: Cancelled) -> str:
    """Where a cancelled sequence stopped, in words (its record's ``detail``)."""
    if stopped.running_step is not None:
        rest = stopped.steps - stopped.running_step - 1
        left = f"; {rest} step(s) after it not run" if rest else ""
        return (
            f"during step {stopped.running_step + 1} of {stopped.steps} (it runs to its end){left}"
        )
    if stopped.done == 0:
        return f"before it started ({stopped.steps} step(s) not run)"
    return f"after step {stopped.done} of {stopped.steps} ({stopped.steps - stopped.done} not run)"


def _steps_json(sequence: Sequence) -> list[dict[str, Any]]:
    return [_step_json(s) for s in sequence.steps]


def _step_json(step: SequenceStep) -> dict[str, Any]:
    return {
        "line": step.line,
        "command": step.command.name,
        "args": step.command.arguments(),
        "time": step.time_tag.kind,
    }


def create_app(config: ServerConfig) -> FastAPI:
    """The FastAPI app over a new ``Server``."""
    server = Server(config)

    @asynccontextmanager
    async def lifespan(_: FastAPI) -> AsyncIterator[None]:
        server.start()
        try:
            yield
        finally:
            server.stop()

    app = FastAPI(
        title="roverops",
        description="Ground operations for a simulated Mars Exploration Rover",
        lifespan=lifespan,
        responses=AUTH_ERRORS,  # any route: a bad token, or no token where reading needs one
    )
    app.router.route_class = AuthFirstRoute  # the token before the body, for every route
    allow_every_method(app)
    app.state.server = server
    app.add_middleware(AuditMiddleware, server=server)
    if config.public_read:
        document_public_reads(app)
    app.state.max_body_bytes = config.max_upload_bytes
    slots = ValidationSlots(config.max_concurrent_validations)

    @app.get("/", include_in_schema=False)
    def console_page() -> FileResponse:
        """The operators' console (``web/``)."""
        return FileResponse(WEB_DIR / "index.html")

    app.mount("/static", StaticFiles(directory=WEB_DIR), name="static")

    @app.get("/api/rovers")
    def list_rovers(_: Viewer) -> list[dict[str, Any]]:
        """The rovers and their clocks."""
        return [
            {k: v for k, v in r.state().items() if k != "frame"} for r in server.rovers.values()
        ]

    @app.get("/api/rovers/{rover}/state", responses=NOT_FOUND)
    def rover_state(rover: RoverName, _: Viewer) -> dict[str, Any]:
        """Clock, queue, the executing command and the latest telemetry frame."""
        return server.rover(rover).state()

    @app.get("/api/commands")
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

    async def read_and_check(
        request: Request, runtime: RoverRuntime | None, named: bool = False
    ) -> Checked:
        """The body read (413 past the limit) and checked in a validation process
        (``server.validation_pool``), in one of the client's validation slots (429 when it
        has none left)."""
        with slots.hold(request):
            body = await read_body(request, config.max_upload_bytes)
            content_type = request.headers.get("content-type", "")
            site = rover_site(runtime) if runtime else None
            return await server.validation.check(body, content_type, site, named)

    @app.post(
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
    async def upload_sequence(rover: RoverName, request: Request, who: Operator) -> JSONResponse:
        """Validate, store and queue a sequence (text, JSON, or a multipart file)."""
        runtime = server.rover(rover)
        request.state.audit_action = "upload a sequence"
        checked = await read_and_check(request, runtime, named=True)
        name = checked.name
        result, diags = checked.result, _diagnostics(checked.result)
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
        steps = _steps_json(result.sequence)
        seq_id = await run_in_threadpool(
            server.store.add_sequence,
            rover, name, checked.text, checked.fmt, "queued", [], diags["warnings"], steps,
            who.name,
        )  # fmt: skip
        # off the event loop: queueing rewrites the last checkpoint (tens of ms)
        await run_in_threadpool(runtime.enqueue, seq_id, result.sequence)
        request.state.audit_action = f"upload sequence {name} (#{seq_id}): queued"
        return JSONResponse({"id": seq_id, "status": "queued", **diags}, status_code=201)

    @app.post(
        "/api/sequences/validate",
        response_model=ValidationReport,
        responses={**NOT_FOUND, **TOO_LARGE, **BAD_REQUEST, **BUSY},
        openapi_extra={"requestBody": SEQUENCE_BODY},
    )
    async def validate_only(
        request: Request,
        _: Viewer,
        rover: Annotated[
            str | None, Query(description="add this rover's warnings (its state now)")
        ] = None,
    ) -> dict[str, Any]:
        """Validation only: nothing stored. ``?rover=`` adds that rover's warnings."""
        runtime = server.rover(rover) if rover is not None else None
        checked = await read_and_check(request, runtime)
        return {"valid": not checked.result.errors, **_diagnostics(checked.result)}

    @app.get("/api/rovers/{rover}/sequences", responses=NOT_FOUND)
    def list_sequences(rover: RoverName, _: Viewer) -> list[dict[str, Any]]:
        """Sequences of a rover, newest first, each with who submitted it."""
        server.rover(rover)
        return server.store.list_sequences(rover)

    @app.get("/api/sequences/{sequence_id:int}", responses=NOT_FOUND)
    def get_sequence(sequence_id: SequenceId, _: Viewer) -> dict[str, Any]:
        """One sequence with its source, steps, status, errors and warnings."""
        found = server.store.get_sequence(sequence_id)
        if found is None:
            raise HTTPException(404, f"no sequence {sequence_id}")
        return found

    @app.delete(
        "/api/sequences/{sequence_id:int}",
        responses={**AUTH_ERRORS, **NOT_FOUND, 409: _error("the sequence is not queued")},
    )
    def cancel_sequence(sequence_id: SequenceId, request: Request, who: Operator) -> dict[str, Any]:
        """Cancel a queued sequence (a running one stops after its current command, which
        runs to its end); ``detail`` says where it stopped, as the sequence's record does."""
        request.state.audit_action = f"cancel sequence #{sequence_id}"
        found = server.store.get_sequence(sequence_id)
        if found is None:
            raise HTTPException(404, f"no sequence {sequence_id}")
        request.state.audit_rover = found["rover"]
        runtime = server.rover(found["rover"])
        stopped = runtime.cancel(sequence_id)
        if stopped is None:
            raise HTTPException(409, f"sequence {sequence_id} is {found['status']}, not queued")
        detail = f"cancelled by {who.name} {cancelled_where(stopped)}"
        server.store.set_sequence_status(sequence_id, "cancelled", detail)
        return {"id": sequence_id, "status": "cancelled", "detail": detail}

    @app.get("/api/rovers/{rover}/queue", responses=NOT_FOUND)
    def rover_queue(rover: RoverName, _: Viewer) -> dict[str, Any]:
        """The queue in order (``position`` 0 runs next), each sequence with every step's
        status (pending, running, completed, failed, refused, skipped) and times, whether
        it may move (``movable``; ``pinned`` says why not); then ``recent``: the last
        sequences that left the queue (completed, failed or cancelled), newest first. The
        telemetry WebSocket sends ``{"type": "queue", "queue": [...]}`` on every change."""
        runtime = server.rover(rover)
        server.writer.flush()
        return {
            "rover": rover,
            "queue": queue_json(runtime, server.store),
            "recent": recent_json(runtime, server.store),
        }

    @app.post(
        "/api/rovers/{rover}/queue/{sequence_id:int}/move",
        responses={
            **AUTH_ERRORS,
            **NOT_FOUND,
            409: _error("the move is not allowed (the answer says why); nothing changed"),
            **TOO_LARGE,
            **BAD_REQUEST,
        },
    )
    def move_in_queue(
        rover: RoverName, sequence_id: SequenceId, body: MoveBody, request: Request, _: Operator
    ) -> dict[str, Any]:
        """Move a queued sequence to position ``to`` (0 runs next), the others keeping
        their order. A sequence that has started and an immediate command keep their place
        and nothing moves in front of them (409 saying so); the new order is stored before
        this answers. The queue as ``GET .../queue`` lists it."""
        runtime = server.rover(rover)
        request.state.audit_action = f"move sequence #{sequence_id} to position {body.to}"
        try:
            runtime.move(sequence_id, body.to)
        except NotQueuedError as error:
            found = server.store.get_sequence(sequence_id)
            if found is None or found["rover"] != rover:
                raise HTTPException(404, f"no sequence {sequence_id} for rover {rover!r}") from None
            raise HTTPException(409, f"{error}: it is {found['status']}") from None
        except QueueError as error:
            raise HTTPException(409, str(error)) from None
        return {"rover": rover, "queue": queue_json(runtime, server.store)}

    @app.post(
        "/api/rovers/{rover}/commands",
        status_code=201,
        responses={**AUTH_ERRORS, **NOT_FOUND, **TOO_LARGE, **BAD_REQUEST},
    )
    def immediate_command(
        rover: RoverName, body: CommandBody, request: Request, who: Operator
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
            raise HTTPException(422, _request_errors(result))
        seq_id = server.store.add_sequence(
            rover,
            f"immediate_{body.command}",
            json.dumps(source),
            "command",
            "queued",
            [],
            _diagnostics(result)["warnings"],
            _steps_json(result.sequence),
            who.name,
        )
        runtime.enqueue(seq_id, result.sequence, immediate=True)
        request.state.audit_action = f"immediate command {body.command} (#{seq_id}): queued"
        return {"id": seq_id, "status": "queued", **_diagnostics(result)}

    @app.post(
        "/api/rovers/{rover}/clock",
        responses={**AUTH_ERRORS, **NOT_FOUND, **TOO_LARGE, **BAD_REQUEST},
    )
    def set_clock(
        rover: RoverName, body: ClockBody, request: Request, _: Operator
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

    @app.get("/api/rovers/{rover}/sols", responses=NOT_FOUND)
    def sols(rover: RoverName, _: Viewer) -> list[int]:
        """Sols with telemetry."""
        server.rover(rover)
        server.writer.flush()
        return server.store.sols(rover)

    @app.get("/api/rovers/{rover}/sols/{sol}/timeline", responses=NOT_FOUND)
    def timeline(rover: RoverName, sol: Sol, _: Viewer) -> dict[str, Any]:
        """One sol: commands, NATE mode and AQF intervals, events, distance, summary."""
        runtime = server.rover(rover)
        server.writer.flush()
        found = sol_timeline(server.store, runtime, sol)
        if found is None:
            raise HTTPException(404, f"no telemetry on sol {sol}")
        return found

    @app.get("/api/rovers/{rover}/events", responses={**NOT_FOUND, **BAD_REQUEST})
    def event_log_page(
        rover: RoverName,
        _: Viewer,
        sol: Annotated[int | None, Query(ge=0, le=MAX_SOL, description="one sol")] = None,
        sol_from: Annotated[int | None, Query(ge=0, le=MAX_SOL, description="first sol")] = None,
        sol_to: Annotated[int | None, Query(ge=0, le=MAX_SOL, description="last sol")] = None,
        kind: Annotated[
            list[str] | None, Query(description=f"repeatable: {', '.join(LOG_KINDS)}")
        ] = None,
        severity: Annotated[
            list[str] | None, Query(description="repeatable: info, warning, error")
        ] = None,
        min_severity: Annotated[str | None, Query(max_length=16)] = None,
        text: Annotated[
            str | None, Query(max_length=200, description="contained, any case")
        ] = None,
        before_t_s: Annotated[float | None, Query(description="events before this TT s")] = None,
        limit: Annotated[int, Query(ge=1, le=MAX_LIMIT)] = 200,
        offset: Annotated[int, Query(ge=0, le=MAX_ID)] = 0,
    ) -> dict[str, Any]:
        """The rover's events, newest first, filtered (server.eventlog): ``{"rover",
        "kinds", "total", "offset", "limit", "events"}``; a filter that cannot be met is a
        422 naming it."""
        runtime = server.rover(rover)
        server.writer.flush()
        flt = EventFilter(
            sol=sol,
            sol_from=sol_from,
            sol_to=sol_to,
            kinds=tuple(dict.fromkeys(kind or [])),
            severities=tuple(dict.fromkeys(severity or [])),
            min_severity=min_severity,
            text=text,
            before_t_s=before_t_s,
            limit=limit,
            offset=offset,
        )
        try:
            return event_log(server.store, runtime, flt)
        except FilterError as exc:
            raise request_error(("query", exc.param), str(exc), "value_error") from exc

    add_channel_routes(app, server)  # telemetry at a glance (server.channels)

    @app.get(
        "/api/rovers/{rover}/sols/{sol}/telemetry.csv",
        response_class=Response,
        responses={200: CSV_FILE, **NOT_FOUND},
    )
    def sol_telemetry_csv(
        rover: RoverName,
        sol: Sol,
        _: Viewer,
        every: Annotated[float, Query(ge=0.0, le=86400.0)] = 0.0,
    ) -> Response:
        """One sol's frames as a CSV file to download (one per ``every`` s; frames with
        events are always kept), named ``{rover}_sol{sol}.csv``."""
        server.rover(rover)
        server.writer.flush()
        span = server.store.sol_range(rover, sol)
        if span is None:
            raise HTTPException(404, f"no telemetry on sol {sol} for rover {rover!r}")
        frames = server.store.frames(rover, span[0], span[1], every)
        disposition = f'attachment; filename="{rover}_sol{sol}.csv"'
        return Response(
            _csv(frames), media_type="text/csv", headers={"Content-Disposition": disposition}
        )

    @app.get(
        "/api/rovers/{rover}/telemetry",
        response_model=None,
        responses={
            200: {
                "description": "frames (JSON), or CSV on Accept: text/csv",
                "content": {
                    "application/json": {"schema": {"type": "array", "items": {"type": "object"}}},
                    **CSV_FILE["content"],
                },
            },
            **NOT_FOUND,
            **BAD_REQUEST,
        },
    )
    def telemetry(
        rover: RoverName,
        request: Request,
        _: Viewer,
        t_from: Annotated[float | None, Query(alias="from")] = None,
        t_to: Annotated[float | None, Query(alias="to")] = None,
        every: Annotated[float, Query(ge=0.0, le=86400.0)] = 0.0,
        limit: Annotated[int, Query(ge=1, le=200_000)] = 20_000,
    ) -> Response | list[dict[str, Any]]:
        """Frames over ``from``-``to`` (TT s), one per ``every`` s; CSV on Accept: text/csv."""
        runtime = server.rover(rover)
        server.writer.flush()
        lo = -math.inf if t_from is None else t_from
        hi = runtime.t_s if t_to is None else t_to
        if not (math.isfinite(hi) and lo <= hi):
            raise request_error(("query", "to"), "from/to: need from <= to, to finite", "range")
        frames = server.store.frames(rover, lo, hi, every, limit)
        if "text/csv" in request.headers.get("accept", ""):
            return Response(_csv(frames), media_type="text/csv")
        return frames

    # ---- limits and alarms (server.limits, server.alarms) ---------------------------

    @app.get("/api/rovers/{rover}/limits", responses=NOT_FOUND)
    def get_limits(rover: RoverName, _: Viewer) -> list[dict[str, Any]]:
        """Every channel's alarm limits for the rover: kind, direction, units, truth view
        or not, why, the levels now and by default, and who last changed them."""
        server.rover(rover)
        return server.alarms.limits(rover)

    @app.put(
        "/api/rovers/{rover}/limits/{channel}",
        responses={**AUTH_ERRORS, **NOT_FOUND, **TOO_LARGE, **BAD_REQUEST},
    )
    def put_limits(
        rover: RoverName, channel: Channel, body: LimitsBody, request: Request, who: Operator
    ) -> dict[str, Any]:
        """Change a channel's levels (stored; judged at once against the latest frame)."""
        runtime = server.rover(rover)
        levels = body.model_dump(exclude_none=False)
        if body.hysteresis is None:
            levels.pop("hysteresis")
        request.state.audit_action = f"set limits of {channel}: " + ", ".join(
            f"{k}={v}" for k, v in levels.items()
        )
        try:
            return server.alarms.set_limits(rover, channel, levels, who.name, runtime.last_frame)
        except KeyError as unknown:
            raise HTTPException(404, str(unknown.args[0])) from None
        except LimitsError as bad:
            raise request_error(("body",), str(bad), "limits") from None

    @app.delete("/api/rovers/{rover}/limits/{channel}", responses={**AUTH_ERRORS, **NOT_FOUND})
    def reset_limits(
        rover: RoverName, channel: Channel, request: Request, _: Operator
    ) -> dict[str, Any]:
        """Back to the default levels for a channel."""
        runtime = server.rover(rover)
        request.state.audit_action = f"reset limits of {channel} to the defaults"
        try:
            return server.alarms.reset_limits(rover, channel, runtime.last_frame)
        except KeyError as unknown:
            raise HTTPException(404, str(unknown.args[0])) from None

    @app.get("/api/rovers/{rover}/alarms", responses={**NOT_FOUND, **BAD_REQUEST})
    def list_alarms(
        rover: RoverName,
        _: Viewer,
        active: Annotated[
            bool | None,
            Query(
                description="true: still listed (not both acknowledged and cleared); "
                "false: done; absent: all"
            ),
        ] = None,
        limit: Annotated[int, Query(ge=1, le=10_000)] = 500,
    ) -> list[dict[str, Any]]:
        """A rover's alarms, newest first."""
        server.rover(rover)
        return server.alarms.listed(rover, active, limit)

    @app.post(
        "/api/alarms/{alarm_id}/acknowledge",
        responses={**AUTH_ERRORS, **NOT_FOUND, 409: _error("acknowledged already")},
    )
    def acknowledge_alarm(alarm_id: AlarmId, request: Request, who: Operator) -> dict[str, Any]:
        """Acknowledge an alarm (who and when are kept; it leaves the list once cleared)."""
        request.state.audit_action = f"acknowledge alarm #{alarm_id}"
        try:
            alarm = server.alarms.acknowledge(alarm_id, who.name)
        except AlarmError as refused:
            raise HTTPException(refused.status, str(refused)) from None
        request.state.audit_rover = alarm["rover"]
        request.state.audit_action = f"acknowledge alarm #{alarm_id} ({alarm['channel']})"
        return alarm

    def scene_port(rover: str) -> int:
        server.rover(rover)
        if rover not in server.scenes:
            raise HTTPException(404, "the 3D view is off (roverops serve starts it)")
        return server.scenes[rover].port

    @app.get("/viser/{rover}", include_in_schema=False)
    def viser_root(rover: str, _: Viewer) -> RedirectResponse:
        scene_port(rover)
        return RedirectResponse(f"/viser/{rover}/")

    @app.get("/viser/{rover}/{path:path}", include_in_schema=False)
    async def viser_page(rover: str, path: str, _: Viewer) -> Response:
        """The rover's viser client (and anything else viser serves), proxied."""
        got = await run_in_threadpool(fetch, scene_port(rover), path)
        return Response(got.body, status_code=got.status, media_type=got.content_type)

    @app.websocket("/viser/{rover}")
    async def viser_socket(websocket: WebSocket, rover: str) -> None:
        """The viser client's WebSocket, relayed to the rover's viser server."""
        if not await _websocket_allowed(websocket):
            return
        if rover not in server.scenes:
            await websocket.close(code=4404)
            return
        await relay(websocket, server.scenes[rover].port)

    @app.get("/api/rovers/{rover}/scene", responses=NOT_FOUND)
    def scene_state(rover: RoverName, _: Viewer) -> dict[str, Any]:
        """The 3D view: its URL on this origin and how many frames it has drawn."""
        scene_port(rover)
        return {"url": f"/viser/{rover}/", "frames_drawn": server.scenes[rover].frames_drawn}

    @app.websocket("/ws/rovers/{rover}/telemetry")
    async def live(websocket: WebSocket, rover: str) -> None:
        """Frames as they are played out, at most MAX_RATE_HZ per second of wall time, and
        notices (``server.hub``) as they come."""
        if not await _websocket_allowed(websocket):
            return
        if rover not in server.rovers:
            await websocket.close(code=4404)
            return
        await websocket.accept()
        client = server.hub.subscribe(rover)
        period = 1.0 / MAX_RATE_HZ

        async def send_frames(done: anyio.CancelScope) -> None:
            with contextlib.suppress(WebSocketDisconnect, RuntimeError):  # the browser left
                next_send = 0.0
                while True:
                    message = await next_message(client)
                    await websocket.send_json(message)
                    if "type" in message:  # a notice: never held back by the frame rate
                        continue
                    next_send = max(next_send + period, time.monotonic())  # >= period apart
                    wait = next_send - time.monotonic()
                    if wait > 0:
                        await asyncio.sleep(wait)
            done.cancel()

        async def until_closed(done: anyio.CancelScope) -> None:
            # A rover at rest sends nothing for a long time: listening is how a closed
            # browser, or the server shutting down, ends this handler (and its subscription).
            while (await websocket.receive())["type"] != "websocket.disconnect":
                pass
            done.cancel()

        try:
            async with anyio.create_task_group() as tasks:
                tasks.start_soon(send_frames, tasks.cancel_scope)
                tasks.start_soon(until_closed, tasks.cancel_scope)
        finally:
            server.hub.unsubscribe(rover, client)

    async def _websocket_allowed(websocket: WebSocket) -> bool:
        """The checks of a WebSocket handshake, before it is accepted (a browser then sees
        HTTP 403): a page of another origin is refused (``server.origin``: the sign-in
        cookie must not let another site read), then the viewer check (header or cookie
        token), closing with 4401 (no token) or 4403 (wrong token)."""
        if not origin_allowed(websocket.headers, websocket.url.scheme):
            await websocket.close(code=4403, reason="cross-origin WebSocket refused")
            return False
        try:
            who = await run_in_threadpool(
                websocket_principal, server, websocket.headers, websocket.cookies
            )
        except HTTPException as refused:
            code = 4401 if refused.status_code == 401 else 4403
            await websocket.close(code=code, reason=str(refused.detail)[:120])
            return False
        websocket.state.principal = who
        return True

    # ---- accounts -------------------------------------------------------------------

    def _principal_json(who: Principal) -> dict[str, Any]:
        return {"name": who.name, "role": who.role, "public_read": config.public_read,
                "roles": list(ROLES)}  # fmt: skip

    @app.get("/api/me")
    def me(who: Viewer) -> dict[str, Any]:
        """Who this request acts as (``anonymous`` with no role when reading without a
        token), and whether reading needs a token on this server."""
        return _principal_json(who)

    @app.post("/api/session", responses=BAD_REQUEST)
    def sign_in(body: SessionBody, request: Request) -> JSONResponse:
        """Sign this browser in: the token is checked and kept in an HttpOnly cookie that
        the 3D view and the telemetry WebSocket send (it counts for reading only)."""
        request.state.audit_action = "sign in"
        try:
            who = server.accounts.authenticate(body.token)
        except TokenRefusedError as refused:
            raise HTTPException(403, f"wrong token: {refused}") from None
        request.state.principal = who
        response = JSONResponse(_principal_json(who))
        secure = request.url.scheme == "https"
        response.set_cookie(COOKIE, body.token, httponly=True, samesite="strict", secure=secure)
        return response

    @app.delete("/api/session")
    def sign_out(request: Request) -> JSONResponse:
        """Sign this browser out (forget the cookie)."""
        request.state.audit_action = "sign out"
        response = JSONResponse({"signed_out": True})
        response.delete_cookie(COOKIE, httponly=True, samesite="strict")
        return response

    @app.get("/api/users")
    def list_users(_: Admin) -> list[dict[str, Any]]:
        """Every user: name, role, creation time and how many live tokens it holds."""
        return server.accounts.list_users()

    @app.post("/api/users", status_code=201, responses={409: _error("the user exists")})
    def add_user(body: NewUserBody, request: Request, _: Admin) -> dict[str, Any]:
        """A new user and its first token (shown in this answer only; stored hashed)."""
        request.state.audit_action = f"add user {body.name} as {body.role}"
        try:
            issued = server.accounts.add_user(body.name, body.role, body.expires_days)
        except AccountError as error:
            raise _account_error(error) from None
        return {"name": issued.name, "role": issued.role, "token": issued.token,
                "expires_at": issued.expires_at.isoformat()}  # fmt: skip

    @app.patch("/api/users/{name}", responses=NOT_FOUND)
    def change_role(name: str, body: RoleBody, request: Request, _: Admin) -> dict[str, Any]:
        """Give a user another role."""
        request.state.audit_action = f"set the role of {name} to {body.role}"
        try:
            server.accounts.set_role(name, body.role)
        except AccountError as error:
            raise _account_error(error) from None
        return {"name": name, "role": body.role}

    @app.post("/api/users/{name}/tokens", status_code=201, responses=NOT_FOUND)
    def new_token(name: str, body: TokenBody, request: Request, _: Admin) -> dict[str, Any]:
        """Another token for a user (shown in this answer only)."""
        request.state.audit_action = f"issue a token to {name}"
        try:
            issued = server.accounts.issue_token(name, body.expires_days)
        except AccountError as error:
            raise _account_error(error) from None
        return {"name": issued.name, "role": issued.role, "token": issued.token,
                "expires_at": issued.expires_at.isoformat()}  # fmt: skip

    @app.delete("/api/users/{name}/tokens", responses=NOT_FOUND)
    def revoke_tokens(name: str, request: Request, _: Admin) -> dict[str, Any]:
        """Revoke every live token of a user."""
        request.state.audit_action = f"revoke the tokens of {name}"
        try:
            revoked = server.accounts.revoke(name)
        except AccountError as error:
            raise _account_error(error) from None
        return {"name": name, "revoked": revoked}

    @app.get(
        "/api/audit",
        response_model=None,
        responses={
            200: {
                "description": "audit rows, newest first (JSON), or CSV",
                "content": {
                    "application/json": {"schema": {"type": "array", "items": {"type": "object"}}},
                    **CSV_FILE["content"],
                },
            },
            **BAD_REQUEST,
        },
    )
    def audit(
        request: Request,
        _: Admin,
        user: Annotated[str | None, Query(max_length=64)] = None,
        rover: Annotated[str | None, Query(max_length=64)] = None,
        result: Literal["accepted", "refused"] | None = None,
        method: Literal["POST", "PUT", "PATCH", "DELETE"] | None = None,
        since: Annotated[str | None, Query(max_length=40, json_schema_extra=ISO_TIME)] = None,
        until: Annotated[str | None, Query(max_length=40, json_schema_extra=ISO_TIME)] = None,
        limit: Annotated[int, Query(ge=1, le=10_000)] = 1000,
        format: Literal["json", "csv"] | None = None,  # the query parameter's own name
    ) -> Response | list[dict[str, Any]]:
        """The audit log, newest first: every accepted or refused mutating request with who,
        when (UTC and the rover's sol and LMST), what and the result. Filters combine; CSV
        with ``format=csv`` or ``Accept: text/csv``."""
        lo, hi = _utc(since, "since"), _utc(until, "until")
        rows = server.audit.query(user, rover, result, method, lo, hi, limit)
        if format == "csv" or (format is None and "text/csv" in request.headers.get("accept", "")):
            return Response(as_csv(rows), media_type="text/csv")
        return rows

    return app


ISO_TIME = {"format": "date-time", "examples": ["2026-12-02T05:00:00+00:00"]}


def _utc(text: str | None, name: str) -> datetime | None:
    """A query's ISO 8601 date and time as aware UTC (without an offset: UTC); a number or
    a date alone is refused, as the schema's ``date-time`` says."""
    if text is None:
        return None
    try:
        if "T" not in text.upper():
            raise ValueError("no time")
        value = datetime.fromisoformat(text)
    except ValueError:
        raise request_error(
            ("query", name), f"{name}: an ISO 8601 date and time", "datetime"
        ) from None
    return value.replace(tzinfo=UTC) if value.tzinfo is None else value.astimezone(UTC)


CSV_COLUMNS = (
    "t_s", "sol", "lmst_h", "nate_mode", "aqf", "site_index", "imu_integration_s",
    "gyro_counter_s", "tilt_est_deg", "tilt_accel_deg", "hga_error_deg", "hga_margin_deg",
    "hga_margin_predicted_deg", "vo_failures_in_row",
    "earth_up", "attitude_error_deg", "position_error_m", "command", "rocker_deg",
)  # fmt: skip
CSV_VECTORS = {
    "q_b_ll_est": 4, "q_b_ll_true": 4, "p_s_est": 3, "p_s_true": 3, "p_mission_est": 3,
    "p_mission_true": 3, "bogie_deg": 2, "steer_deg": 4, "sun_ll_true": 3,
    "earth_ll_true": 3, "hga_boresight_ll_true": 3,
}  # fmt: skip
# Each estimator that can run beside SAPP (sim.loop.side.kinematic) has its columns in every
# CSV, empty where it did not run: columns never depend on the rover's configuration.
CSV_SIDE_ESTIMATORS = tuple(e for e in ESTIMATORS if e != "sapp")
CSV_SIDE_FIELDS = ("position_error_m", "attitude_error_deg")
CSV_SIDE_VECTORS = {"p_mission": 3, "q_b_ll": 4}


def _side_cells(f: dict[str, Any]) -> list[Any]:
    cells: list[Any] = []
    for name in CSV_SIDE_ESTIMATORS:
        side = (f.get("estimators") or {}).get(name) or {}
        cells += [side.get(c) for c in CSV_SIDE_FIELDS]
        for v, n in CSV_SIDE_VECTORS.items():
            values = list(side.get(v) or [])
            cells += values + [None] * (n - len(values))
    return cells


def _csv(frames: list[dict[str, Any]]) -> str:
    """Frames as CSV, one column per vector component, then each side estimator's figures
    (``<name>_position_error_m``, ...); a figure a frame lacks (NaN, an estimator that did not
    run, or a field frames stored by an older version do not have) is an empty cell."""
    out = io.StringIO()
    writer = csv.writer(out)
    header = list(CSV_COLUMNS)
    for v, n in CSV_VECTORS.items():
        header += [f"{v}_{i}" for i in range(n)]
    for name in CSV_SIDE_ESTIMATORS:
        header += [f"{name}_{c}" for c in CSV_SIDE_FIELDS]
        for v, n in CSV_SIDE_VECTORS.items():
            header += [f"{name}_{v}_{i}" for i in range(n)]
    header.append("events")
    writer.writerow(header)
    for f in frames:
        row = [f.get(c) for c in CSV_COLUMNS]
        for v, n in CSV_VECTORS.items():
            values = list(f.get(v) or [])
            row += values + [None] * (n - len(values))
        row += _side_cells(f)
        row.append("; ".join(e["text"] for e in f.get("events", [])))
        writer.writerow(row)
    return out.getvalue()


def data_dir_url(data_dir: Path) -> str:
    """The embedded SQLite database under ``data_dir``."""
    data_dir.mkdir(parents=True, exist_ok=True)
    return f"sqlite:///{(data_dir / 'roverops.db').resolve()}"
