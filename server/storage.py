"""Storage of the operations server: sequences, commands, events, telemetry and checkpoints.

One SQLAlchemy 2 (Core) layer over any database URL, so that the embedded default (SQLite,
a file under the data directory) and a shared server (PostgreSQL) behave the same and run
the same tests. ``Store`` is the synchronous API the request handlers call; ``BatchWriter``
takes the high-rate writes off the simulation threads (docs/DESIGN.md: "server stores frames
(batched)") and commits them together at least once per ``interval_s`` of wall time, so a
server killed with SIGKILL loses at most the writes of the last interval (issue 4, item 5).

Choices worth knowing:

- SQLite runs in WAL mode (readers never block the writer thread and the writer never
  blocks the request threads), with foreign keys on and ``synchronous=NORMAL``: a committed
  transaction survives the process being killed; only a power cut may lose the last ones.
- A telemetry frame is stored whole as JSON beside its ``t_s`` and ``sol`` (the columns the
  queries select on), so the frame's fields can grow without a schema change.
- JSON has no NaN or infinity (PostgreSQL's ``json`` rejects them) while frames carry NaN
  for "no value" (a tilt before the first estimate), so non-finite floats are stored as
  ``null`` on every database and read back as ``None``.
- Timestamps are wall-clock UTC, returned as ISO 8601 strings with ``+00:00``.
- A step of a sequence has one command row, whatever the restarts (issue 13, defect 8): a
  server killed after a step's row was stored but before a checkpoint after that step runs
  the step again from its checkpoint, and recording it again updates the row and counts
  the re-run (``reruns``). The rule lives in the write path, not in a unique index, so a
  database that already holds such duplicates opens as before.
- Events (``estimation.events``) are stored with their kind and severity; those stored
  before events had them (as a column or inside a stored frame) read back as kind
  ``unknown``, severity ``info`` (``event_dict``).
- The schema grows in place: opening a database adds the columns and indexes this version
  declares and it lacks (``_upgrade_schema``), so a database of an older version keeps
  working; a column added this way must be nullable or have a ``server_default``.

>>> store = Store("sqlite://")
>>> planted = {"text": "Site 1 planted", "kind": "site", "severity": "info"}
>>> store.add_events("spirit", [(10.0, planted)])
>>> store.events("spirit", 0.0, 20.0)
[{'t_s': 10.0, 'text': 'Site 1 planted', 'kind': 'site', 'severity': 'info'}]
>>> store.close()
"""

from __future__ import annotations

import json
import logging
import math
import threading
import time
from collections.abc import Callable, Iterable, Mapping
from datetime import UTC, datetime
from typing import Any

from sqlalchemy import (
    JSON,
    Boolean,
    Column,
    DateTime,
    Double,
    ForeignKey,
    Index,
    Integer,
    LargeBinary,
    MetaData,
    String,
    Table,
    Text,
    create_engine,
    delete,
    event,
    func,
    insert,
    inspect,
    select,
    text,
    update,
)
from sqlalchemy.engine import Connection, Engine, RowMapping, make_url
from sqlalchemy.pool import StaticPool
from sqlalchemy.schema import CreateColumn

log = logging.getLogger(__name__)

metadata = MetaData()


def _now() -> datetime:
    return datetime.now(UTC)


sequences = Table(
    "sequences",
    metadata,
    Column("id", Integer, primary_key=True, autoincrement=True),
    Column("rover", String(64), nullable=False, index=True),
    Column("name", String(256), nullable=False),
    Column("source", Text, nullable=False),
    Column("format", String(16), nullable=False),  # "text", "json", "command"
    Column("status", String(32), nullable=False),  # "queued", "rejected", "running", ...
    Column("detail", Text, nullable=True),
    Column("errors", JSON, nullable=False),
    Column("warnings", JSON, nullable=False),
    Column("steps", JSON, nullable=False),
    Column("created_at", DateTime(timezone=True), nullable=False, default=_now),
    Column("updated_at", DateTime(timezone=True), nullable=False, default=_now),
    # who uploaded it (an immediate command: who sent it); null on rows from before accounts
    Column("submitted_by", String(64), nullable=True),
)

