"""A database written before the two records were stored apart (one ``frames`` table, each
row's ``data`` the whole merged frame, no truth table) opens with this version and is
migrated in place (``server.storage.migrate``): every field of the old frames comes back,
the downlink's from ``frames`` and the truth's from ``truths``, and their channels packed by
chunk (``server.storage.chunks``) are the old frames' numbers; in batches, and again from
where it was if it was stopped; on SQLite and PostgreSQL. The old frames are the reference
frames recorded in that format (``tests/sim/loop/frames_before_fast_loop.json.gz``)."""

from __future__ import annotations

import gzip
import json
import logging
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from sqlalchemy import (
    JSON,
    Column,
    Double,
    Index,
    Integer,
    MetaData,
    String,
    Table,
    create_engine,
    insert,
    select,
    text,
)

from server.storage import Store
from server.storage.migrate import SPLIT_STEP, split_merged_frames
from server.storage.schema import frames_table, storage_steps
from sim.loop.downlink import downlink_fields
from sim.scoring.truth import merged, truth_fields

REFERENCE = Path(__file__).parents[2] / "sim" / "loop" / "frames_before_fast_loop.json.gz"
SIDE_SCORES = {"position_error_m", "attitude_error_deg"}
CHUNK = 64  # rows a packed chunk (server.storage.chunks): a few chunks and rows after them

# The frames table of the release before (main's server/storage/schema.py), as it was.
OLD = MetaData()
OLD_FRAMES = Table(
    "frames",
    OLD,
    Column("id", Integer, primary_key=True, autoincrement=True),
    Column("rover", String(64), nullable=False),
    Column("t_s", Double, nullable=False),
    Column("sol", Integer, nullable=False),
    Column("data", JSON, nullable=False),
    Index("ix_frames_rover_t", "rover", "t_s"),
    Index("ix_frames_rover_sol", "rover", "sol"),
)


@pytest.fixture(scope="module")
def old_frames() -> list[dict[str, Any]]:
    with gzip.open(REFERENCE, "rt", encoding="utf-8") as f:
        frames: list[dict[str, Any]] = json.load(f)
    assert len(frames) > 400 and any(f["events"] for f in frames)
    assert any(f["estimators"] for f in frames)
    return frames


def old_database(url: str, frames: list[dict[str, Any]]) -> None:
    """A database as the release before wrote it: its frames table only, the merged frames
    in it (and a second rover's few)."""
    engine = create_engine(url)
    OLD.create_all(engine)
    rows = [{"rover": "spirit", "t_s": f["t_s"], "sol": f["sol"], "data": f} for f in frames]
    rows += [{**r, "rover": "opportunity"} for r in rows[:5]]
    with engine.begin() as conn:
        conn.execute(insert(OLD_FRAMES), rows)
    engine.dispose()


def _downlink(frame: dict[str, Any]) -> dict[str, Any]:
    """The downlink part of an old frame, every field (null where the old frame lacks it)."""
    out = {k: frame.get(k) for k in downlink_fields()}
    out["estimators"] = {
        n: {k: v for k, v in e.items() if k not in SIDE_SCORES}
        for n, e in frame["estimators"].items()
    }
    return out


def _truth(frame: dict[str, Any]) -> dict[str, Any]:
    out = {k: frame.get(k) for k in truth_fields()}
    out["events"] = []
    out["estimators"] = {
        n: {k: v for k, v in e.items() if k in SIDE_SCORES} for n, e in frame["estimators"].items()
    }
    return out


