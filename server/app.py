"""The operations server: FastAPI over the rover runtimes, storage and live telemetry.

``create_app(config)`` builds the app; ``roverops serve`` runs it with uvicorn. Viewing
needs no token; uploading, commanding and clock control need the operator token
(``Authorization: Bearer <token>`` or ``X-Operator-Token``): missing 401, wrong 403, and
nothing changes. Request bodies are validated (422 with the reason); uploads above
``max_upload_bytes`` get 413. OpenAPI at ``/docs``.
"""

from __future__ import annotations

import asyncio
import contextlib
import csv
import hmac
import io
import json
import math
import re
import secrets
import time
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any, Literal

import anyio
from fastapi import Depends, FastAPI, Header, HTTPException, Query, Request, WebSocket
from fastapi.responses import FileResponse, JSONResponse, RedirectResponse, Response
from fastapi.staticfiles import StaticFiles
from pydantic import BaseModel, ConfigDict, Field
from starlette.concurrency import run_in_threadpool
from starlette.websockets import WebSocketDisconnect

from sequences import commands as cmd
from sequences.language import Sequence, SequenceStep
from sequences.validate import ValidationContext, ValidationResult, validate
from server.hub import MAX_RATE_HZ, TelemetryHub, next_message
from server.origin import origin_allowed
from server.runtime import MAX_SPEED, ROVERS, RoverRuntime
from server.scene3d import RoverScene
from server.storage import BatchWriter, Store
from server.timeline import sol_timeline
from server.viser_proxy import fetch, relay
from sim.mars_frames import earth_ll_truth, elevation_rad
from sim.marsclock import t_s_for_sol_lmst
from sim.side_estimators import ESTIMATORS

MAX_UPLOAD_BYTES = 1_000_000
WEB_DIR = Path(__file__).resolve().parent.parent / "web"  # the console, served as is


@dataclass
class ServerConfig:
    """Settings of one server (``roverops serve`` fills them from flags and ROVEROPS_*)."""

    database_url: str
    operator_token: str = field(default_factory=lambda: secrets.token_urlsafe(18))
    max_upload_bytes: int = MAX_UPLOAD_BYTES
    start_clocks: bool = True
    initial_speed: float = 1.0
    viewer_3d: bool = False  # a viser 3D view per rover under /viser/{rover}/
    # what runs beside SAPP on a new rover (sim.side_estimators); a rover restored from a
    # checkpoint keeps the estimators it was started with
    estimators: tuple[str, ...] = ("sapp",)


class ClockBody(BaseModel):
    """``POST /api/rovers/{rover}/clock``: pause/resume and the speed factor."""

    model_config = ConfigDict(extra="forbid")
    action: Literal["pause", "resume"] | None = None
    speed: float | Literal["max"] | None = Field(
        default=None, description=f"speed factor, 1 to {MAX_SPEED:g}, or 'max'"
    )


class CommandBody(BaseModel):
    """``POST /api/rovers/{rover}/commands``: one immediate command."""

    model_config = ConfigDict(extra="forbid")
    command: str = Field(description="a keyword of the command dictionary, e.g. DRIVE_STRAIGHT")
    args: dict[str, Any] = Field(default_factory=dict)


class ValidateBody(BaseModel):
    """``POST /api/sequences/validate`` (and JSON uploads): text or JSON sequence."""

    model_config = ConfigDict(extra="forbid")
    text: str | None = None
    sequence: dict[str, Any] | None = None
    rover: str | None = Field(default=None, description="validate against this rover's state")