commands = Table(
    "commands",
    metadata,
    Column("id", Integer, primary_key=True, autoincrement=True),
    Column("rover", String(64), nullable=False),
    Column("sequence_id", Integer, ForeignKey("sequences.id", ondelete="SET NULL")),
    Column("step_index", Integer),
    Column("command", String(64), nullable=False),
    Column("status", String(32), nullable=False),  # "completed", "refused", "failed"
    Column("reason", Text),
    Column("start_t_s", Double, nullable=False),
    Column("end_t_s", Double, nullable=False),
    Column("events", JSON, nullable=False),
    Column("created_at", DateTime(timezone=True), nullable=False, default=_now),
    # times the step ran again after a restart (module docstring)
    Column("reruns", Integer, nullable=False, default=0, server_default="0"),
    Index("ix_commands_rover_start", "rover", "start_t_s"),
    Index("ix_commands_sequence_step", "sequence_id", "step_index"),
)

events = Table(
    "events",
    metadata,
    Column("id", Integer, primary_key=True, autoincrement=True),
    Column("rover", String(64), nullable=False),
    Column("t_s", Double, nullable=False),
    Column("text", Text, nullable=False),
    # estimation.events: kind and severity; rows from before they existed read as
    # LEGACY_KIND / LEGACY_SEVERITY
    Column("kind", String(32), nullable=False, server_default="unknown"),
    Column("severity", String(16), nullable=False, server_default="info"),
    Index("ix_events_rover_t", "rover", "t_s"),
)

frames_table = Table(
    "frames",
    metadata,
    Column("id", Integer, primary_key=True, autoincrement=True),
    Column("rover", String(64), nullable=False),
    Column("t_s", Double, nullable=False),
    Column("sol", Integer, nullable=False),
    Column("data", JSON, nullable=False),
    Index("ix_frames_rover_t", "rover", "t_s"),
    Index("ix_frames_rover_sol", "rover", "sol"),
)

checkpoints = Table(
    "checkpoints",
    metadata,
    Column("rover", String(64), primary_key=True),
    Column("t_s", Double, nullable=False),
    Column("blob", LargeBinary, nullable=False),
    Column("saved_at", DateTime(timezone=True), nullable=False, default=_now),
)


# ---- accounts and the audit log (server.accounts, server.audit) ---------------------------

users = Table(
    "users",
    metadata,
    Column("id", Integer, primary_key=True, autoincrement=True),
    Column("name", String(64), nullable=False, unique=True),
    Column("role", String(16), nullable=False),  # viewer, operator, conductor, admin
    Column("created_at", DateTime(timezone=True), nullable=False, default=_now),
)

api_tokens = Table(
    "api_tokens",
    metadata,
    Column("id", Integer, primary_key=True, autoincrement=True),
    Column("user_id", Integer, ForeignKey("users.id", ondelete="CASCADE"), nullable=False),
    # SHA-256 of the token (hex): the token itself is shown once and never stored
    Column("token_sha256", String(64), nullable=False, unique=True),
    Column("created_at", DateTime(timezone=True), nullable=False, default=_now),
    Column("expires_at", DateTime(timezone=True), nullable=False),
    Column("revoked_at", DateTime(timezone=True), nullable=True),
)

audit_log = Table(
    "audit_log",
    metadata,
    Column("id", Integer, primary_key=True, autoincrement=True),
    Column("at", DateTime(timezone=True), nullable=False),  # wall-clock UTC
    Column("rover", String(64), nullable=True),
    Column("rover_clock", String(32), nullable=True),  # "sol N hh:mm:ss LMST" of that rover
    Column("username", String(64), nullable=False),  # "anonymous" without a valid token
    Column("role", String(16), nullable=True),
    Column("method", String(8), nullable=False),
    Column("path", String(512), nullable=False),
    Column("action", Text, nullable=True),  # what the request did, in words
    Column("status", Integer, nullable=False),  # the HTTP status answered
    Column("result", String(16), nullable=False),  # "accepted" or "refused"
    Column("detail", Text, nullable=True),  # why it was refused
    Index("ix_audit_at", "at"),
)


LEGACY_KIND = "unknown"  # an event stored before events had a kind
LEGACY_SEVERITY = "info"


def event_dict(event: str | Mapping[str, Any]) -> dict[str, Any]:
    """An event of a frame as ``{"text", "kind", "severity"}`` (plus any other keys it
    has), whether stored by this version or as the bare text of an older one."""
    if isinstance(event, str):
        return {"text": event, "kind": LEGACY_KIND, "severity": LEGACY_SEVERITY}
    return {"kind": LEGACY_KIND, "severity": LEGACY_SEVERITY, **event}


