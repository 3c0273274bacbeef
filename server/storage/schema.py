"""The server's tables and how an existing database is brought up to them.

``metadata`` declares every table (sequences, commands, events, frames, images,
checkpoints, users, tokens, the audit log, alarms and their limits, rehearsal campaigns);
``upgrade_schema`` adds, when a database is opened, the columns and indexes this version
declares and an older database lacks (``create_all`` the tables it lacks), so it keeps
working (a column added this way must be nullable or have a ``server_default``), and
``server.storage.migrate`` then moves the data of an older layout. Events stored before
events had a kind and severity read back as ``LEGACY_KIND`` / ``LEGACY_SEVERITY``
(``event_dict``).
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from datetime import UTC, datetime
from typing import Any

from sqlalchemy import (
    JSON,
    BigInteger,
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
    inspect,
    text,
)
from sqlalchemy.engine import Engine
from sqlalchemy.schema import CreateColumn

from server.storage.columns import DOWNLINK, TRUTH

log = logging.getLogger(__name__)
metadata = MetaData()


def now_utc() -> datetime:
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
    Column("created_at", DateTime(timezone=True), nullable=False, default=now_utc),
    Column("updated_at", DateTime(timezone=True), nullable=False, default=now_utc),
    # who uploaded it (an immediate command: who sent it); null on rows from before accounts
    Column("submitted_by", String(64), nullable=True),
    # its command history (server.comm): [{"stage", "t_s", "detail"}] in the order learned
    Column("stages", JSON, nullable=True),
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
    Column("created_at", DateTime(timezone=True), nullable=False, default=now_utc),
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
    # on the ground then, across light time (server.comm); null: as it was made
    Column("received_t_s", Double, nullable=True),
    Index("ix_events_rover_t", "rover", "t_s"),
)

# Rehearsal campaigns (server.rehearsal.service; queries in server.storage.rehearsals): one
# row per campaign, its risk table as JSON and its run outcomes as zlib-compressed JSON.
rehearsals_table = Table(
    "rehearsals",
    metadata,
    Column("id", Integer, primary_key=True, autoincrement=True),
    Column("rover", String(64), nullable=False, index=True),
    Column("user", String(64), nullable=False),
    Column("state", String(16), nullable=False),  # queued, running, done, cancelled, failed
    Column("runs", Integer, nullable=False),
    Column("done", Integer, nullable=False, default=0),
    Column("seed", BigInteger, nullable=False),  # 0 .. 2**63 - 1
    Column("sequence_id", Integer, nullable=True),
    Column("sequence_text", Text, nullable=False),
    Column("created_at", DateTime(timezone=True), nullable=False, default=now_utc),
    Column("finished_at", DateTime(timezone=True), nullable=True),
    Column("warmup_s", Double, nullable=True),
    Column("error", Text, nullable=True),
    Column("risk", JSON, nullable=True),
    Column("outcomes_z", LargeBinary, nullable=True),
)

# The rover's downlink records (sim.loop.downlink), one row each: ``t_s`` and ``sol`` (what the
# queries select on), a Double column per numeric figure (``server.storage.columns``: a
# channel query reads one of them) and the rest as JSON in ``data``. ``layout`` is
# ``RECORD_LAYOUT`` for a row stored so; null on a row of a database written before
# (``data`` then holds the whole frame, truth and all), which opening it migrates
# (``server.storage.migrate``).
RECORD_LAYOUT = 2
frames_table = Table(
    "frames",
    metadata,
    Column("id", Integer, primary_key=True, autoincrement=True),
    Column("rover", String(64), nullable=False),
    Column("t_s", Double, nullable=False),
    Column("sol", Integer, nullable=False),
    Column("data", JSON, nullable=False),
    Column("layout", Integer, nullable=True),
    # on the ground then, across light time (server.comm); null: as it was made
    Column("received_t_s", Double, nullable=True),
    *DOWNLINK.table_columns(),
    Index("ix_frames_rover_t", "rover", "t_s"),
    Index("ix_frames_rover_sol", "rover", "sol"),
    Index("ix_frames_rover_id", "rover", "id"),  # the rows after a rover's last chunk
)

# What only the simulator knows, beside each frame of the downlink (``frames``): the truth
# records (sim.scoring.truth), in a table of their own so that the ground's queries never read
# them (docs/DESIGN.md, "Two records"), with their numbers in columns as the downlink's.
truth_frames = Table(
    "truth_frames",
    metadata,
    Column("id", Integer, primary_key=True, autoincrement=True),
    Column("rover", String(64), nullable=False),
    Column("t_s", Double, nullable=False),
    Column("data", JSON, nullable=False),
    *TRUTH.table_columns(),
    Index("ix_truth_frames_rover_t", "rover", "t_s"),
    Index("ix_truth_frames_rover_id", "rover", "id"),
)


# The images the rover sent (sim.loop.images), stored once when they arrive
# (server.storage.images): their metadata in columns and JSON (the features of a VO pair
# apart), the two 8-bit images encoded as PNG then, served as they are. A rover's image is
# one moment and kind: the unique index keeps it once when it is delivered again.
images_table = Table(
    "images",
    metadata,
    Column("id", Integer, primary_key=True, autoincrement=True),
    Column("rover", String(64), nullable=False),
    Column("t_s", Double, nullable=False),
    Column("kind", String(32), nullable=False),
    Column("width_px", Integer, nullable=False),
    Column("height_px", Integer, nullable=False),
    # on the ground then, across light time (server.comm); null: as it was made
    Column("received_t_s", Double, nullable=True),
    Column("meta", JSON, nullable=False),
    Column("features", JSON, nullable=True),
    Column("left_png", LargeBinary, nullable=False),
    Column("right_png", LargeBinary, nullable=False),
    Index("ux_images_rover_t_kind", "rover", "t_s", "kind", unique=True),
)


def chunk_table(name: str) -> Table:
    """A table of packed channels (``server.storage.chunks``): per rover, channel and chunk
    of rows (ids ``id_first``-``id_last``, ``n`` of them, times ``t_first``-``t_last``) the
    channel's values as little-endian float64 in ``data``."""
    return Table(
        name,
        metadata,
        Column("rover", String(64), primary_key=True),
        Column("channel", String(64), primary_key=True),
        Column("id_first", Integer, primary_key=True, autoincrement=False),
        Column("id_last", Integer, nullable=False),
        Column("t_first", Double, nullable=False),
        Column("t_last", Double, nullable=False),
        Column("n", Integer, nullable=False),
        Column("data", LargeBinary, nullable=False),
    )


