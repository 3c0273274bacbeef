"""A rover's event log, filtered and paged (``server.eventlog``)."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import Query

from server.access.auth import Viewer
from server.api.answers import EventPage
from server.api.deps import (
    BAD_REQUEST,
    MAX_ID,
    MAX_SOL,
    NOT_FOUND,
    RoverName,
    SeesTruth,
    ServerDep,
    router,
)
from server.eventlog import LOG_KINDS, MAX_LIMIT, EventFilter, event_log

routes = router()


@routes.get(
    "/api/rovers/{rover}/events", response_model=EventPage, responses={**NOT_FOUND, **BAD_REQUEST}
)
def event_log_page(
    server: ServerDep,
    rover: RoverName,
    _: Viewer,
    truth: SeesTruth,
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
    text: Annotated[str | None, Query(max_length=200, description="contained, any case")] = None,
    before_t_s: Annotated[float | None, Query(description="events before this TT s")] = None,
    limit: Annotated[int, Query(ge=1, le=MAX_LIMIT)] = 200,
    offset: Annotated[int, Query(ge=0, le=MAX_ID)] = 0,
) -> dict[str, Any]:
    """The rover's events, newest first, filtered (server.eventlog): ``{"rover",
    "kinds", "total", "offset", "limit", "events"}``; a filter that cannot be met is a
    422 naming it. The events of alarms on truth channels only in the truth view."""
    runtime = server.rover(rover)
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
    return event_log(server.store, runtime, flt, truth)
