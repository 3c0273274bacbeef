"""``Store``: the synchronous queries of the operations server, one transaction each.

The request handlers call it; ``server.storage.writer.BatchWriter`` shares its batch
primitives (``_insert_frames`` ...) to commit high-rate writes together. The choices it
keeps (strict JSON with non-finite floats as null, UTC ISO 8601 timestamps, one command
row per step whatever the restarts) are the package's (``server.storage``).
"""

from __future__ import annotations

import functools
import json
import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from datetime import UTC, datetime
from typing import TYPE_CHECKING, Any, Concatenate, ParamSpec, TypeVar

from sqlalchemy import (
    create_engine,
    delete,
    event,
    func,
    insert,
    select,
    update,
)
from sqlalchemy.engine import Connection, Engine, RowMapping, make_url

from server.storage.channels import (
    DOWNLINK_ROW,
    FRAMES,
    TRUTH_ROW,
    TRUTHS,
    ChannelArrays,
    downlink_record,
    downlink_row,
    read_channel,
    truth_record,
    truth_row,
)
from server.storage.chunks import CHUNK_FRAMES, pack_new
from server.storage.engine import OneThreadAtATimePool
from server.storage.migrate import upgrade_database
from server.storage.records import CommandRecord, command_row, record_command

if TYPE_CHECKING:  # types only: storage loads without the simulator (roverops users)
    from sim.loop.downlink import DownlinkDict
    from sim.scoring.truth import TruthDict
from server.storage.schema import (
    alarm_limits,
    alarms_table,
    checkpoints,
    commands,
    event_dict,
    events,
    frames_table,
    metadata,
    now_utc,
    sequences,
    sqlite_pragmas,
    truth_frames,
)

P = ParamSpec("P")
R = TypeVar("R")


# a writer's queued telemetry: (rover, downlink records, truth records, received_t_s)
FrameRows = tuple[str, Sequence[Mapping[str, Any]], Sequence[Mapping[str, Any]], float | None]
# a queued event: (rover, t_s, event, received_t_s)
EventRow = tuple[str, float, Mapping[str, Any], float | None]


