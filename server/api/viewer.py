"""The 3D view of each rover (``server.scene3d``), proxied on this origin under
``/viser/{rover}/``: its page, its WebSocket, and where it is."""

from __future__ import annotations

from typing import Any

from fastapi import HTTPException, WebSocket
from fastapi.responses import RedirectResponse, Response
from starlette.concurrency import run_in_threadpool

from server.access.auth import Viewer
from server.api.deps import (
    NOT_FOUND,
    RoverName,
    ServerDep,
    router,
    websocket_allowed,
)
from server.scene3d.proxy import fetch, relay

routes = router()


def scene_port(server: ServerDep, rover: str) -> int:
    server.rover(rover)
    if rover not in server.scenes:
        raise HTTPException(404, "the 3D view is off (roverops serve starts it)")
    return server.scenes[rover].port


@routes.get("/viser/{rover}", include_in_schema=False)
def viser_root(server: ServerDep, rover: str, _: Viewer) -> RedirectResponse:
    scene_port(server, rover)
    return RedirectResponse(f"/viser/{rover}/")


@routes.get("/viser/{rover}/{path:path}", include_in_schema=False)
async def viser_page(server: ServerDep, rover: str, path: str, _: Viewer) -> Response:
    """The rover's viser client (and anything else viser serves), proxied."""
    got = await run_in_threadpool(fetch, scene_port(server, rover), path)
    return Response(got.body, status_code=got.status, media_type=got.content_type)


@routes.websocket("/viser/{rover}")
async def viser_socket(server: ServerDep, websocket: WebSocket, rover: str) -> None:
    """The viser client's WebSocket, relayed to the rover's viser server."""
    if not await websocket_allowed(websocket):
        return
    if rover not in server.scenes:
        await websocket.close(code=4404)
        return
    await relay(websocket, server.scenes[rover].port)


@routes.get("/api/rovers/{rover}/scene", responses=NOT_FOUND)
def scene_state(server: ServerDep, rover: RoverName, _: Viewer) -> dict[str, Any]:
    """The 3D view: its URL on this origin and how many frames it has drawn."""
    scene_port(server, rover)
    return {"url": f"/viser/{rover}/", "frames_drawn": server.scenes[rover].frames_drawn}