def _frame_events(data: dict[str, Any]) -> dict[str, Any]:
    """A stored frame with its events in this version's shape (module docstring)."""
    got = data.get("events")
    if got and any(isinstance(e, str) for e in got):
        data["events"] = [event_dict(e) for e in got]
    return data


# ---- alarms and their limits (server.alarms, server.limits) ----------------------------

alarms_table = Table(
    "alarms",
    metadata,
    Column("id", Integer, primary_key=True, autoincrement=True),
    Column("rover", String(64), nullable=False),
    Column("channel", String(64), nullable=False),
    Column("level", String(16), nullable=False),  # "warning" or "critical"
    Column("truth", Boolean, nullable=False),  # a truth-view channel
    Column("value", JSON, nullable=True),  # a number or a name (AQF, NATE mode)
    Column("limit_value", JSON, nullable=True),  # the limit crossed (a list for states)
    Column("units", String(16), nullable=False, default=""),
    Column("message", Text, nullable=False),
    Column("violations", Integer, nullable=False, default=1, server_default="1"),
    Column("raised_t_s", Double, nullable=False),
    Column("raised_utc", String(40), nullable=False),
    Column("raised_lmst_h", Double, nullable=False),
    Column("raised_sol", Integer, nullable=False),
    Column("cleared_t_s", Double, nullable=True),
    Column("cleared_utc", String(40), nullable=True),
    Column("cleared_lmst_h", Double, nullable=True),
    Column("acknowledged_by", String(64), nullable=True),
    Column("acknowledged_at", DateTime(timezone=True), nullable=True),  # wall-clock UTC
    Index("ix_alarms_rover_raised", "rover", "raised_t_s"),
)

alarm_limits = Table(
    "alarm_limits",
    metadata,
    Column("rover", String(64), primary_key=True),
    Column("channel", String(64), primary_key=True),
    Column("levels", JSON, nullable=False),  # {"warning", "critical"[, "hysteresis"]}
    Column("updated_by", String(64), nullable=True),
    Column("updated_at", DateTime(timezone=True), nullable=False, default=_now),
)