class Server:
    """The app's state: the runtimes, storage, the writer and the hub."""

    def __init__(self, config: ServerConfig) -> None:
        self.config = config
        self.store = Store(config.database_url)
        self.writer = BatchWriter(self.store)
        self.hub = TelemetryHub()
        self.rovers: dict[str, RoverRuntime] = {}
        for name, spec in ROVERS.items():
            saved = self.store.load_checkpoint(name)
            runtime = (
                RoverRuntime.restore(spec, saved[1])
                if saved
                else RoverRuntime(spec, estimators=config.estimators)
            )
            if saved is None:
                runtime.set_clock(speed=config.initial_speed)
            if saved is not None:
                self._resume(runtime)
            runtime.listeners.append(self._frames)
            runtime.on_command = self._command
            runtime.on_sequence = self._sequence
            runtime.on_checkpoint = self.writer.checkpoint
            self.rovers[name] = runtime
        self.scenes: dict[str, RoverScene] = {}
        if config.viewer_3d:
            self.scenes = {name: RoverScene(rt, self.store) for name, rt in self.rovers.items()}

    def _resume(self, runtime: RoverRuntime) -> None:
        """After a restart: no frame stored twice, and every accepted sequence the
        checkpoint does not hold (accepted or started after it) queued again, in order."""
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
            runtime.enqueue(summary["id"], result.sequence)

    def _frames(self, rover: str, frames: list[dict[str, Any]]) -> None:
        self.writer.frames(rover, frames)
        events = [(float(f["t_s"]), e) for f in frames for e in f.get("events", [])]
        if events:
            self.writer.events(rover, events)
        self.hub.publish(rover, frames)

    def _command(self, rover: str, report: dict[str, Any]) -> None:
        self.writer.command(rover, **report)

    def _sequence(self, sequence_id: int, status: str, detail: str | None) -> None:
        self.writer.flush()
        self.store.set_sequence_status(sequence_id, status, detail)

    def start(self) -> None:
        self.writer.start()
        for scene in self.scenes.values():
            scene.start()
        if self.config.start_clocks:
            for runtime in self.rovers.values():
                runtime.start()

    def stop(self) -> None:
        for runtime in self.rovers.values():
            runtime.stop()
        for scene in self.scenes.values():
            scene.stop()
        self.writer.stop()
        self.store.close()

    def rover(self, name: str) -> RoverRuntime:
        if name not in self.rovers:
            raise HTTPException(404, f"unknown rover {name!r}; known: {', '.join(self.rovers)}")
        return self.rovers[name]

    def context(self, runtime: RoverRuntime) -> ValidationContext:
        """What validation warnings need to know of a rover, from its state now."""
        sim = runtime.session.sim
        frame = runtime.last_frame or {}
        lat, lon = sim.lat_rad, sim.lon_east_rad
        mission = runtime.spec.mission

        def earth_elevation_deg(t_s: float) -> float:
            return math.degrees(float(elevation_rad(earth_ll_truth(t_s, lat, lon))))

        return ValidationContext(
            start_t_s=runtime.t_s,
            lmst_h=runtime.lmst_h,
            sol=runtime.sol,
            t_s_for=lambda sol, lmst_h: t_s_for_sol_lmst(mission, sol, lmst_h),
            earth_elevation_deg=earth_elevation_deg,
            aqf=frame.get("aqf", runtime.session.nate.aqf.paper_name),
            imu_integration_s=float(frame.get("imu_integration_s", 0.0)),
            articulating=runtime.session.nate.mode.value == "Articulate",
        )


def _diagnostics(result: ValidationResult) -> dict[str, Any]:
    def as_list(items: list[Any]) -> list[dict[str, Any]]:
        return [
            {"line": d.line, "column": d.column, "code": d.code, "message": d.message}
            for d in items
        ]

    return {"errors": as_list(result.errors), "warnings": as_list(result.warnings)}


def _steps_json(sequence: Sequence) -> list[dict[str, Any]]:
    return [_step_json(s) for s in sequence.steps]


def _step_json(step: SequenceStep) -> dict[str, Any]:
    return {
        "line": step.line,
        "command": step.command.name,
        "args": step.command.arguments(),
        "time": step.time_tag.kind,
    }


def operator(
    request: Request,
    authorization: Annotated[str | None, Header()] = None,
    x_operator_token: Annotated[str | None, Header()] = None,
) -> None:
    """The operator token check: missing 401, wrong 403 (before anything changes)."""
    expected: str = request.app.state.server.config.operator_token
    token = x_operator_token
    if authorization and authorization.lower().startswith("bearer "):
        token = authorization[7:].strip()
    if not token:
        raise HTTPException(401, "operator token required", {"WWW-Authenticate": "Bearer"})
    if not hmac.compare_digest(token.encode(), expected.encode()):
        raise HTTPException(403, "wrong operator token")