def check_every_field(store: Store, frames: list[dict[str, Any]]) -> None:
    downlinks = store.frames("spirit", -math.inf, math.inf)
    truths = store.truths("spirit", -math.inf, math.inf)
    assert len(downlinks) == len(frames) and len(truths) == len({f["t_s"] for f in frames})
    for old, downlink in zip(frames, downlinks, strict=True):
        assert downlink == _downlink(old)
        truth = truths[old["t_s"]]
        assert truth == _truth(old)
        # merged back, the old frame as it was (the fields it lacked: null)
        assert merged(downlink, truth) == {**dict.fromkeys(downlink), **truth, **old}
    assert len(store.frames("opportunity", -math.inf, math.inf)) == 5
    assert store.last_frame("spirit") == _downlink(frames[-1])
    assert store.sols("spirit") == sorted({f["sol"] for f in frames})


def test_an_old_database_is_split_into_the_two_records(
    store_url: str, old_frames: list[dict[str, Any]], caplog: pytest.LogCaptureFixture
) -> None:
    old_database(store_url, old_frames)
    with caplog.at_level(logging.INFO, logger="server.storage"):
        store = Store(store_url, chunk_frames=CHUNK)
    try:
        assert f"{SPLIT_STEP} done: {len(old_frames) + 5} frames split" in caplog.text
        chunks = len(old_frames) // CHUNK
        assert f"spirit in a chunk ({chunks} chunks so far)" in caplog.text  # the downlink's
        check_every_field(store, old_frames)
        # the numbers are in their columns and packed by chunk now: a channel is read so
        for name in ("attitude_error_deg", "tilt_est_deg"):
            got = store.channel("spirit", name, -math.inf, math.inf)
            assert got is not None
            want = [math.nan if f[name] is None else f[name] for f in old_frames]
            assert np.array_equal(got.values, want, equal_nan=True)
            assert got.t_s.tolist() == [f["t_s"] for f in old_frames]
        with store.engine.connect() as conn:
            assert conn.execute(select(frames_table.c.layout).distinct()).scalars().all() == [2]
    finally:
        store.close()
    caplog.clear()
    with caplog.at_level(logging.INFO, logger="server.storage"):
        again = Store(store_url, chunk_frames=CHUNK)  # opened again: nothing to do
    try:
        assert "split" not in caplog.text and "packed" not in caplog.text
        check_every_field(again, old_frames)
    finally:
        again.close()


def test_a_migration_stopped_half_way_carries_on(
    store_url: str, old_frames: list[dict[str, Any]], caplog: pytest.LogCaptureFixture
) -> None:
    """Batches of 100; the server killed after the first batches (here: the step's record
    removed and half the rows put back as they were): the next opening splits the rest,
    once each."""
    old_database(store_url, old_frames)
    store = Store(store_url)
    try:
        with store.engine.begin() as conn:
            conn.execute(storage_steps.delete())
            half = len(old_frames) // 2
            ids = conn.execute(select(frames_table.c.id).order_by(frames_table.c.id)).scalars()
            undo = list(ids)[half:]
            conn.execute(text("DELETE FROM truth_frames WHERE id > :n"), {"n": half})
            for i, frame in zip(undo, old_frames[half:] + old_frames[:5], strict=False):
                row = frames_table.update().where(frames_table.c.id == i)
                conn.execute(row.values(layout=None, data=frame))
        with caplog.at_level(logging.INFO, logger="server.storage.migrate"):
            split = split_merged_frames(store.engine, batch_rows=100)
        assert split == len(undo)
        assert caplog.text.count("old frames into downlink and truth rows") == math.ceil(
            len(undo) / 100
        )
        check_every_field(store, old_frames)
    finally:
        store.close()


def test_a_row_that_is_no_frame_is_refused_saying_what_to_do(
    store_url: str, old_frames: list[dict[str, Any]]
) -> None:
    old_database(store_url, old_frames[:3])
    engine = create_engine(store_url)
    with engine.begin() as conn:
        conn.execute(insert(OLD_FRAMES).values(rover="spirit", t_s=1.0, sol=1, data=[1, 2]))
    engine.dispose()
    with pytest.raises(RuntimeError, match=r"frames row 7 is not a frame .* delete the row"):
        Store(store_url)