def _finite(value: Any) -> Any:
    """``value`` with every non-finite float (NaN, ±inf) replaced by ``None``."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, Mapping):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite(v) for v in value]
    return value


def _json_dumps(value: Any) -> str:
    """Strict JSON for every database: non-finite floats become null (module docstring)."""
    try:
        return json.dumps(value, allow_nan=False)
    except ValueError:  # a NaN somewhere: the slow path only for the frames that have one
        return json.dumps(_finite(value), allow_nan=False)


def _iso(value: datetime | None) -> str | None:
    """UTC ISO 8601; SQLite hands back naive datetimes (stored as UTC), PostgreSQL aware."""
    if value is None:
        return None
    if value.tzinfo is None:
        value = value.replace(tzinfo=UTC)
    return value.astimezone(UTC).isoformat()


def _row_dict(row: RowMapping) -> dict[str, Any]:
    return {str(k): _iso(v) if isinstance(v, datetime) else v for k, v in row.items()}


class Store:
    """The server's database: one engine, the tables created on first use.

    ``url`` is any SQLAlchemy URL: ``sqlite:///path/roverops.db`` (the embedded default),
    ``sqlite://`` (in memory, one shared connection: for tests and doctests), or
    ``postgresql+psycopg://user@host:port/db``. Every method is one transaction and safe to
    call from any thread. Times ``t_s`` are simulated TT seconds from J2000 (floats).
    """

    def __init__(self, url: str) -> None:
        parsed = make_url(url)
        self.url = url
        kwargs: dict[str, Any] = {"json_serializer": _json_dumps}
        self.is_sqlite = parsed.get_backend_name() == "sqlite"
        if self.is_sqlite:
            # The writer thread and the request threads share the engine.
            kwargs["connect_args"] = {"check_same_thread": False, "timeout": 30.0}
            if parsed.database in (None, "", ":memory:"):
                kwargs["poolclass"] = StaticPool  # else each connection is a new empty db
        else:
            kwargs["pool_pre_ping"] = True  # a restarted database server is not an error
        self.engine: Engine = create_engine(url, **kwargs)
        if self.is_sqlite:
            event.listen(self.engine, "connect", _sqlite_pragmas)
        metadata.create_all(self.engine)
        _upgrade_schema(self.engine)

    def close(self) -> None:
        """Close every pooled connection (the store is not usable afterwards)."""
        self.engine.dispose()

    # ---- sequences: one row per upload, accepted or rejected ------------------------

    def add_sequence(
        self,
        rover: str,
        name: str,
        source: str,
        fmt: str,
        status: str,
        errors: list[dict[str, Any]],
        warnings: list[dict[str, Any]],
        steps: list[dict[str, Any]],
        submitted_by: str | None = None,
    ) -> int:
        """Store an upload as given (a rejected one keeps its errors), with the name of who
        submitted it; its new id."""
        with self.engine.begin() as conn:
            result = conn.execute(
                insert(sequences).values(
                    rover=rover,
                    name=name,
                    source=source,
                    format=fmt,
                    status=status,
                    errors=errors,
                    warnings=warnings,
                    steps=steps,
                    submitted_by=submitted_by,
                )
            )
            key = result.inserted_primary_key
            assert key is not None
            return int(key[0])

    def set_sequence_status(self, sequence_id: int, status: str, detail: str | None = None) -> None:
        """Move a sequence to ``status`` (``detail`` says why); ``KeyError`` if unknown."""
        with self.engine.begin() as conn:
            result = conn.execute(
                update(sequences)
                .where(sequences.c.id == sequence_id)
                .values(status=status, detail=detail, updated_at=_now())
            )
            if result.rowcount == 0:
                raise KeyError(f"no sequence {sequence_id}")

    def get_sequence(self, sequence_id: int) -> dict[str, Any] | None:
        """Every column of one sequence (JSON decoded, times ISO), or ``None``."""
        with self.engine.connect() as conn:
            row = conn.execute(select(sequences).where(sequences.c.id == sequence_id)).first()
        return None if row is None else _row_dict(row._mapping)

    def list_sequences(self, rover: str) -> list[dict[str, Any]]:
        """A rover's sequences, newest first, without the bulky ``source`` and ``steps``."""
        cols = [c for c in sequences.c if c.name not in ("source", "steps")]
        query = select(*cols).where(sequences.c.rover == rover).order_by(sequences.c.id.desc())
        with self.engine.connect() as conn:
            return [_row_dict(r._mapping) for r in conn.execute(query)]

    def submitters(self, sequence_ids: Iterable[int]) -> dict[int, str | None]:
        """Who submitted each of these sequences (``None`` for rows from before accounts)."""
        ids = sorted({int(i) for i in sequence_ids})
        if not ids:
            return {}
        c = sequences.c
        query = select(c.id, c.submitted_by).where(c.id.in_(ids))
        with self.engine.connect() as conn:
            return {int(r.id): r.submitted_by for r in conn.execute(query)}

    # ---- command executions ------------------------------------------------------

    def add_command(
        self,
        rover: str,
        sequence_id: int | None,
        step_index: int | None,
        command: str,
        status: str,
        reason: str | None,
        start_t_s: float,
        end_t_s: float,
        events: list[str],
    ) -> int:
        """Store one executed or refused command; its row's id. A step of a sequence
        already stored (run again after a restart) updates its row (module docstring)."""
        row = _command_row(rover, sequence_id, step_index, command, status, reason,
                           start_t_s, end_t_s, events)  # fmt: skip
        with self.engine.begin() as conn:
            return _record_command(conn, row)

    def commands(self, rover: str, t_from: float, t_to: float) -> list[dict[str, Any]]:
        """Commands whose [start, end] overlaps [t_from, t_to], by start time."""
        c = commands.c
        query = (
            select(commands)
            .where(c.rover == rover, c.start_t_s <= t_to, c.end_t_s >= t_from)
            .order_by(c.start_t_s, c.id)
        )
        with self.engine.connect() as conn:
            return [_row_dict(r._mapping) for r in conn.execute(query)]

    # ---- events ------------------------------------------------------------------

    def add_events(self, rover: str, events: list[tuple[float, Mapping[str, Any]]]) -> None:
        """Store events as (t_s, ``{"text", "kind", "severity"}``) pairs."""
        with self.engine.begin() as conn:
            self._insert_events(conn, [(rover, t, e) for t, e in events])

    def events(self, rover: str, t_from: float, t_to: float) -> list[dict[str, Any]]:
        """Events with t_from <= t_s <= t_to, in time order, as
        ``{"t_s", "text", "kind", "severity"}``."""
        return self.event_log(rover, t_from, t_to, newest_first=False)[0]

    def event_log(
        self,
        rover: str,
        t_from: float,
        t_to: float,
        *,
        kinds: Iterable[str] = (),
        severities: Iterable[str] = (),
        text_contains: str | None = None,
        before_t_s: float | None = None,
        limit: int | None = None,
        offset: int = 0,
        newest_first: bool = True,
    ) -> tuple[list[dict[str, Any]], int]:
        """Events with t_from <= t_s < ``before_t_s`` (if given) and t_s <= t_to, of one of
        ``kinds`` and ``severities`` (all if empty) whose text contains ``text_contains``
        (any case); the page of ``limit`` from ``offset``, newest first unless
        ``newest_first`` is false, and the number of events matching in all."""
        e = events.c
        where = [e.rover == rover, e.t_s >= t_from, e.t_s <= t_to]
        if before_t_s is not None:
            where.append(e.t_s < before_t_s)
        kinds, severities = list(kinds), list(severities)
        if kinds:
            where.append(e.kind.in_(kinds))
        if severities:
            where.append(e.severity.in_(severities))
        if text_contains:
            escaped = text_contains.replace("\\", "\\\\").replace("%", "\\%").replace("_", "\\_")
            where.append(func.lower(e.text).like(f"%{escaped.lower()}%", escape="\\"))
        order = (e.t_s.desc(), e.id.desc()) if newest_first else (e.t_s, e.id)
        query = select(e.t_s, e.text, e.kind, e.severity).where(*where).order_by(*order)
        if offset:
            query = query.offset(offset)
        if limit is not None:
            query = query.limit(limit)
        with self.engine.connect() as conn:
            rows = [dict(r._mapping) for r in conn.execute(query)]
            total = len(rows) if limit is None and not offset else None
            if total is None:
                total = int(conn.execute(select(func.count()).where(*where)).scalar_one())
        return rows, total

    # ---- telemetry frames --------------------------------------------------------

    def add_frames(self, rover: str, frames: list[dict[str, Any]]) -> None:
        """Store frames (``TelemetryFrame.as_dict()``) in one executemany."""
        with self.engine.begin() as conn:
            self._insert_frames(conn, [(rover, f) for f in frames])

    def frames(
        self,
        rover: str,
        t_from: float,
        t_to: float,
        every_s: float = 0.0,
        limit: int | None = None,
    ) -> list[dict[str, Any]]:
        """Frames with t_from <= t_s <= t_to, ascending, at most ``limit`` of them.

        With ``every_s > 0`` they are decimated: a frame is kept when it is at least
        ``every_s`` after the last kept frame, and a frame with events is always kept (and
        then counts as the last kept one), so decimation never hides an event.
        """
        f = frames_table.c
        query = (
            select(f.t_s, f.data)
            .where(f.rover == rover, f.t_s >= t_from, f.t_s <= t_to)
            .order_by(f.t_s, f.id)
        )
        out: list[dict[str, Any]] = []
        if limit is not None and limit <= 0:
            return out
        last = -math.inf
        with self.engine.connect() as conn:
            for row in conn.execution_options(yield_per=2000).execute(query):
                data: dict[str, Any] = row.data
                if every_s > 0.0 and row.t_s - last < every_s and not data.get("events"):
                    continue
                last = row.t_s
                out.append(_frame_events(data))
                if limit is not None and len(out) >= limit:
                    break
        return out

    def sols(self, rover: str) -> list[int]:
        """The sols that have telemetry, ascending."""
        f = frames_table.c
        query = select(f.sol).where(f.rover == rover).distinct().order_by(f.sol)
        with self.engine.connect() as conn:
            return [int(s) for s in conn.execute(query).scalars()]

    def sol_range(self, rover: str, sol: int) -> tuple[float, float] | None:
        """The first and last frame times of a sol, or ``None`` without telemetry."""
        f = frames_table.c
        query = select(func.min(f.t_s), func.max(f.t_s)).where(f.rover == rover, f.sol == sol)
        with self.engine.connect() as conn:
            lo, hi = conn.execute(query).one()
        return None if lo is None else (float(lo), float(hi))

    def last_frame(self, rover: str) -> dict[str, Any] | None:
        """The latest frame of a rover, or ``None``."""
        f = frames_table.c
        query = select(f.data).where(f.rover == rover).order_by(f.t_s.desc(), f.id.desc()).limit(1)
        with self.engine.connect() as conn:
            data: dict[str, Any] | None = conn.execute(query).scalar()
        return None if data is None else _frame_events(data)

    # ---- alarms (server.alarms) and operators' limits (server.limits) ---------------

    def add_alarm(self, row: dict[str, Any]) -> int:
        """Store a raised alarm (the columns of ``alarms``); its id."""
        with self.engine.begin() as conn:
            key = conn.execute(insert(alarms_table).values(**row)).inserted_primary_key
        assert key is not None
        return int(key[0])

    def update_alarm(self, alarm_id: int, values: dict[str, Any]) -> None:
        """Change an alarm's columns (escalated, cleared, re-raised, acknowledged)."""
        with self.engine.begin() as conn:
            conn.execute(update(alarms_table).where(alarms_table.c.id == alarm_id).values(**values))

    def alarms(
        self,
        rover: str | None = None,
        listed: bool | None = None,
        span: tuple[float, float] | None = None,
        limit: int | None = None,
        alarm_id: int | None = None,
    ) -> list[dict[str, Any]]:
        """Alarm rows, newest first: of ``rover``; ``listed`` True: still listed (not both
        acknowledged and cleared), False: done; ``span`` (t0, t1): raised by t1 and not
        cleared before t0."""
        a = alarms_table.c
        query = select(alarms_table).order_by(a.raised_t_s.desc(), a.id.desc())
        if rover is not None:
            query = query.where(a.rover == rover)
        if alarm_id is not None:
            query = query.where(a.id == alarm_id)
        done = a.acknowledged_by.is_not(None) & a.cleared_t_s.is_not(None)
        if listed is not None:
            query = query.where(~done if listed else done)
        if span is not None:
            query = query.where(
                a.raised_t_s <= span[1], a.cleared_t_s.is_(None) | (a.cleared_t_s >= span[0])
            )
        if limit is not None:
            query = query.limit(limit)
        with self.engine.connect() as conn:
            return [_row_dict(r._mapping) for r in conn.execute(query)]

    def set_limits(self, rover: str, channel: str, levels: dict[str, Any], by: str) -> None:
        """Store an operator's levels for a channel (replacing earlier ones)."""
        c = alarm_limits.c
        with self.engine.begin() as conn:
            conn.execute(delete(alarm_limits).where(c.rover == rover, c.channel == channel))
            conn.execute(insert(alarm_limits).values(
                rover=rover, channel=channel, levels=levels, updated_by=by, updated_at=_now()
            ))  # fmt: skip

    def reset_limits(self, rover: str, channel: str) -> None:
        """Forget an operator's levels for a channel (the default applies again)."""
        c = alarm_limits.c
        with self.engine.begin() as conn:
            conn.execute(delete(alarm_limits).where(c.rover == rover, c.channel == channel))

    def stored_limits(self, rover: str) -> dict[str, dict[str, Any]]:
        """The operators' levels of a rover by channel, with ``updated_by``/``updated_at``."""
        c = alarm_limits.c
        with self.engine.connect() as conn:
            rows = conn.execute(select(alarm_limits).where(c.rover == rover))
            return {r.channel: _row_dict(r._mapping) for r in rows}

    # ---- checkpoints: the latest simulation state, an opaque blob ---------------

    def save_checkpoint(self, rover: str, t_s: float, blob: bytes) -> None:
        """Replace the rover's checkpoint."""
        with self.engine.begin() as conn:
            self._replace_checkpoints(conn, {rover: (t_s, blob)})

    def load_checkpoint(self, rover: str) -> tuple[float, bytes] | None:
        """The rover's checkpoint as (t_s, blob), or ``None``."""
        c = checkpoints.c
        with self.engine.connect() as conn:
            row = conn.execute(select(c.t_s, c.blob).where(c.rover == rover)).first()
        return None if row is None else (float(row.t_s), bytes(row.blob))

    # ---- the batch primitives, shared with BatchWriter ----------------------------

    def _insert_frames(self, conn: Connection, rows: list[tuple[str, dict[str, Any]]]) -> None:
        if rows:
            conn.execute(
                insert(frames_table),
                [{"rover": r, "t_s": float(f["t_s"]), "sol": int(f["sol"]), "data": f}
                 for r, f in rows],
            )  # fmt: skip

    def _insert_events(
        self, conn: Connection, rows: list[tuple[str, float, Mapping[str, Any]]]
    ) -> None:
        if rows:
            conn.execute(
                insert(events),
                [{"rover": r, "t_s": float(t), **_event_columns(x)} for r, t, x in rows],
            )

    def _record_commands(self, conn: Connection, rows: list[dict[str, Any]]) -> None:
        for row in rows:  # a few per flush: one per step completed
            _record_command(conn, row)

    def _replace_checkpoints(self, conn: Connection, saved: dict[str, tuple[float, bytes]]) -> None:
        # Delete-then-insert in one transaction is the portable upsert; only the writer
        # thread (or a test) saves checkpoints, so there is no concurrent insert to race.
        if not saved:
            return
        conn.execute(delete(checkpoints).where(checkpoints.c.rover.in_(list(saved))))
        conn.execute(
            insert(checkpoints),
            [{"rover": r, "t_s": float(t), "blob": b, "saved_at": _now()}
             for r, (t, b) in saved.items()],
        )  # fmt: skip


