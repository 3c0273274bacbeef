"""The 3D view of each rover (``server.scene3d``), proxied on this origin under
``/viser/{rover}/``: its page, its WebSocket, and where it is."""

from __future__ import annotations

from typing import Any

from fastapi import Request, WebSocket
from fastapi.responses import RedirectResponse, Response
from pydantic import BaseModel, ConfigDict, Field
from starlette.concurrency import run_in_threadpool

from server.access.auth import Operator, Viewer
from server.api.answers import Scene
from server.api.deps import (
    MAX_ID,
    NOT_FOUND,
    RoverName,
    SeesTruth,
    ServerDep,
    connection_sees_truth,
    error_doc,
    router,
    websocket_allowed,
)
from server.errors import NotFoundError
from server.scene3d.proxy import fetch, relay
from server.scene3d.rehearsal import show_stored, view_of

routes = router()


class SceneState(Scene):
    """The 3D view, and what it draws of a rehearsal (``server.scene3d.rehearsal``: the
    campaign's id, its runs, the traverses and ellipses drawn, the viewers' note), or null."""

    rehearsal: dict[str, Any] | None = None


def scene_port(server: ServerDep, rover: str, truth: bool) -> int:
    server.rover(rover)
    scene = server.scene_for(rover, truth)
    if scene is None:
        raise NotFoundError("the 3D view is off (roverops serve starts it)")
    return scene.port


@routes.get("/viser/{rover}", include_in_schema=False)
def viser_root(server: ServerDep, rover: str, _: Viewer, truth: SeesTruth) -> RedirectResponse:
    scene_port(server, rover, truth)
    return RedirectResponse(f"/viser/{rover}/")


@routes.get("/viser/{rover}/{path:path}", include_in_schema=False)
async def viser_page(
    server: ServerDep, rover: str, path: str, _: Viewer, truth: SeesTruth
) -> Response:
    """The rover's viser client (and anything else viser serves), proxied."""
    got = await run_in_threadpool(fetch, scene_port(server, rover, truth), path)
    return Response(got.body, status_code=got.status, media_type=got.content_type)


@routes.websocket("/viser/{rover}")
async def viser_socket(server: ServerDep, websocket: WebSocket, rover: str) -> None:
    """The viser client's WebSocket, relayed to the rover's viser server: the scene with
    the truth or the one of the downlink alone, as the handshake's token allows
    (``server.scene3d.scene``)."""
    if not await websocket_allowed(websocket):
        return
    scene = server.scene_for(rover, connection_sees_truth(server, websocket.state.principal))
    if scene is None:
        await websocket.close(code=4404)
        return
    await relay(websocket, scene.port)


@routes.get("/api/rovers/{rover}/scene", response_model=SceneState, responses=NOT_FOUND)
def scene_state(server: ServerDep, rover: RoverName, _: Viewer, truth: SeesTruth) -> dict[str, Any]:
    """The 3D view: its URL on this origin, how many frames it has drawn, and whether it
    shows the truth (the truth view's scene)."""
    port = scene_port(server, rover, truth)
    scene = server.scene_for(rover, truth)
    assert scene is not None and scene.port == port
    return {
        "url": f"/viser/{rover}/",
        "frames_drawn": scene.frames_drawn,
        "truth": scene.truth,
        "rehearsal": view_of(scene).state(),
    }


class SceneRehearsal(BaseModel):
    """The rehearsal campaign the rover's 3D view draws (``server.scene3d.rehearsal``)."""

    model_config = ConfigDict(extra="forbid", strict=True)
    id: int = Field(ge=1, le=MAX_ID, description="a rehearsal campaign's id")


@routes.post(
    "/api/rovers/{rover}/scene/rehearsal",
    response_model=SceneState,
    responses={**NOT_FOUND, 409: error_doc("the campaign has no risk table yet")},
)
def show_scene_rehearsal(
    server: ServerDep,
    rover: RoverName,
    body: SceneRehearsal,
    request: Request,
    _: Operator,
    truth: SeesTruth,
) -> dict[str, Any]:
    """Draw a campaign's predicted traverses and end ellipses in the rover's 3D view (every
    viewer's: the view is shared); the view as ``GET .../scene`` then says."""
    scene_port(server, rover, truth)
    request.state.audit_action = f"show rehearsal #{body.id} in the 3D view of {rover}"
    scenes = [server.scenes.get(rover), server.truth_scenes.get(rover)]
    show_stored(scenes, server.store, rover, body.id)
    return scene_state(server, rover, _, truth)