Operator = Annotated[None, Depends(operator)]


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
    )
    app.state.server = server

    @app.get("/", include_in_schema=False)
    def console_page() -> FileResponse:
        """The operators' console (``web/``)."""
        return FileResponse(WEB_DIR / "index.html")

    app.mount("/static", StaticFiles(directory=WEB_DIR), name="static")

    @app.get("/api/rovers")
    def list_rovers() -> list[dict[str, Any]]:
        """The rovers and their clocks."""
        return [
            {k: v for k, v in r.state().items() if k != "frame"} for r in server.rovers.values()
        ]

    @app.get("/api/rovers/{rover}/state")
    def rover_state(rover: str) -> dict[str, Any]:
        """Clock, queue, the executing command and the latest telemetry frame."""
        return server.rover(rover).state()

    @app.get("/api/commands")
    def command_dictionary() -> list[dict[str, Any]]:
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

    async def _read_upload(request: Request) -> tuple[str | dict[str, Any], str]:
        size = int(request.headers.get("content-length") or 0)
        if size > config.max_upload_bytes:
            raise HTTPException(413, f"upload over {config.max_upload_bytes} bytes")
        body = await request.body()
        if len(body) > config.max_upload_bytes:
            raise HTTPException(413, f"upload over {config.max_upload_bytes} bytes")
        ctype = request.headers.get("content-type", "")
        if ctype.startswith("multipart/form-data"):
            form = await request.form()
            upload = form.get("file")
            if upload is None or isinstance(upload, str):
                raise HTTPException(422, "multipart upload needs a 'file' part")
            data = await upload.read()
            name = upload.filename or "upload"
            return _decode(data, name), "json" if name.endswith(".json") else "text"
        if ctype.startswith("application/json"):
            try:
                parsed = json.loads(body)
            except json.JSONDecodeError as exc:
                raise HTTPException(422, f"body: not JSON: {exc}") from exc
            if isinstance(parsed, dict) and "text" in parsed and isinstance(parsed["text"], str):
                return parsed["text"], "text"
            if isinstance(parsed, dict) and isinstance(parsed.get("sequence"), (dict, list)):
                return parsed["sequence"], "json"
            if isinstance(parsed, (dict, list)):
                return parsed if isinstance(parsed, dict) else {"steps": parsed}, "json"
            raise HTTPException(422, "body: a sequence object, or {'text': ...}")
        return _decode(body, "body"), "text"

    @app.post("/api/rovers/{rover}/sequences", status_code=201)
    async def upload_sequence(rover: str, request: Request, _: Operator) -> JSONResponse:
        """Validate, store and queue a sequence (text, JSON, or a multipart file)."""
        runtime = server.rover(rover)
        source, fmt = await _read_upload(request)
        result = await run_in_threadpool(validate, source, server.context(runtime))
        text = source if isinstance(source, str) else json.dumps(source)
        name = (result.sequence.name if result.sequence else None) or _declared_name(source)
        diags = _diagnostics(result)
        if result.errors or result.sequence is None:
            seq_id = await run_in_threadpool(
                server.store.add_sequence,
                rover, name, text, fmt, "rejected", diags["errors"], diags["warnings"], [],
            )  # fmt: skip
            return JSONResponse({"id": seq_id, "status": "rejected", **diags}, status_code=422)
        steps = _steps_json(result.sequence)
        seq_id = await run_in_threadpool(
            server.store.add_sequence,
            rover,
            name,
            text,
            fmt,
            "queued",
            [],
            diags["warnings"],
            steps,
        )
        runtime.enqueue(seq_id, result.sequence)
        return JSONResponse({"id": seq_id, "status": "queued", **diags}, status_code=201)

    @app.post("/api/sequences/validate")
    async def validate_only(request: Request) -> dict[str, Any]:
        """Validation only: nothing stored. ``?rover=`` adds that rover's warnings."""
        source, _fmt = await _read_upload(request)
        rover = request.query_params.get("rover")
        context = server.context(server.rover(rover)) if rover else None
        result = await run_in_threadpool(validate, source, context)
        return {"valid": not result.errors, **_diagnostics(result)}

    @app.get("/api/rovers/{rover}/sequences")
    def list_sequences(rover: str) -> list[dict[str, Any]]:
        """Sequences of a rover, newest first."""
        server.rover(rover)
        return server.store.list_sequences(rover)

    @app.get("/api/sequences/{sequence_id}")
    def get_sequence(sequence_id: int) -> dict[str, Any]:
        """One sequence with its source, steps, status, errors and warnings."""
        found = server.store.get_sequence(sequence_id)
        if found is None:
            raise HTTPException(404, f"no sequence {sequence_id}")
        return found

    @app.delete("/api/sequences/{sequence_id}")
    def cancel_sequence(sequence_id: int, _: Operator) -> dict[str, Any]:
        """Cancel a queued sequence (a running one stops after its current command)."""
        found = server.store.get_sequence(sequence_id)
        if found is None:
            raise HTTPException(404, f"no sequence {sequence_id}")
        runtime = server.rover(found["rover"])
        if not runtime.cancel(sequence_id):
            raise HTTPException(409, f"sequence {sequence_id} is {found['status']}, not queued")
        server.store.set_sequence_status(sequence_id, "cancelled", "cancelled by an operator")
        return {"id": sequence_id, "status": "cancelled"}

    @app.post("/api/rovers/{rover}/commands", status_code=201)
    def immediate_command(rover: str, body: CommandBody, _: Operator) -> dict[str, Any]:
        """One command, run before the next queued step."""
        runtime = server.rover(rover)
        source = {
            "name": f"immediate_{body.command}",
            "steps": [{"command": body.command, "args": body.args}],
        }
        result = validate(source, server.context(runtime))
        if result.errors or result.sequence is None:
            raise HTTPException(422, _diagnostics(result))
        seq_id = server.store.add_sequence(
            rover,
            f"immediate_{body.command}",
            json.dumps(source),
            "command",
            "queued",
            [],
            _diagnostics(result)["warnings"],
            _steps_json(result.sequence),
        )
        runtime.enqueue(seq_id, result.sequence, immediate=True)
        return {"id": seq_id, "status": "queued", **_diagnostics(result)}

    @app.post("/api/rovers/{rover}/clock")
    def set_clock(rover: str, body: ClockBody, _: Operator) -> dict[str, Any]:
        """Pause, resume, or set the speed factor (1 to MAX_SPEED, or 'max')."""
        runtime = server.rover(rover)
        speed: float | None = None
        if body.speed == "max":
            speed = math.inf
        elif body.speed is not None:
            if not (isinstance(body.speed, (int, float)) and 1.0 <= body.speed <= MAX_SPEED):
                raise HTTPException(422, f"speed: must be 1 to {MAX_SPEED:g} or 'max'")
            speed = float(body.speed)
        running = None if body.action is None else body.action == "resume"
        runtime.set_clock(running=running, speed=speed)
        clock: dict[str, Any] = runtime.state()["clock"]
        return clock

    @app.get("/api/rovers/{rover}/sols")
    def sols(rover: str) -> list[int]:
        """Sols with telemetry."""
        server.rover(rover)
        server.writer.flush()
        return server.store.sols(rover)

    @app.get("/api/rovers/{rover}/sols/{sol}/timeline")
    def timeline(rover: str, sol: int) -> dict[str, Any]:
        """One sol: commands, NATE mode and AQF intervals, events, distance, summary."""
        runtime = server.rover(rover)
        server.writer.flush()
        found = sol_timeline(server.store, runtime, sol)
        if found is None:
            raise HTTPException(404, f"no telemetry on sol {sol}")
        return found

    @app.get("/api/rovers/{rover}/sols/{sol}/telemetry.csv", response_class=Response)
    def sol_telemetry_csv(
        rover: str,
        sol: int,
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

    @app.get("/api/rovers/{rover}/telemetry", response_model=None)
    def telemetry(
        rover: str,
        request: Request,
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
            raise HTTPException(422, "from/to: need from <= to")
        frames = server.store.frames(rover, lo, hi, every, limit)
        if "text/csv" in request.headers.get("accept", ""):
            return Response(_csv(frames), media_type="text/csv")
        return frames

    def scene_port(rover: str) -> int:
        server.rover(rover)
        if rover not in server.scenes:
            raise HTTPException(404, "the 3D view is off (roverops serve starts it)")
        return server.scenes[rover].port

    @app.get("/viser/{rover}", include_in_schema=False)
    def viser_root(rover: str) -> RedirectResponse:
        scene_port(rover)
        return RedirectResponse(f"/viser/{rover}/")

    @app.get("/viser/{rover}/{path:path}", include_in_schema=False)
    async def viser_page(rover: str, path: str) -> Response:
        """The rover's viser client (and anything else viser serves), proxied."""
        got = await run_in_threadpool(fetch, scene_port(rover), path)
        return Response(got.body, status_code=got.status, media_type=got.content_type)

    @app.websocket("/viser/{rover}")
    async def viser_socket(websocket: WebSocket, rover: str) -> None:
        """The viser client's WebSocket, relayed to the rover's viser server."""
        if not origin_allowed(websocket.headers, websocket.url.scheme):
            await websocket.close(code=4403)  # before accept: a browser sees HTTP 403
            return
        if rover not in server.scenes:
            await websocket.close(code=4404)
            return
        await relay(websocket, server.scenes[rover].port)

    @app.get("/api/rovers/{rover}/scene")
    def scene_state(rover: str) -> dict[str, Any]:
        """The 3D view: its URL on this origin and how many frames it has drawn."""
        scene_port(rover)
        return {"url": f"/viser/{rover}/", "frames_drawn": server.scenes[rover].frames_drawn}

    @app.websocket("/ws/rovers/{rover}/telemetry")
    async def live(websocket: WebSocket, rover: str) -> None:
        """Frames as they are played out, at most MAX_RATE_HZ per second of wall time."""
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

    return app


_SEQUENCE_LINE = re.compile(r"^\s*SEQUENCE\s+([A-Za-z0-9_-]{1,64})\s*(?:#.*)?$", re.MULTILINE)


def _declared_name(source: str | dict[str, Any]) -> str:
    """The name a sequence declares (its SEQUENCE line, or JSON ``name``), even when other
    lines have errors; ``unnamed`` if it declares none."""
    if isinstance(source, dict):
        name = source.get("name")
        return name if isinstance(name, str) and 0 < len(name) <= 64 else "unnamed"
    found = _SEQUENCE_LINE.search(source)
    return found.group(1) if found else "unnamed"


def _decode(data: bytes, name: str) -> str:
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise HTTPException(422, f"{name}: not UTF-8 text ({exc.reason})") from exc


CSV_COLUMNS = (
    "t_s", "sol", "lmst_h", "nate_mode", "aqf", "site_index", "imu_integration_s",
    "gyro_counter_s", "tilt_est_deg", "tilt_accel_deg", "hga_error_deg", "hga_margin_deg",
    "earth_up", "attitude_error_deg", "position_error_m", "command", "rocker_deg",
)  # fmt: skip
CSV_VECTORS = {
    "q_b_ll_est": 4, "q_b_ll_true": 4, "p_s_est": 3, "p_s_true": 3, "p_mission_est": 3,
    "p_mission_true": 3, "bogie_deg": 2, "steer_deg": 4, "sun_ll_true": 3,
    "earth_ll_true": 3, "hga_boresight_ll_true": 3,
}  # fmt: skip
# Each estimator that can run beside SAPP (sim.side_estimators) has its columns in every
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
        row.append("; ".join(f.get("events", [])))
        writer.writerow(row)
    return out.getvalue()


def data_dir_url(data_dir: Path) -> str:
    """The embedded SQLite database under ``data_dir``."""
    data_dir.mkdir(parents=True, exist_ok=True)
    return f"sqlite:///{(data_dir / 'roverops.db').resolve()}"