def _sqlite_pragmas(dbapi_connection: Any, _record: Any) -> None:
    cursor = dbapi_connection.cursor()
    cursor.execute("PRAGMA journal_mode=WAL")
    cursor.execute("PRAGMA synchronous=NORMAL")
    cursor.execute("PRAGMA foreign_keys=ON")
    cursor.close()


def _record_command(conn: Connection, row: dict[str, Any]) -> int:
    """Insert a command row, or update the row of the same step (``sequence_id``,
    ``step_index``) and count the re-run: every row of it, should a database of an older
    version hold the step twice. The id of the (first) row."""
    c = commands.c
    if row["sequence_id"] is not None and row["step_index"] is not None:
        same_step = (c.sequence_id == row["sequence_id"], c.step_index == row["step_index"])
        found = conn.execute(select(func.min(c.id)).where(*same_step)).scalar()
        if found is not None:
            report = {k: v for k, v in row.items() if k != "created_at"}
            conn.execute(update(commands).where(*same_step).values(**report, reruns=c.reruns + 1))
            return int(found)
    key = conn.execute(insert(commands).values(**row)).inserted_primary_key
    assert key is not None
    return int(key[0])


def _upgrade_schema(engine: Engine) -> None:
    """Bring an existing database up to ``metadata``: missing columns, then missing indexes
    (``create_all`` only creates missing tables, with their indexes). A unique index added
    to an existing table would fail on rows that break it: migrate those by hand."""
    _add_missing_columns(engine)
    with engine.begin() as conn:
        for table in metadata.sorted_tables:
            for index in table.indexes:
                index.create(conn, checkfirst=True)


