"""Data migrations, run when a database is opened (``upgrade_database``: after the schema is
brought up to this version's tables, ``server.storage.schema.upgrade_schema``).

``split_merged_frames``: a database written before the two records were stored apart (one
``frames`` row per frame, its ``data`` the whole frame as JSON: the downlink's fields and the
truth's side by side, as ``sim.scoring.truth.merged`` gives them) has each frame split into
its downlink row (the numbers in their columns, ``server.storage.columns``) and its truth
row (``truth_frames``), by the records' field names (``downlink_fields``, ``truth_fields``):
the side estimators' poses stay with the downlink and their errors go to the truth; the
events stay with the downlink (they were the frame's, and are in the events table too); a
field the old frame lacks reads back as null, a key of neither record stays with the
downlink. It runs in batches of ``BATCH_ROWS`` frames, each batch one transaction that
marks its rows done (``layout``), so a migration stopped half-way (the server killed)
carries on where it was at the next opening; once no old row is left it is recorded in
``storage_steps`` and not looked for again. Each batch is logged.

``pack_stored`` (``server.storage.chunks``): a database written before the channels were
packed by chunk has its rows packed, a chunk a transaction, logged; a database that has
them packs only what has filled a chunk since (nothing, after a clean stop).
"""

from __future__ import annotations

import logging
from typing import Any

from sqlalchemy import bindparam, insert, select, update
from sqlalchemy.engine import Engine

from server.storage.chunks import CHUNK_FRAMES, pack_stored
from server.storage.columns import DOWNLINK, TRUTH
from server.storage.schema import (
    RECORD_LAYOUT,
    frames_table,
    storage_steps,
    truth_frames,
    upgrade_schema,
)
from sim.loop.downlink import downlink_fields
from sim.scoring.truth import truth_fields

log = logging.getLogger(__name__)

SPLIT_STEP = "frames_split_into_downlink_and_truth"
BATCH_ROWS = 2000
# the truth's own fields (t_s is both records', events and estimators are split below)
TRUTH_ONLY = frozenset(truth_fields()) - frozenset(downlink_fields())
SIDE_SCORES = frozenset({"position_error_m", "attitude_error_deg"})  # a side estimator's errors


def upgrade_database(engine: Engine, chunk_frames: int = CHUNK_FRAMES) -> None:
    """This version's tables, columns and indexes (``upgrade_schema``), then the data
    migrations: the old merged frames split (``split_merged_frames``), then the channels of
    the rows no chunk holds yet packed (``server.storage.chunks.pack_stored``)."""
    upgrade_schema(engine)
    split_merged_frames(engine)
    pack_stored(engine, chunk_frames)


def split_merged(frame: dict[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    """An old merged frame as its downlink record and its truth record (module docstring)."""
    side = frame.get("estimators") or {}
    downlink = {k: v for k, v in frame.items() if k not in TRUTH_ONLY}
    downlink["estimators"] = {
        name: {k: v for k, v in (e or {}).items() if k not in SIDE_SCORES}
        for name, e in side.items()
    }
    truth = {k: frame[k] for k in truth_fields() if k in TRUTH_ONLY and k in frame}
    truth["t_s"] = frame["t_s"]
    truth["events"] = []
    truth["estimators"] = {
        name: {k: v for k, v in (e or {}).items() if k in SIDE_SCORES} for name, e in side.items()
    }
    return downlink, truth


def split_merged_frames(engine: Engine, batch_rows: int = BATCH_ROWS) -> int:
    """Split the old merged frames of the database (module docstring); how many it split."""
    with engine.connect() as conn:
        if conn.execute(
            select(storage_steps.c.name).where(storage_steps.c.name == SPLIT_STEP)
        ).first():
            return 0
    f = frames_table.c
    set_columns: dict[str, Any] = {c: bindparam(c) for c in ("data", *DOWNLINK.columns)}
    rewrite = (
        update(frames_table)
        .where(f.id == bindparam("row_id"))
        .values(layout=RECORD_LAYOUT, **set_columns)
    )
    after, split = 0, 0
    while True:
        with engine.begin() as conn:
            rows = conn.execute(
                select(f.id, f.rover, f.t_s, f.data)
                .where(f.id > after, f.layout.is_(None))
                .order_by(f.id)
                .limit(batch_rows)
            ).all()
            if not rows:
                break
            downlinks, truths = [], []
            for row in rows:
                if not isinstance(row.data, dict) or "t_s" not in row.data:
                    raise RuntimeError(
                        f"frames row {row.id} is not a frame of this server "
                        f"({str(row.data)[:80]}): delete the row, or restore the database "
                        "from a backup, then start the server again"
                    )
                downlink, truth = split_merged({**row.data, "t_s": row.t_s})
                downlinks.append({"row_id": row.id, **DOWNLINK.encode(downlink)})
                truths.append({"rover": row.rover, "t_s": row.t_s, **TRUTH.encode(truth)})
            conn.execute(rewrite, downlinks)
            conn.execute(insert(truth_frames), truths)
        after = rows[-1].id
        split += len(rows)
        log.info("storage: split %d old frames into downlink and truth rows (%d so far)",
                 len(rows), split)  # fmt: skip
    with engine.begin() as conn:
        conn.execute(insert(storage_steps).values(name=SPLIT_STEP))
    if split:
        log.info("storage: migration %s done: %d frames split", SPLIT_STEP, split)
    return split