def _finite(value: Any) -> Any:
    """``value`` with every non-finite float (NaN, ±inf) replaced by ``None``."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, Mapping):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite(v) for v in value]
    return value


def json_dumps(value: Any) -> str:
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


def row_dict(row: RowMapping) -> dict[str, Any]:
    return {str(k): _iso(v) if isinstance(v, datetime) else v for k, v in row.items()}


def event_columns(event: Mapping[str, Any]) -> dict[str, str]:
    e = event_dict(event)
    return {"text": str(e["text"]), "kind": str(e["kind"]), "severity": str(e["severity"])}


def _after_queued_writes(
    read: Callable[Concatenate[Store, P], R],
) -> Callable[Concatenate[Store, P], R]:
    """A read of what the batch writer writes: it commits the writes queued so far first
    (``Store.commit_queued_with``), so a reader sees everything written before it asked."""

    @functools.wraps(read)
    def settled(store: Store, /, *args: P.args, **kwargs: P.kwargs) -> R:
        store._commit_queued()
        return read(store, *args, **kwargs)

    return settled


class Store:
    """The server's database: one engine, the tables created on first use.

    ``url`` is any SQLAlchemy URL: ``sqlite:///path/roverops.db`` (the embedded default),
    ``sqlite://`` (in memory, one shared connection: for tests and doctests), or
    ``postgresql+psycopg://user@host:port/db``. Every method is one transaction and safe to
    call from any thread. Times ``t_s`` are simulated TT seconds from J2000 (floats).
    """

    def __init__(self, url: str, chunk_frames: int = CHUNK_FRAMES) -> None:
        parsed = make_url(url)
        self.url = url
        self.chunk_frames = chunk_frames  # rows per packed chunk (server.storage.chunks)
        kwargs: dict[str, Any] = {"json_serializer": json_dumps}
        self.is_sqlite = parsed.get_backend_name() == "sqlite"
        if self.is_sqlite:
            # The writer thread and the request threads share the engine.
            kwargs["connect_args"] = {"check_same_thread": False, "timeout": 30.0}
            if parsed.database in (None, "", ":memory:"):
                kwargs["poolclass"] = OneThreadAtATimePool  # else each connection a new empty db
        else:
            kwargs["pool_pre_ping"] = True  # a restarted database server is not an error
        self.engine: Engine = create_engine(url, **kwargs)
        if self.is_sqlite:
            event.listen(self.engine, "connect", sqlite_pragmas)
        metadata.create_all(self.engine)
        upgrade_database(self.engine, chunk_frames)
        self._commit_queued: Callable[[], None] = lambda: None

    def commit_queued_with(self, flush: Callable[[], None]) -> None:
        """Have every read of frames, events, commands and checkpoints call ``flush`` first
        (the ``BatchWriter`` of this store registers its own), so no reader flushes."""
        self._commit_queued = flush

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
                .values(status=status, detail=detail, updated_at=now_utc())
            )
            if result.rowcount == 0:
                raise KeyError(f"no sequence {sequence_id}")

    def add_stage(
        self, sequence_id: int, stage: str, t_s: float, detail: str | None = None
    ) -> bool:
        """Add a stage to a sequence's command history, unless it has that stage already
        (a report delivered again after a restart); whether it was added."""
        c = sequences.c
        with self.engine.begin() as conn:
            found = conn.execute(select(c.stages).where(c.id == sequence_id)).first()
            if found is None:
                raise KeyError(f"no sequence {sequence_id}")
            stages = list(found[0] or [])
            if any(s["stage"] == stage for s in stages):
                return False
            stages.append({"stage": stage, "t_s": float(t_s), "detail": detail})
            conn.execute(update(sequences).where(c.id == sequence_id).values(stages=stages))
        return True

    @_after_queued_writes
    def stored_frame_times(self, rover: str, t_s: Iterable[float]) -> set[float]:
        """Which of the times ``t_s`` have a downlink record of ``rover`` stored."""
        wanted = sorted({float(t) for t in t_s})
        if not wanted:
            return set()
        f = frames_table.c
        query = select(f.t_s).where(f.rover == rover, f.t_s >= wanted[0], f.t_s <= wanted[-1])
        with self.engine.connect() as conn:
            return {float(t) for (t,) in conn.execute(query)} & set(wanted)

    def get_sequence(self, sequence_id: int) -> dict[str, Any] | None:
        """Every column of one sequence (JSON decoded, times ISO), or ``None``."""
        with self.engine.connect() as conn:
            row = conn.execute(select(sequences).where(sequences.c.id == sequence_id)).first()
        return None if row is None else row_dict(row._mapping)

    def list_sequences(self, rover: str) -> list[dict[str, Any]]:
        """A rover's sequences, newest first, without the bulky ``source`` and ``steps``."""
        cols = [c for c in sequences.c if c.name not in ("source", "steps")]
        query = select(*cols).where(sequences.c.rover == rover).order_by(sequences.c.id.desc())
        with self.engine.connect() as conn:
            return [row_dict(r._mapping) for r in conn.execute(query)]

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
        record = CommandRecord(sequence_id, step_index, command, status, reason,
                               start_t_s, end_t_s, tuple(events))  # fmt: skip
        row = command_row(rover, record)
        with self.engine.begin() as conn:
            return record_command(conn, row)

    @_after_queued_writes
    def commands(self, rover: str, t_from: float, t_to: float) -> list[dict[str, Any]]:
        """Commands whose [start, end] overlaps [t_from, t_to], by start time."""
        c = commands.c
        query = (
            select(commands)
            .where(c.rover == rover, c.start_t_s <= t_to, c.end_t_s >= t_from)
            .order_by(c.start_t_s, c.id)
        )
        with self.engine.connect() as conn:
            return [row_dict(r._mapping) for r in conn.execute(query)]

    # ---- events ------------------------------------------------------------------

    def add_events(self, rover: str, events: list[tuple[float, Mapping[str, Any]]]) -> None:
        """Store events as (t_s, ``{"text", "kind", "severity"}``) pairs."""
        with self.engine.begin() as conn:
            self._insert_events(conn, [(rover, t, e, None) for t, e in events])

    def events(self, rover: str, t_from: float, t_to: float) -> list[dict[str, Any]]:
        """Events with t_from <= t_s <= t_to, in time order, as
        ``{"t_s", "text", "kind", "severity"}``."""
        return self.event_log(rover, t_from, t_to, newest_first=False)[0]

    @_after_queued_writes
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

    def add_frames(
        self,
        rover: str,
        downlinks: list[dict[str, Any]],
        truths: list[dict[str, Any]],
        received_t_s: float | None = None,
    ) -> None:
        """Store frames, the downlink records (``Downlink.as_dict()``) and the truth records
        (``Truth.as_dict()``), in one transaction: paired, or either alone (across light
        time the downlink comes when it reaches the ground, at ``received_t_s``)."""
        with self.engine.begin() as conn:
            self._insert_frames(conn, [(rover, downlinks, truths, received_t_s)])

    @_after_queued_writes
    def frames(
        self,
        rover: str,
        t_from: float,
        t_to: float,
        every_s: float = 0.0,
        limit: int | None = None,
        with_truth: bool = False,
    ) -> list[dict[str, Any]]:
        """Downlink records with t_from <= t_s <= t_to, ascending, at most ``limit`` of them;
        ``with_truth``: each merged with its truth record (``sim.scoring.truth.merged``).

        With ``every_s > 0`` they are decimated: a frame is kept when it is at least
        ``every_s`` after the last kept frame, and a frame with events is always kept (and
        then counts as the last kept one), so decimation never hides an event.
        """
        query = (
            select(*DOWNLINK_ROW)
            .where(FRAMES.rover == rover, FRAMES.t_s >= t_from, FRAMES.t_s <= t_to)
            .order_by(FRAMES.t_s, FRAMES.id)
        )
        out: list[DownlinkDict] = []
        if limit is not None and limit <= 0:
            return []
        last = -math.inf
        with self.engine.connect() as conn:
            for row in conn.execution_options(yield_per=2000).execute(query):
                t_s, data = row[0], row[2]
                if every_s > 0.0 and t_s - last < every_s and not data.get("events"):
                    continue
                last = t_s
                out.append(downlink_record(row))
                if limit is not None and len(out) >= limit:
                    break
        if with_truth and out:
            truths = self.truths(rover, out[0]["t_s"], out[-1]["t_s"])
            # imported here: the accounts' commands (roverops users) load storage without
            # the simulator (tests/cli/test_cli_imports.py)
            from sim.scoring.truth import merged

            return [merged(d, truths[d["t_s"]]) if d["t_s"] in truths else dict(d) for d in out]
        return [dict(d) for d in out]

    @_after_queued_writes
    def channel(self, rover: str, name: str, t_from: float, t_to: float) -> ChannelArrays | None:
        """One stored channel (a numeric column of the downlink or of the truth record,
        ``server.storage.columns``) over t_from <= t_s <= t_to, as arrays beside the frames'
        ``t_s``, ``sol`` and ``lmst_h`` (``server.storage.channels``); ``None`` if no column
        holds it (a side estimator's figure: read it from ``frames``)."""
        with self.engine.connect() as conn:
            return read_channel(conn, rover, name, t_from, t_to)

    @_after_queued_writes
    def sols(self, rover: str) -> list[int]:
        """The sols that have telemetry, ascending."""
        f = frames_table.c
        query = select(f.sol).where(f.rover == rover).distinct().order_by(f.sol)
        with self.engine.connect() as conn:
            return [int(s) for s in conn.execute(query).scalars()]

    @_after_queued_writes
    def sol_range(self, rover: str, sol: int) -> tuple[float, float] | None:
        """The first and last frame times of a sol, or ``None`` without telemetry."""
        f = frames_table.c
        query = select(func.min(f.t_s), func.max(f.t_s)).where(f.rover == rover, f.sol == sol)
        with self.engine.connect() as conn:
            lo, hi = conn.execute(query).one()
        return None if lo is None else (float(lo), float(hi))

    @_after_queued_writes
    def last_frame(self, rover: str) -> DownlinkDict | None:
        """The latest downlink record of a rover, or ``None``."""
        query = (
            select(*DOWNLINK_ROW)
            .where(FRAMES.rover == rover)
            .order_by(FRAMES.t_s.desc(), FRAMES.id.desc())
            .limit(1)
        )
        with self.engine.connect() as conn:
            row = conn.execute(query).first()
        return None if row is None else downlink_record(row)

    @_after_queued_writes
    def last_truth(self, rover: str) -> TruthDict | None:
        """The latest truth record of a rover, or ``None``."""
        query = (
            select(*TRUTH_ROW)
            .where(TRUTHS.rover == rover)
            .order_by(TRUTHS.t_s.desc(), TRUTHS.id.desc())
            .limit(1)
        )
        with self.engine.connect() as conn:
            row = conn.execute(query).first()
        return None if row is None else truth_record(row)

    @_after_queued_writes
    def truths(self, rover: str, t_from: float, t_to: float) -> dict[float, TruthDict]:
        """The truth records with t_from <= t_s <= t_to, by their time."""
        query = (
            select(*TRUTH_ROW)
            .where(TRUTHS.rover == rover, TRUTHS.t_s >= t_from, TRUTHS.t_s <= t_to)
            .order_by(TRUTHS.t_s, TRUTHS.id)
        )
        with self.engine.connect() as conn:
            rows = conn.execution_options(yield_per=2000).execute(query)
            return {float(row[0]): truth_record(row) for row in rows}

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
            return [row_dict(r._mapping) for r in conn.execute(query)]

    def set_limits(self, rover: str, channel: str, levels: dict[str, Any], by: str) -> None:
        """Store an operator's levels for a channel (replacing earlier ones)."""
        c = alarm_limits.c
        with self.engine.begin() as conn:
            conn.execute(delete(alarm_limits).where(c.rover == rover, c.channel == channel))
            conn.execute(insert(alarm_limits).values(
                rover=rover, channel=channel, levels=levels, updated_by=by, updated_at=now_utc()
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
            return {r.channel: row_dict(r._mapping) for r in rows}

    # ---- checkpoints: the latest simulation state, an opaque blob ---------------

    def save_checkpoint(self, rover: str, t_s: float, blob: bytes) -> None:
        """Replace the rover's checkpoint."""
        with self.engine.begin() as conn:
            self._replace_checkpoints(conn, {rover: (t_s, blob)})

    @_after_queued_writes
    def load_checkpoint(self, rover: str) -> tuple[float, bytes] | None:
        """The rover's checkpoint as (t_s, blob), or ``None``."""
        c = checkpoints.c
        with self.engine.connect() as conn:
            row = conn.execute(select(c.t_s, c.blob).where(c.rover == rover)).first()
        return None if row is None else (float(row.t_s), bytes(row.blob))

    # ---- the batch primitives, shared with BatchWriter ----------------------------

    def _insert_frames(self, conn: Connection, rows: list[FrameRows]) -> None:
        downlinks = [{**downlink_row(r, d), "received_t_s": got} for r, ds, _, got in rows
                     for d in ds]  # fmt: skip
        truths = [truth_row(r, t) for r, _, ts, _ in rows for t in ts]
        if downlinks:
            conn.execute(insert(frames_table), downlinks)
        if truths:
            conn.execute(insert(truth_frames), truths)
        if downlinks or truths:
            pack_new(conn, sorted({r[0] for r in rows}), self.chunk_frames)

    @_after_queued_writes
    def received_until(self, rover: str) -> float:
        """The latest ``received_t_s`` of the rover's stored frames and events: what came
        down across light time up to then is stored (``-inf``: nothing yet)."""
        with self.engine.connect() as conn:
            got = [
                conn.execute(select(func.max(t.c.received_t_s)).where(t.c.rover == rover)).scalar()
                for t in (frames_table, events)
            ]
        return max((float(g) for g in got if g is not None), default=-math.inf)

    def _insert_events(self, conn: Connection, rows: list[EventRow]) -> None:
        if rows:
            conn.execute(
                insert(events),
                [{"rover": r, "t_s": float(t), "received_t_s": got, **event_columns(x)}
                 for r, t, x, got in rows],
            )  # fmt: skip

    def _record_commands(self, conn: Connection, rows: list[dict[str, Any]]) -> None:
        for row in rows:  # a few per flush: one per step completed
            record_command(conn, row)

    def _replace_checkpoints(self, conn: Connection, saved: dict[str, tuple[float, bytes]]) -> None:
        # Delete-then-insert in one transaction is the portable upsert; only the writer
        # thread (or a test) saves checkpoints, so there is no concurrent insert to race.
        if not saved:
            return
        conn.execute(delete(checkpoints).where(checkpoints.c.rover.in_(list(saved))))
        conn.execute(
            insert(checkpoints),
            [{"rover": r, "t_s": float(t), "blob": b, "saved_at": now_utc()}
             for r, (t, b) in saved.items()],
        )  # fmt: skip
