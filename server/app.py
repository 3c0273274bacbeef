"""The operations server: FastAPI over the rover runtimes, storage and live telemetry.

This module only wires: ``create_app(config)`` makes the ``Server`` (``server.state``: the
runtimes and where their frames go, runtime -> sinks: storage, alarms, the WebSocket hub,
the 3D view), the middleware, and one router per resource (``server.api``: rovers,
sequences, queue, telemetry, events, channels, alarms, viewer, users, audit; the
conductor's faults, ``server.faults.api``; rehearsal campaigns, ``server.rehearsal.api``,
over the ``server.rehearsal.service`` closed at shutdown).

``roverops serve`` runs it with uvicorn. Each route needs a role
(``server.access.accounts``: viewer, operator, conductor, admin; ``server.access.auth``):
viewing needs no token while ``public_read`` is on; uploading, commanding and clock
control need an operator's token (``Authorization: Bearer <token>``): missing 401, wrong
or too low 403, and nothing changes; the token is checked before the body is read
(``server.api.routing``). Every mutating request is audited (``server.access.audit``).
Request bodies are validated: every 422's ``detail`` is a list of ``{"loc", "msg",
"type"}`` (FastAPI's shape), except a rejected upload, which is stored and answered with
its diagnostics (``SequenceReport``). Bodies above ``max_upload_bytes`` get 413 while they
stream in; a client running ``max_concurrent_validations`` validations at once gets 429
(``server.validation.uploads``). OpenAPI at ``/docs``.
"""

from __future__ import annotations

from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from pathlib import Path

from fastapi import FastAPI
from fastapi.responses import FileResponse
from fastapi.staticfiles import StaticFiles

from server.access.audit import AuditMiddleware
from server.api import (
    alarms,
    audit,
    channels,
    events,
    queue,
    rovers,
    sequences,
    telemetry,
    users,
    viewer,
)
from server.api.deps import AUTH_ERRORS, install_error_handlers
from server.api.routing import AuthFirstRoute, allow_every_method, document_public_reads
from server.comm import api as comm
from server.faults import api as faults
from server.images import api as images
from server.rehearsal import api as rehearsal_api
from server.rehearsal.service import RehearsalService
from server.state import Server, ServerConfig
from server.storage import data_dir_url
from server.terrain import advice_api

__all__ = ["Server", "ServerConfig", "create_app", "data_dir_url"]

WEB_DIR = Path(__file__).resolve().parent.parent / "web"  # the console, served as is


def create_app(config: ServerConfig) -> FastAPI:
    """The FastAPI app over a new ``Server``."""
    server = Server.open(config)

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        server.start()
        try:
            yield
        finally:
            app.state.rehearsals.close()  # its campaigns stored as stopped, its workers ended
            server.stop()

    app = FastAPI(
        title="roverops",
        description="Ground operations for a simulated Mars Exploration Rover",
        lifespan=lifespan,
        responses=AUTH_ERRORS,  # any route: a bad token, or no token where reading needs one
    )
    app.router.route_class = AuthFirstRoute  # the token before the body, for every route
    allow_every_method(app)
    install_error_handlers(app)  # domain errors to HTTP (server.api.deps)
    app.state.server = server  # what server.api.deps.ServerDep hands the routes
    # server.rehearsal.api; the cluster starts on the first campaign
    app.state.rehearsals = RehearsalService(server.store, config.dask_scheduler)
    app.add_middleware(AuditMiddleware, server=server)
    if config.public_read:
        document_public_reads(app)
    app.state.max_body_bytes = config.max_upload_bytes

    @app.get("/", include_in_schema=False)
    def console_page() -> FileResponse:
        """The operators' console (``web/``)."""
        return FileResponse(WEB_DIR / "index.html")

    app.mount("/static", StaticFiles(directory=WEB_DIR), name="static")
    for api in (rovers, sequences, queue, telemetry, events, channels, alarms, viewer, users,
                audit, faults, comm, images, advice_api, rehearsal_api):  # fmt: skip
        app.include_router(api.routes)
    return app
