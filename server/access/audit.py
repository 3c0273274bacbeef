"""The audit log: every request that would change something, accepted or refused, is a row.

A ground system must answer "who did that, and when" (Yamcs and COSMOS keep such logs).
``AuditMiddleware`` wraps the app: for every mutating request (POST, PUT, PATCH, DELETE,
except those that change nothing, ``EXEMPT``) it records, after the response, who asked
(the principal the route's auth check found, or ``anonymous``), when (wall-clock UTC and the
rover's own clock, sol and LMST), what (method, path and the route's own words for it,
``request.state.audit_action``), the HTTP status and, for a refusal, why. It sits inside
Starlette's error middleware, so a request that failed with a 500 is recorded too.

>>> from server.storage import Store
>>> log = AuditLog(Store("sqlite://"))
>>> log.add(AuditEntry(username="ada", role="operator", method="POST",
...                    path="/api/rovers/spirit/clock", status=200, action="pause"))
>>> [(r["username"], r["result"], r["action"]) for r in log.query()]
[('ada', 'accepted', 'pause')]
"""

from __future__ import annotations

import csv
import io
import json
import logging
import re
from dataclasses import dataclass, field
from datetime import UTC, datetime
from typing import Any

from sqlalchemy import insert, select
from starlette.concurrency import run_in_threadpool
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from server.storage import Store, audit_log

log = logging.getLogger(__name__)

MUTATING = ("POST", "PUT", "PATCH", "DELETE")
EXEMPT = ("/api/sequences/validate",)  # a POST that stores and changes nothing
MAX_LIMIT = 10_000
_ROVER_PATH = re.compile(r"^/(?:api|ws)/rovers/([^/]{1,64})")
_DETAIL_BYTES = 4096
COLUMNS = ("id", "at", "rover", "rover_clock", "username", "role", "method", "path",
           "action", "status", "result", "detail")  # fmt: skip


@dataclass
class AuditEntry:
    """One row of the audit log (``at`` defaults to now, ``result`` follows ``status``)."""

    username: str
    method: str
    path: str
    status: int
    role: str | None = None
    rover: str | None = None
    rover_clock: str | None = None
    action: str | None = None
    detail: str | None = None
    at: datetime = field(default_factory=lambda: datetime.now(UTC))

    @property
    def result(self) -> str:
        return "accepted" if self.status < 400 else "refused"


class AuditLog:
    """The ``audit_log`` table of a ``Store``."""

    def __init__(self, store: Store) -> None:
        self.store = store

    def add(self, entry: AuditEntry) -> None:
        """Store one entry."""
        with self.store.engine.begin() as conn:
            conn.execute(
                insert(audit_log).values(
                    at=entry.at,
                    rover=entry.rover,
                    rover_clock=entry.rover_clock,
                    username=entry.username[:64],
                    role=entry.role,
                    method=entry.method[:8],
                    path=entry.path[:512],
                    action=entry.action,
                    status=entry.status,
                    result=entry.result,
                    detail=entry.detail,
                )
            )

    def query(
        self,
        username: str | None = None,
        rover: str | None = None,
        result: str | None = None,
        method: str | None = None,
        since: datetime | None = None,
        until: datetime | None = None,
        limit: int = 1000,
    ) -> list[dict[str, Any]]:
        """Entries matching every filter given, newest first, at most ``limit``."""
        a = audit_log.c
        query = select(audit_log).order_by(a.id.desc()).limit(max(1, min(limit, MAX_LIMIT)))
        for column, value in (
            (a.username, username),
            (a.rover, rover),
            (a.result, result),
            (a.method, method),
        ):
            if value is not None:
                query = query.where(column == value)
        if since is not None:
            query = query.where(a.at >= since)
        if until is not None:
            query = query.where(a.at <= until)
        with self.store.engine.connect() as conn:
            rows = [dict(r._mapping) for r in conn.execute(query)]
        for row in rows:
            at: datetime = row["at"]
            row["at"] = (at if at.tzinfo else at.replace(tzinfo=UTC)).isoformat()
        return rows


def as_csv(rows: list[dict[str, Any]]) -> str:
    """Audit rows as CSV, one column per field."""
    out = io.StringIO()
    writer = csv.writer(out)
    writer.writerow(COLUMNS)
    for row in rows:
        writer.writerow([row.get(c) for c in COLUMNS])
    return out.getvalue()


def _detail(body: bytes) -> str | None:
    """The ``detail`` of an error response (our errors are JSON ``{"detail": ...}``)."""
    try:
        parsed = json.loads(body)
    except (ValueError, RecursionError):
        return body[:500].decode("utf-8", "replace") or None
    detail = parsed.get("detail", parsed) if isinstance(parsed, dict) else parsed
    text = detail if isinstance(detail, str) else json.dumps(detail)[:1000]
    return text[:1000]


class AuditMiddleware:
    """Records every mutating HTTP request after its response (module docstring).
    ``server`` is the app's ``Server``: its audit log and rovers (for their clocks)."""

    def __init__(self, app: ASGIApp, server: Any) -> None:
        self.app = app
        self.server = server

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http" or scope["method"] not in MUTATING or scope["path"] in EXEMPT:
            await self.app(scope, receive, send)
            return
        status = 500
        body = bytearray()

        async def send_and_watch(message: Message) -> None:
            nonlocal status
            if message["type"] == "http.response.start":
                status = int(message["status"])
            elif message["type"] == "http.response.body" and status >= 400:
                body.extend(message.get("body", b"")[: max(0, _DETAIL_BYTES - len(body))])
            await send(message)

        try:
            await self.app(scope, receive, send_and_watch)
        finally:
            entry = self._entry(scope, status, bytes(body))
            try:
                await run_in_threadpool(self.server.audit.add, entry)
            except Exception:  # the response is sent; losing the row must not hide it
                log.exception("audit: could not record %s %s", entry.method, entry.path)

    def _entry(self, scope: Scope, status: int, body: bytes) -> AuditEntry:
        state = scope.get("state") or {}
        principal = state.get("principal")
        path = scope["path"]
        query = scope.get("query_string", b"").decode("latin-1")
        rover = state.get("audit_rover")
        if rover is None:
            found = _ROVER_PATH.match(path)
            rover = found.group(1) if found else None
        runtime = self.server.rovers.get(rover) if rover else None
        return AuditEntry(
            username=principal.name if principal is not None else "anonymous",
            role=principal.role if principal is not None else None,
            method=scope["method"],
            path=(path + ("?" + query if query else ""))[:512],
            status=status,
            rover=rover if runtime is not None else None,
            rover_clock=runtime.clock_text() if runtime is not None else None,
            action=state.get("audit_action"),
            detail=_detail(body) if status >= 400 else None,
        )
