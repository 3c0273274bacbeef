"""The image routes (viewer role, like telemetry): a rover's images listed, one image's
metadata and features, and its two PNGs as they were stored when it arrived
(``server.storage.images``: encoded once, never rendered again on request)."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from fastapi import Path as PathParam
from fastapi import Query
from fastapi.responses import Response

from server.access.auth import Viewer
from server.api.deps import BAD_REQUEST, MAX_ID, NOT_FOUND, RoverName, ServerDep, router
from server.errors import NotFoundError
from server.images.answers import ImageDetail, ImageList
from server.storage.images import image_detail, image_png, list_images
from server.validation.uploads import request_error

routes = router()

ImageId = Annotated[int, PathParam(ge=1, le=MAX_ID, description="an image's id")]
MAX_PAGE = 1000
# An image's bytes never change once stored: a browser keeps them (its reader's own copy).
CACHE = "private, max-age=31536000, immutable"
PNG_FILE: dict[str, Any] = {
    "description": "the 8-bit image as the rover sent it, PNG",
    "content": {"image/png": {"schema": {"type": "string", "format": "binary"}}},
}


@routes.get(
    "/api/rovers/{rover}/images",
    response_model=ImageList,
    responses={**NOT_FOUND, **BAD_REQUEST},
)
def images(
    server: ServerDep,
    rover: RoverName,
    _: Viewer,
    t_from: Annotated[float | None, Query(alias="from", allow_inf_nan=False)] = None,
    t_to: Annotated[float | None, Query(alias="to", allow_inf_nan=False)] = None,
    kind: Literal["navcam_stereo", "vo_pair"] | None = None,
    limit: Annotated[int, Query(ge=1, le=MAX_PAGE)] = 100,
    offset: Annotated[int, Query(ge=0, le=MAX_ID)] = 0,
) -> dict[str, Any]:
    """The rover's images taken over ``from``-``to`` (TT s), of ``kind`` if given, in time
    order: ``limit`` of them from ``offset``, and how many match."""
    server.rover(rover)
    if t_from is not None and t_to is not None and not t_from <= t_to:
        raise request_error(("query", "to"), "from/to: need from <= to", "range")
    found, total = list_images(server.store, rover, t_from, t_to, kind, limit, offset)
    return {"images": found, "total": total, "limit": limit, "offset": offset}


@routes.get(
    "/api/rovers/{rover}/images/{image_id}", response_model=ImageDetail, responses=NOT_FOUND
)
def image(server: ServerDep, rover: RoverName, image_id: ImageId, _: Viewer) -> dict[str, Any]:
    """One image's metadata and, for a VO pair, its features, tracks and inliers."""
    server.rover(rover)
    found = image_detail(server.store, rover, image_id)
    if found is None:
        raise NotFoundError(f"no image {image_id} of rover {rover!r}")
    return found


def _png(server: ServerDep, rover: str, image_id: int, side: Literal["left", "right"]) -> Response:
    server.rover(rover)
    data = image_png(server.store, rover, image_id, side)
    if data is None:
        raise NotFoundError(f"no image {image_id} of rover {rover!r}")
    return Response(data, media_type="image/png", headers={"Cache-Control": CACHE})


@routes.get(
    "/api/rovers/{rover}/images/{image_id}/left.png",
    response_class=Response,
    responses={200: PNG_FILE, **NOT_FOUND},
)
def left_png(server: ServerDep, rover: RoverName, image_id: ImageId, _: Viewer) -> Response:
    """The left image, PNG, as stored when it arrived."""
    return _png(server, rover, image_id, "left")


@routes.get(
    "/api/rovers/{rover}/images/{image_id}/right.png",
    response_class=Response,
    responses={200: PNG_FILE, **NOT_FOUND},
)
def right_png(server: ServerDep, rover: RoverName, image_id: ImageId, _: Viewer) -> Response:
    """The right image, PNG, as stored when it arrived."""
    return _png(server, rover, image_id, "right")
