"""A rover's queue: the sequences in order with their steps' status, and moving one."""

from __future__ import annotations

from typing import Any

from fastapi import Request
from pydantic import BaseModel, ConfigDict, Field

from server.access.auth import Operator, Viewer
from server.api.answers import Queue
from server.api.deps import (
    AUTH_ERRORS,
    BAD_REQUEST,
    MAX_ID,
    NOT_FOUND,
    TOO_LARGE,
    RoverName,
    SequenceId,
    ServerDep,
    error_doc,
    router,
)
from server.errors import ConflictError, NotFoundError
from server.queue_view import queue_json, recent_json
from server.runtime import NotQueuedError


class MoveBody(BaseModel):
    """``POST /api/rovers/{rover}/queue/{sequence_id}/move``: the queued sequence's new
    position (0 runs next; ``GET .../queue`` lists positions)."""

    model_config = ConfigDict(extra="forbid", strict=True)
    to: int = Field(ge=0, le=MAX_ID, description="the new position, 0 at the head")


routes = router()


@routes.get("/api/rovers/{rover}/queue", response_model=Queue, responses=NOT_FOUND)
def rover_queue(server: ServerDep, rover: RoverName, _: Viewer) -> dict[str, Any]:
    """The queue in order (``position`` 0 runs next), each sequence with every step's
    status (pending, running, completed, failed, refused, skipped) and times, whether
    it may move (``movable``; ``pinned`` says why not); then ``recent``: the last
    sequences that left the queue (completed, failed or cancelled), newest first. The
    telemetry WebSocket sends ``{"type": "queue", "queue": [...]}`` on every change."""
    runtime = server.rover(rover)
    return {
        "rover": rover,
        "queue": queue_json(runtime, server.store),
        "recent": recent_json(runtime, server.store),
    }


@routes.post(
    "/api/rovers/{rover}/queue/{sequence_id:int}/move",
    response_model=Queue,
    responses={
        **AUTH_ERRORS,
        **NOT_FOUND,
        409: error_doc("the move is not allowed (the answer says why); nothing changed"),
        **TOO_LARGE,
        **BAD_REQUEST,
    },
)
def move_in_queue(
    server: ServerDep,
    rover: RoverName,
    sequence_id: SequenceId,
    body: MoveBody,
    request: Request,
    _: Operator,
) -> dict[str, Any]:
    """Move a queued sequence to position ``to`` (0 runs next), the others keeping
    their order. A sequence that has started and an immediate command keep their place
    and nothing moves in front of them (409 saying so); the new order is stored before
    this answers. The queue as ``GET .../queue`` lists it."""
    runtime = server.rover(rover)
    request.state.audit_action = f"move sequence #{sequence_id} to position {body.to}"
    if runtime.comm.mission is not None:
        raise ConflictError(
            "across light time the rover's queue is not reordered from the ground: cancel "
            "the sequence and upload it again"
        )
    try:
        runtime.move(sequence_id, body.to)
    except NotQueuedError as error:
        found = server.store.get_sequence(sequence_id)
        if found is None or found["rover"] != rover:
            raise NotFoundError(f"no sequence {sequence_id} for rover {rover!r}") from None
        raise ConflictError(f"{error}: it is {found['status']}") from None
    return {"rover": rover, "queue": queue_json(runtime, server.store)}
