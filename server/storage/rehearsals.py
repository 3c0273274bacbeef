"""Rehearsal campaigns in the database (the ``rehearsals`` table, ``server.storage.schema``).

A campaign (``server.rehearsal.service``) is stored when it is asked for, its progress as it
goes (``done``), and its end: its state, when it finished, the workers' warm-up, an error,
its risk table (JSON) and its runs' outcomes (``sim.rehearsal.outcome.RunOutcome.as_dict``
each, as JSON compressed with zlib: 200 runs of a few steps with their thinned paths are
a few MB of JSON, a tenth of it compressed). So a restarted server lists the campaigns
that finished and serves their tables; one that was running when its server stopped is
stored as ``cancelled`` (``stop_unfinished``: "server stopped").
"""

from __future__ import annotations

import json
import zlib
from datetime import UTC, datetime
from typing import TYPE_CHECKING, Any

from sqlalchemy import insert, select, update

from server.storage.schema import now_utc, rehearsals_table

if TYPE_CHECKING:
    from server.storage.store import Store

UNFINISHED = ("queued", "running")
STATES = ("queued", "running", "done", "cancelled", "failed")
SERVER_STOPPED = "server stopped"
_SUMMARY = [c for c in rehearsals_table.c if c.name not in ("risk", "outcomes_z")]


def _iso(value: datetime | None) -> str | None:
    """UTC ISO 8601 (SQLite hands back naive datetimes, stored as UTC)."""
    if value is None:
        return None
    return (value if value.tzinfo else value.replace(tzinfo=UTC)).astimezone(UTC).isoformat()


def compress_outcomes(outcomes: list[dict[str, Any]]) -> bytes:
    """Outcome dicts as zlib-compressed strict JSON (NaN as null, as every stored JSON)."""
    from server.storage.store import json_dumps

    return zlib.compress(json_dumps(outcomes).encode("utf-8"), 6)


def decompress_outcomes(blob: bytes | None) -> list[dict[str, Any]] | None:
    """``compress_outcomes`` undone (``None`` for none stored)."""
    if blob is None:
        return None
    found: list[dict[str, Any]] = json.loads(zlib.decompress(blob).decode("utf-8"))
    return found


def _summary(row: Any) -> dict[str, Any]:
    m = row._mapping
    return {
        "id": int(m["id"]),
        "rover": m["rover"],
        "user": m["user"],
        "state": m["state"],
        "runs": int(m["runs"]),
        "done": int(m["done"]),
        "seed": int(m["seed"]),
        "sequence_id": m["sequence_id"],
        "sequence_text": m["sequence_text"],
        "created_t_utc": _iso(m["created_at"]),
        "finished_t_utc": _iso(m["finished_at"]),
        "warmup_s": m["warmup_s"],
        "error": m["error"],
    }


def add_rehearsal(
    store: Store, rover: str, user: str, runs: int, seed: int, sequence_id: int | None,
    sequence_text: str,
) -> dict[str, Any]:  # fmt: skip
    """A new campaign, ``queued``; its summary as stored."""
    with store.engine.begin() as conn:
        key = conn.execute(
            insert(rehearsals_table).values(
                rover=rover,
                user=user,
                state="queued",
                runs=runs,
                done=0,
                seed=seed,
                sequence_id=sequence_id,
                sequence_text=sequence_text,
                created_at=now_utc(),
            )
        ).inserted_primary_key
        assert key is not None
        row = conn.execute(select(*_SUMMARY).where(rehearsals_table.c.id == int(key[0]))).one()
    return _summary(row)


def update_rehearsal(store: Store, rehearsal_id: int, **values: Any) -> None:
    """Set columns of a campaign: ``state``, ``done``, ``warmup_s``, ``error``, ``risk``,
    ``outcomes`` (a list of outcome dicts, stored compressed); a final state sets
    ``finished_at``. ``KeyError`` if there is no such campaign."""
    if "state" in values and values["state"] not in STATES:
        raise ValueError(f"state: must be one of {', '.join(STATES)}, got {values['state']!r}")
    if "outcomes" in values:
        values["outcomes_z"] = compress_outcomes(values.pop("outcomes"))
    if values.get("state") in ("done", "cancelled", "failed"):
        values.setdefault("finished_at", now_utc())
    with store.engine.begin() as conn:
        result = conn.execute(
            update(rehearsals_table).where(rehearsals_table.c.id == rehearsal_id).values(**values)
        )
        if result.rowcount == 0:
            raise KeyError(f"no rehearsal {rehearsal_id}")


def list_rehearsals(store: Store, rover: str) -> list[dict[str, Any]]:
    """A rover's campaigns, newest first (summaries: no risk table, no outcomes)."""
    c = rehearsals_table.c
    query = select(*_SUMMARY).where(c.rover == rover).order_by(c.id.desc())
    with store.engine.connect() as conn:
        return [_summary(row) for row in conn.execute(query)]


def get_rehearsal(
    store: Store, rehearsal_id: int, with_outcomes: bool = False
) -> dict[str, Any] | None:
    """One campaign's summary and its ``risk`` table (``None`` until stored), with its
    ``outcomes`` when asked; ``None`` if there is no such campaign."""
    c = rehearsals_table.c
    columns = [*_SUMMARY, c.risk] + ([c.outcomes_z] if with_outcomes else [])
    with store.engine.connect() as conn:
        row = conn.execute(select(*columns).where(c.id == rehearsal_id)).first()
    if row is None:
        return None
    found = {**_summary(row), "risk": row._mapping["risk"]}
    if with_outcomes:
        found["outcomes"] = decompress_outcomes(row._mapping["outcomes_z"])
    return found


def stop_unfinished(store: Store, why: str = SERVER_STOPPED) -> list[int]:
    """Every campaign still ``queued`` or ``running`` (its server stopped, or was killed,
    while it ran) stored as ``cancelled`` with ``why``; their ids."""
    c = rehearsals_table.c
    with store.engine.begin() as conn:
        ids = [int(i) for i in conn.execute(select(c.id).where(c.state.in_(UNFINISHED))).scalars()]
        if ids:
            conn.execute(
                update(rehearsals_table)
                .where(c.id.in_(ids))
                .values(state="cancelled", error=why, finished_at=now_utc())
            )
    return ids