def _add_missing_columns(engine: Engine, meta: MetaData = metadata) -> list[str]:
    """``ALTER TABLE ... ADD COLUMN`` each column a table of ``meta`` declares and the
    database's table lacks (tables the database lacks are ``create_all``'s). The column is
    written as ``CREATE TABLE`` would write it (type, ``server_default``, ``NOT NULL``), so
    one that is not nullable needs a ``server_default`` for the rows already there
    (``ValueError`` naming it otherwise, before anything changes). The names added, as
    ``table.column``; works on SQLite and PostgreSQL."""
    with engine.begin() as conn:
        inspector = inspect(conn)
        present = set(inspector.get_table_names())
        missing: list[tuple[Table, Column[Any]]] = []
        for table in meta.sorted_tables:
            if table.name in present:
                have = {col["name"] for col in inspector.get_columns(table.name)}
                missing += [(table, col) for col in table.columns if col.name not in have]
        for table, column in missing:
            if not column.nullable and column.server_default is None:
                raise ValueError(
                    f"{table.name}.{column.name}: cannot add a NOT NULL column without a "
                    "server_default to an existing table"
                )
        quote = engine.dialect.identifier_preparer.format_table
        for table, column in missing:
            ddl = CreateColumn(column).compile(dialect=engine.dialect)
            conn.execute(text(f"ALTER TABLE {quote(table)} ADD COLUMN {ddl}"))
            log.info("storage: added column %s.%s", table.name, column.name)
    return [f"{table.name}.{column.name}" for table, column in missing]


