"""Storage of the operations server: sequences, commands, events, telemetry and checkpoints.

One SQLAlchemy 2 (Core) layer over any database URL, so that the embedded default (SQLite,
a file under the data directory) and a shared server (PostgreSQL) behave the same and run
the same tests. ``Store`` is the synchronous API the request handlers call; ``BatchWriter``
takes the high-rate writes off the simulation threads (DESIGN.md: "server stores frames
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

>>> store = Store("sqlite://")
>>> store.add_events("spirit", [(10.0, "Site planted")])
>>> store.events("spirit", 0.0, 20.0)
[{'t_s': 10.0, 'text': 'Site planted'}]
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
    update,
)
from sqlalchemy import text as sql_text
from sqlalchemy.engine import Connection, Engine, RowMapping, make_url
from sqlalchemy.pool import StaticPool

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
    Index("ix_commands_rover_start", "rover", "start_t_s"),
)

events = Table(
    "events",
    metadata,
    Column("id", Integer, primary_key=True, autoincrement=True),
    Column("rover", String(64), nullable=False),
    Column("t_s", Double, nullable=False),
    Column("text", Text, nullable=False),
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


def add_missing_columns(engine: Engine) -> list[str]:
    """Bring a database made by an older version up to ``metadata``: every column the code
    declares and the table lacks is added (``ALTER TABLE ... ADD COLUMN``, nullable, on
    SQLite and PostgreSQL alike). New tables come from ``create_all``; this covers the
    columns later versions add to existing tables. Returns ``table.column`` added."""
    inspector = inspect(engine)
    added: list[str] = []
    with engine.begin() as conn:
        for table in metadata.sorted_tables:
            if not inspector.has_table(table.name):
                continue
            have = {c["name"] for c in inspector.get_columns(table.name)}
            for column in table.columns:
                if column.name in have:
                    continue
                if not column.nullable:
                    raise RuntimeError(f"cannot add NOT NULL column {table.name}.{column.name}")
                kind = column.type.compile(dialect=engine.dialect)
                preparer = engine.dialect.identifier_preparer
                conn.execute(
                    sql_text(
                        f"ALTER TABLE {preparer.quote(table.name)} "
                        f"ADD COLUMN {preparer.quote(column.name)} {kind}"
                    )
                )
                added.append(f"{table.name}.{column.name}")
    if added:
        log.warning("storage: upgraded the schema, added %s", ", ".join(added))
    return added


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
        add_missing_columns(self.engine)

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
        """Store one executed or refused command; its new id."""
        row = _command_row(rover, sequence_id, step_index, command, status, reason,
                           start_t_s, end_t_s, events)  # fmt: skip
        with self.engine.begin() as conn:
            key = conn.execute(insert(commands).values(**row)).inserted_primary_key
            assert key is not None
            return int(key[0])

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

    def add_events(self, rover: str, events: list[tuple[float, str]]) -> None:
        """Store events as (t_s, text) pairs."""
        with self.engine.begin() as conn:
            self._insert_events(conn, [(rover, t, text) for t, text in events])

    def events(self, rover: str, t_from: float, t_to: float) -> list[dict[str, Any]]:
        """Events with t_from <= t_s <= t_to, in time order, as ``{"t_s", "text"}``."""
        e = events.c
        query = (
            select(e.t_s, e.text)
            .where(e.rover == rover, e.t_s >= t_from, e.t_s <= t_to)
            .order_by(e.t_s, e.id)
        )
        with self.engine.connect() as conn:
            return [{"t_s": r.t_s, "text": r.text} for r in conn.execute(query)]

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
                out.append(data)
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
        return data

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

    def _insert_events(self, conn: Connection, rows: list[tuple[str, float, str]]) -> None:
        if rows:
            conn.execute(
                insert(events), [{"rover": r, "t_s": float(t), "text": x} for r, t, x in rows]
            )

    def _insert_commands(self, conn: Connection, rows: list[dict[str, Any]]) -> None:
        if rows:
            conn.execute(insert(commands), rows)

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
        self._events: list[tuple[str, float, str]] = []
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

    def events(self, rover: str, events: list[tuple[float, str]]) -> None:
        """Queue events as (t_s, text) pairs."""
        with self._lock:
            self._events.extend((rover, float(t), text) for t, text in events)

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
                ("commands", lambda conn: store._insert_commands(conn, commands_)),
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