# the downlink's channels by chunk of ``frames`` rows, and the truth's of ``truth_frames``
frame_chunks = chunk_table("frame_chunks")
truth_chunks = chunk_table("truth_chunks")

# The data migrations done on this database (``server.storage.migrate``), by name.
storage_steps = Table(
    "storage_steps",
    metadata,
    Column("name", String(64), primary_key=True),
    Column("done_at", DateTime(timezone=True), nullable=False, default=now_utc),
)

checkpoints = Table(
    "checkpoints",
    metadata,
    Column("rover", String(64), primary_key=True),
    Column("t_s", Double, nullable=False),
    Column("blob", LargeBinary, nullable=False),
    Column("saved_at", DateTime(timezone=True), nullable=False, default=now_utc),
)


# ---- accounts and the audit log (server.access.accounts, server.access.audit) ----------

users = Table(
    "users",
    metadata,
    Column("id", Integer, primary_key=True, autoincrement=True),
    Column("name", String(64), nullable=False, unique=True),
    Column("role", String(16), nullable=False),  # viewer, operator, conductor, admin
    Column("created_at", DateTime(timezone=True), nullable=False, default=now_utc),
)

api_tokens = Table(
    "api_tokens",
    metadata,
    Column("id", Integer, primary_key=True, autoincrement=True),
    Column("user_id", Integer, ForeignKey("users.id", ondelete="CASCADE"), nullable=False),
    # SHA-256 of the token (hex): the token itself is shown once and never stored
    Column("token_sha256", String(64), nullable=False, unique=True),
    Column("created_at", DateTime(timezone=True), nullable=False, default=now_utc),
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


def frame_events(data: dict[str, Any]) -> dict[str, Any]:
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
    # the data that raised it reached the ground then, across light time (null: at once)
    Column("received_t_s", Double, nullable=True),
    Column("raised_lmst_h", Double, nullable=False),
    Column("raised_sol", Integer, nullable=False),
    Column("cleared_t_s", Double, nullable=True),
    Column("cleared_utc", String(40), nullable=True),
    Column("cleared_lmst_h", Double, nullable=True),
    Column("acknowledged_by", String(64), nullable=True),
    Column("acknowledged_at", DateTime(timezone=True), nullable=True),  # wall-clock UTC
    # issue 21 (null on older rows, server.alarms.alarm_json reads them): the latest value
    # {value, t_s, utc, lmst_h, sol}; the active spans [[raised_t_s, cleared_t_s|null], ...];
    # an operator's shelf {by, reason, until: {t_s, utc, lmst_h, sol}}
    Column("latest", JSON, nullable=True),
    Column("spans", JSON, nullable=True),
    Column("shelved", JSON, nullable=True),
    Index("ix_alarms_rover_raised", "rover", "raised_t_s"),
)

alarm_limits = Table(
    "alarm_limits",
    metadata,
    Column("rover", String(64), primary_key=True),
    Column("channel", String(64), primary_key=True),
    Column("levels", JSON, nullable=False),  # {"warning", "critical"[, "hysteresis"]}
    Column("updated_by", String(64), nullable=True),
    Column("updated_at", DateTime(timezone=True), nullable=False, default=now_utc),
)


def sqlite_pragmas(dbapi_connection: Any, _record: Any) -> None:
    cursor = dbapi_connection.cursor()
    cursor.execute("PRAGMA journal_mode=WAL")
    cursor.execute("PRAGMA synchronous=NORMAL")
    cursor.execute("PRAGMA foreign_keys=ON")
    cursor.close()


def upgrade_schema(engine: Engine) -> None:
    """Bring an existing database up to ``metadata``: missing columns, then missing indexes
    (``create_all`` only creates missing tables, with their indexes). A unique index added
    to an existing table would fail on rows that break it: migrate those by hand. The data
    migrations come after it (``server.storage.migrate.upgrade_database``)."""
    add_missing_columns(engine)
    with engine.begin() as conn:
        for table in metadata.sorted_tables:
            for index in table.indexes:
                index.create(conn, checkfirst=True)


def add_missing_columns(engine: Engine, meta: MetaData = metadata) -> list[str]:
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