def _event_columns(event: Mapping[str, Any]) -> dict[str, str]:
    e = event_dict(event)
    return {"text": str(e["text"]), "kind": str(e["kind"]), "severity": str(e["severity"])}


def _command_row(
    rover: str,
    sequence_id: int | None,
    step_index: int | None,
    command: str,
    status: str,
    reason: str | None,
    start_t_s: float,
    end_t_s: float,
    events: list[str],
) -> dict[str, Any]:
    return {
        "rover": rover,
        "sequence_id": sequence_id,
        "step_index": step_index,
        "command": command,
        "status": status,
        "reason": reason,
        "start_t_s": float(start_t_s),
        "end_t_s": float(end_t_s),
        "events": list(events),
        "created_at": _now(),
    }


class BatchWriter:
    """Queue writes from the simulation threads and flush them in one transaction at least
    once per ``interval_s`` (default 0.5 s) of wall time, from its own thread, so the
    simulation never waits on the database. A server killed with SIGKILL loses at most the
    writes of the last interval.

    The queueing methods only append under a lock. A flush writes everything queued when
    it starts, frames, events, commands and the latest checkpoint of each rover together,
    so a checkpoint is never committed without the telemetry queued before it. If that
    transaction fails (say, a command naming an unknown sequence), each kind is retried in
    its own transaction and only a kind that fails again is dropped (and logged), so one
    bad row cannot block telemetry for good. ``flushed_frames`` counts the frames committed.
    """

    def __init__(self, store: Store, interval_s: float = 0.5) -> None:
        self.store = store
        self.interval_s = interval_s
        self.flushed_frames = 0
        self.on_flush: Callable[[int], None] | None = None  # called with flushed_frames
        self._lock = threading.Lock()  # guards the queues
        self._flush_lock = threading.Lock()  # one flush at a time, in queue order
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._frames: list[tuple[str, dict[str, Any]]] = []
        self._events: list[tuple[str, float, Mapping[str, Any]]] = []
        self._commands: list[dict[str, Any]] = []
        self._checkpoints: dict[str, tuple[float, bytes]] = {}

    def start(self) -> None:
        """Start the flushing thread (a no-op if it runs)."""
        if self._thread is not None and self._thread.is_alive():
            return
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name="storage-writer", daemon=True)
        self._thread.start()

    def frames(self, rover: str, frames: list[dict[str, Any]]) -> None:
        """Queue telemetry frames."""
        with self._lock:
            self._frames.extend((rover, f) for f in frames)

    def events(self, rover: str, events: list[tuple[float, Mapping[str, Any]]]) -> None:
        """Queue events as (t_s, ``{"text", "kind", "severity"}``) pairs."""
        with self._lock:
            self._events.extend((rover, float(t), e) for t, e in events)

    def command(self, rover: str, **fields: Any) -> None:
        """Queue one command execution (the keyword arguments of ``Store.add_command``)."""
        row = _command_row(rover, **fields)  # a wrong field fails here, in the caller
        with self._lock:
            self._commands.append(row)

    def checkpoint(self, rover: str, t_s: float, blob: bytes) -> None:
        """Queue a rover's checkpoint; only the last one queued before a flush is written."""
        with self._lock:
            self._checkpoints[rover] = (t_s, blob)

    def flush(self) -> None:
        """Write everything queued so far; returns when it is committed (or dropped)."""
        with self._flush_lock:
            with self._lock:
                frames, self._frames = self._frames, []
                events, self._events = self._events, []
                commands_, self._commands = self._commands, []
                saved, self._checkpoints = self._checkpoints, {}
            if not (frames or events or commands_ or saved):
                return
            store = self.store
            parts: list[tuple[str, Callable[[Connection], None]]] = [
                ("frames", lambda conn: store._insert_frames(conn, frames)),
                ("events", lambda conn: store._insert_events(conn, events)),
                ("commands", lambda conn: store._record_commands(conn, commands_)),
                ("checkpoints", lambda conn: store._replace_checkpoints(conn, saved)),
            ]
            try:
                with store.engine.begin() as conn:
                    for _name, write in parts:
                        write(conn)
                written = len(frames)
            except Exception:
                log.exception("storage batch failed; retrying each kind on its own")
                written = self._write_parts(parts, len(frames))
            self.flushed_frames += written
            callback = self.on_flush
        if callback is not None:
            callback(self.flushed_frames)

    def _write_parts(
        self, parts: Iterable[tuple[str, Callable[[Connection], None]]], n_frames: int
    ) -> int:
        written = 0
        for name, write in parts:
            try:
                with self.store.engine.begin() as conn:
                    write(conn)
                if name == "frames":
                    written = n_frames
            except Exception:
                log.exception("storage: dropped a batch of %s", name)
        return written

    def stop(self) -> None:
        """Flush what is queued and end the thread."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
            self._thread = None
        self.flush()

    def _run(self) -> None:
        # Deadlines from the start of each flush: a slow flush shortens the next wait
        # rather than stretching the interval.
        next_t = time.monotonic() + self.interval_s
        while not self._stop.wait(max(0.0, next_t - time.monotonic())):
            next_t = time.monotonic() + self.interval_s
            try:
                self.flush()
            except Exception:  # never let the thread die: the next interval retries
                log.exception("storage flush failed")
