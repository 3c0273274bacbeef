"""The audit log (``server.access.audit``), admin only: JSON or CSV, filtered."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from fastapi import Query, Request
from fastapi.responses import Response

from server.access.audit import as_csv
from server.access.auth import Admin
from server.api.answers import AuditRow
from server.api.deps import (
    BAD_REQUEST,
    CSV_FILE,
    ISO_TIME,
    ServerDep,
    router,
    utc,
)

routes = router()


@routes.get(
    "/api/audit",
    response_model=None,
    responses={
        200: {
            "description": "audit rows, newest first (JSON), or CSV",
            "content": {
                **CSV_FILE["content"],
            },
            "model": list[AuditRow],
        },
        **BAD_REQUEST,
    },
)
def audit(
    server: ServerDep,
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
    lo, hi = utc(since, "since"), utc(until, "until")
    rows = server.audit.query(user, rover, result, method, lo, hi, limit)
    if format == "csv" or (format is None and "text/csv" in request.headers.get("accept", "")):
        return Response(as_csv(rows), media_type="text/csv")
    return rows
