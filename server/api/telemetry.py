"""Telemetry: sols with data, a sol's timeline, frames over a span (JSON or CSV), a sol's
CSV file, the live WebSocket, and the JSON schemas of a frame's two records (the rover's
downlink and the simulator's truth)."""

from __future__ import annotations

import asyncio
import contextlib
import math
import time
from typing import Annotated, Any

import anyio
from fastapi import Query, Request, WebSocket
from fastapi.responses import Response
from pydantic import TypeAdapter
from starlette.websockets import WebSocketDisconnect

from server.access.auth import Viewer
from server.access.truth_view import truth_refused
from server.api.answers import Frame, RecordSchema, Timeline, UnionSchema, WsMessage
from server.api.deps import (
    BAD_REQUEST,
    CSV_FILE,
    NOT_FOUND,
    RoverName,
    SeesTruth,
    ServerDep,
    Sol,
    connection_sees_truth,
    error_doc,
    router,
    websocket_allowed,
)
from server.api.telemetry_csv import frames_csv
from server.errors import NotFoundError
from server.hub import MAX_RATE_HZ, next_message
from server.timeline import sol_timeline
from server.validation.uploads import request_error
from sim.loop.downlink import downlink_schema
from sim.scoring.truth import truth_schema

routes = router()


@routes.get("/api/rovers/{rover}/sols", responses=NOT_FOUND)
def sols(server: ServerDep, rover: RoverName, _: Viewer) -> list[int]:
    """Sols with telemetry."""
    server.rover(rover)
    return server.store.sols(rover)


@routes.get("/api/rovers/{rover}/sols/{sol}/timeline", response_model=Timeline, responses=NOT_FOUND)
def timeline(
    server: ServerDep, rover: RoverName, sol: Sol, _: Viewer, truth: SeesTruth
) -> dict[str, Any]:
    """One sol: commands, NATE mode and AQF intervals, events, distance, summary, and in
    the truth view its ``truth`` part (the true distance, the errors, the true margin)."""
    runtime = server.rover(rover)
    found = sol_timeline(server.store, runtime, sol, truth)
    if found is None:
        raise NotFoundError(f"no telemetry on sol {sol}")
    return found


@routes.get(
    "/api/rovers/{rover}/sols/{sol}/telemetry.csv",
    response_class=Response,
    responses={200: CSV_FILE, **NOT_FOUND},
)
def sol_telemetry_csv(
    server: ServerDep,
    rover: RoverName,
    sol: Sol,
    _: Viewer,
    truth: SeesTruth,
    every: Annotated[float, Query(ge=0.0, le=86400.0)] = 0.0,
) -> Response:
    """One sol's frames as a CSV file to download (one per ``every`` s; frames with
    events are always kept), named ``{rover}_sol{sol}.csv``; the truth's columns only in
    the truth view."""
    server.rover(rover)
    span = server.store.sol_range(rover, sol)
    if span is None:
        raise NotFoundError(f"no telemetry on sol {sol} for rover {rover!r}")
    frames = server.store.frames(rover, span[0], span[1], every, with_truth=truth)
    disposition = f'attachment; filename="{rover}_sol{sol}.csv"'
    return Response(
        frames_csv(frames, truth),
        media_type="text/csv",
        headers={"Content-Disposition": disposition},
    )


@routes.get(
    "/api/rovers/{rover}/telemetry",
    response_model=None,
    responses={
        200: {
            "description": "frames (JSON), or CSV on Accept: text/csv",
            "content": {
                **CSV_FILE["content"],
            },
            "model": list[Frame],  # type: ignore[valid-type]
        },
        **NOT_FOUND,
        **BAD_REQUEST,
    },
)
def telemetry(
    server: ServerDep,
    rover: RoverName,
    request: Request,
    _: Viewer,
    truth: SeesTruth,
    t_from: Annotated[float | None, Query(alias="from")] = None,
    t_to: Annotated[float | None, Query(alias="to")] = None,
    every: Annotated[float, Query(ge=0.0, le=86400.0)] = 0.0,
    limit: Annotated[int, Query(ge=1, le=200_000)] = 20_000,
) -> Response | list[dict[str, Any]]:
    """Frames over ``from``-``to`` (TT s), one per ``every`` s; CSV on Accept: text/csv.
    Each frame is the downlink record, merged with its truth record in the truth view."""
    runtime = server.rover(rover)
    lo = -math.inf if t_from is None else t_from
    hi = runtime.t_s if t_to is None else t_to
    if not (math.isfinite(hi) and lo <= hi):
        raise request_error(("query", "to"), "from/to: need from <= to, to finite", "range")
    frames = server.store.frames(rover, lo, hi, every, limit, with_truth=truth)
    if "text/csv" in request.headers.get("accept", ""):
        return Response(frames_csv(frames, truth), media_type="text/csv")
    return frames


@routes.websocket("/ws/rovers/{rover}/telemetry")
async def live(server: ServerDep, websocket: WebSocket, rover: str) -> None:
    """Frames as they are played out, at most MAX_RATE_HZ per second of wall time, and
    notices (``server.hub``) as they come: the downlink records, merged with their truth
    records for a client in the truth view (``server.access.truth_view``)."""
    if not await websocket_allowed(websocket):
        return
    if rover not in server.rovers:
        await websocket.close(code=4404)
        return
    # Subscribed before the accept: a page that loads the stored events once its socket is
    # open misses none published in between (web/eventlog.js). The truth merged in or not,
    # decided once, from the handshake's token.
    client = server.hub.subscribe(
        rover, truth=connection_sees_truth(server, websocket.state.principal)
    )
    try:
        await websocket.accept()
    except BaseException:
        server.hub.unsubscribe(rover, client)
        raise
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


@routes.get("/api/schema/downlink", response_model=RecordSchema)
def downlink_record_schema(_: Viewer) -> dict[str, Any]:
    """The JSON schema of the rover's downlink record, what the rover itself reports in a
    frame (``sim.loop.downlink.Downlink``, the one definition of its fields)."""
    return downlink_schema()


@routes.get(
    "/api/schema/truth",
    response_model=RecordSchema,
    responses={403: error_doc("not in the truth view")},
)
def truth_record_schema(_: Viewer, truth: SeesTruth) -> dict[str, Any]:
    """The JSON schema of the truth record beside each frame: what only the simulator knows,
    and the scores against it (``sim.scoring.truth.Truth``); for the truth view only."""
    if not truth:
        raise truth_refused("the truth record's schema")
    return truth_schema()


WS_MESSAGE = TypeAdapter(WsMessage)


@routes.get("/api/schema/ws", response_model=UnionSchema)
def ws_message_schema(_: Viewer) -> dict[str, Any]:
    """The JSON schema of a message of ``/ws/rovers/{rover}/telemetry``: a frame (it has no
    ``type``) or a notice tagged by its ``type`` (``alarm``, ``command``, ``event``,
    ``queue``)."""
    return WS_MESSAGE.json_schema()
