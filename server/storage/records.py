"""The typed records the server hands to storage.

``CommandRecord`` is one executed (or refused) command as a rover runtime reports it
(``server.sinks.RuntimeListener.command_reported``): the server stores it
(``BatchWriter.command``) and announces it on the live timeline. Its fields are the columns
of the ``commands`` table, so a report and its stored row hold the same figures.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from sqlalchemy import func, insert, select, update
from sqlalchemy.engine import Connection

from server.storage.schema import commands, now_utc


@dataclass(frozen=True)
class CommandRecord:
    """A command's execution: ``sequence_id`` and ``step_index`` name its step (``None``
    for a command that is in no sequence), ``command`` is its text, ``status``
    ``completed``, ``refused`` or ``failed`` (``reason`` says why), ``start_t_s`` and
    ``end_t_s`` its span on the rover's clock (TT s from J2000), ``events`` the texts of
    the rover's events while it ran."""

    sequence_id: int | None
    step_index: int | None
    command: str
    status: str
    reason: str | None
    start_t_s: float
    end_t_s: float
    events: tuple[str, ...] = field(default=())


def command_row(rover: str, record: CommandRecord) -> dict[str, Any]:
    """The ``commands`` row of ``record`` (its columns, plus the rover and when it is
    written)."""
    return {
        "rover": rover,
        "sequence_id": record.sequence_id,
        "step_index": record.step_index,
        "command": record.command,
        "status": record.status,
        "reason": record.reason,
        "start_t_s": float(record.start_t_s),
        "end_t_s": float(record.end_t_s),
        "events": list(record.events),
        "created_at": now_utc(),
    }


def record_command(conn: Connection, row: dict[str, Any]) -> int:
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
