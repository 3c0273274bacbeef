"""What every router shares: typed dependencies, path parameters and the documented errors.

``ServerDep`` is the app's ``server.state.Server`` (the runtimes, storage, hub ...), the
role checks are ``server.access.auth``'s ``Viewer``, ``Operator``, ``Admin`` (run before
the body is read: ``server.api.routing``); ``router()`` makes a router whose routes do so.
``SeesTruth`` says whether the caller may see the simulator's truth (the truth view,
``server.access.truth_view``): every route that could carry it asks.
The error shapes: every error but a 422 is ``ErrorMessage``, a 422 is ``RequestErrors``.
``install_error_handlers`` maps the server's domain errors (``server.errors``) to HTTP, the
one place that does: domain code never raises ``HTTPException``.
"""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Annotated, Any

from fastapi import APIRouter, Depends, FastAPI, HTTPException, WebSocket
from fastapi import Path as PathParam
from pydantic import BaseModel, ConfigDict
from starlette.concurrency import run_in_threadpool
from starlette.requests import HTTPConnection, Request
from starlette.responses import JSONResponse

from server.access.accounts import Principal
from server.access.auth import Viewer, websocket_principal
from server.access.truth_view import may_see_truth
from server.api.origin import origin_allowed
from server.api.routing import AuthFirstRoute
from server.errors import ConflictError, DomainError, InvalidError, NotFoundError
from server.runtime import ROVERS
from server.state import Server
from server.validation.uploads import request_error

MAX_ID = 2**31 - 1  # ids are PostgreSQL's int4 (storage: Integer columns)
MAX_SOL = 100_000  # 270 Earth years of a mission; the bundled ephemeris covers fewer


def get_server(connection: HTTPConnection) -> Server:
    """The app's state (``create_app`` puts it in ``app.state.server``)."""
    server: Server = connection.app.state.server
    return server


ServerDep = Annotated[Server, Depends(get_server)]


def sees_truth(server: ServerDep, who: Viewer) -> bool:
    """Whether the caller may see the simulator's truth (``server.access.truth_view``)."""
    return may_see_truth(server.config.truth_view, who)


# A route's answer carries the truth only when this is true (server.access.truth_view).
SeesTruth = Annotated[bool, Depends(sees_truth)]


def connection_sees_truth(server: Server, who: Principal) -> bool:
    """The same decision for a WebSocket, from its handshake's principal."""
    return may_see_truth(server.config.truth_view, who)


def router() -> APIRouter:
    """A router whose routes check the token before the body is read (``AuthFirstRoute``)."""
    return APIRouter(route_class=AuthFirstRoute)


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


def error_doc(text: str) -> dict[str, Any]:
    return {"model": ErrorMessage, "description": text}


AUTH_ERRORS: dict[int | str, dict[str, Any]] = {
    401: error_doc("no token where the route needs one (Authorization: Bearer <token>)"),
    403: error_doc("a wrong, expired or revoked token, or a role too low for the route"),
}
NOT_FOUND: dict[int | str, dict[str, Any]] = {404: error_doc("no such rover or record")}
TOO_LARGE: dict[int | str, dict[str, Any]] = {413: error_doc("body over the server's limit")}
BUSY: dict[int | str, dict[str, Any]] = {
    429: {
        **error_doc("this client already runs the most validations allowed at once"),
        "headers": {"Retry-After": {"schema": {"type": "integer"}, "description": "seconds"}},
    }
}
BAD_REQUEST: dict[int | str, dict[str, Any]] = {
    422: {"model": RequestErrors, "description": "the request's problems"}
}

CSV_FILE: dict[str, Any] = {
    "description": "CSV, one row per frame",
    "content": {"text/csv": {"schema": {"type": "string"}}},
}

ISO_TIME = {"format": "date-time", "examples": ["2026-12-02T05:00:00+00:00"]}


def utc(text: str | None, name: str) -> datetime | None:
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


RoverName = Annotated[
    str, PathParam(description="a rover's name (GET /api/rovers)", examples=list(ROVERS))
]
SequenceId = Annotated[int, PathParam(ge=1, le=MAX_ID, description="a sequence's id")]
Sol = Annotated[int, PathParam(ge=0, le=MAX_SOL, description="a sol of the mission")]
Channel = Annotated[str, PathParam(max_length=64, description="a channel (GET .../limits)")]
AlarmId = Annotated[int, PathParam(ge=1, le=MAX_ID, description="an alarm's id")]


async def websocket_allowed(websocket: WebSocket) -> bool:
    """The checks of a WebSocket handshake, before it is accepted (a browser then sees
    HTTP 403): a page of another origin is refused (``server.api.origin``: the sign-in
    cookie must not let another site read), then the viewer check (header or cookie
    token), closing with 4401 (no token) or 4403 (wrong token)."""
    if not origin_allowed(websocket.headers, websocket.url.scheme):
        await websocket.close(code=4403, reason="cross-origin WebSocket refused")
        return False
    try:
        who = await run_in_threadpool(
            websocket_principal, get_server(websocket), websocket.headers, websocket.cookies
        )
    except HTTPException as refused:
        code = 4401 if refused.status_code == 401 else 4403
        await websocket.close(code=code, reason=str(refused.detail)[:120])
        return False
    websocket.state.principal = who
    return True


def domain_error_answer(error: DomainError) -> tuple[int, Any]:
    """The HTTP status and ``detail`` of a domain error: 404 for what does not exist, 409
    for what the record's state refuses, 422 (``RequestErrors``) for a value that cannot be;
    a lookup fails before a value is judged."""
    if isinstance(error, NotFoundError):
        return 404, str(error)
    if isinstance(error, ConflictError):
        return 409, str(error)
    if isinstance(error, InvalidError):
        return 422, [{"loc": list(error.loc), "msg": str(error), "type": error.kind}]
    return 400, str(error)


async def _domain_error(_: Request, error: Exception) -> JSONResponse:
    assert isinstance(error, DomainError)
    status, detail = domain_error_answer(error)
    return JSONResponse({"detail": detail}, status_code=status)


def install_error_handlers(app: FastAPI) -> None:
    """Every domain error a route lets through answered as ``domain_error_answer`` says."""
    app.add_exception_handler(DomainError, _domain_error)
