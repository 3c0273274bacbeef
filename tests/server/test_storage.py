"""Storage (issue 4, item 5): every Store method and the BatchWriter, on SQLite and on a real
PostgreSQL server (``store_url`` in conftest.py runs each test on both).

The telemetry is real: a Nadir Update's downlink records on the flat site (``as_dict()``);
larger sets are copies shifted in time."""

from __future__ import annotations

import itertools
import json
import math
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

import pytest

from server.storage import BatchWriter, CommandRecord, Store
from tests.frame_batches import scores_of

ROOT = Path(__file__).resolve().parents[2]
DT_S = 0.125  # 8 Hz
SOL_S = 88775.244  # a Mars solar day in seconds


@pytest.fixture(scope="module")
def real_frames() -> list[dict[str, Any]]:
    """The frames of one Nadir Update (about 10 s at 8 Hz; the last one has its event)."""
    from sequences import commands
    from sim.loop.session import RoverSession

    session = RoverSession("flat", 0, datetime(2004, 4, 14, 16, 30, tzinfo=UTC))
    report = session.execute(commands.NadirUpdate())
    assert report.status == "completed"
    frames = [f.as_dict() for f in session.downlinks]
    assert len(frames) > 40 and any(f["events"] for f in frames)
    return frames


@pytest.fixture
def store(store_url: str) -> Iterator[Store]:
    s = Store(store_url)
    yield s
    s.close()


def shifted(
    frames: list[dict[str, Any]], n: int, *, t0_s: float | None = None
) -> list[dict[str, Any]]:
    """``n`` frames cycling through ``frames`` at 8 Hz from ``t0_s`` (events only where the
    template has them), so big sets keep the real shape."""
    start = frames[0]["t_s"] if t0_s is None else t0_s
    return [
        {**frames[i % len(frames)], "t_s": start + i * DT_S, "events": []}
        if i >= len(frames)
        else {**frames[i], "t_s": start + i * DT_S}
        for i in range(n)
    ]


def all_frames(store: Store, rover: str = "spirit") -> list[dict[str, Any]]:
    return store.frames(rover, -math.inf, math.inf)


def test_sqlite_is_wal_with_foreign_keys(tmp_path: Path) -> None:
    from sqlalchemy import text

    store = Store(f"sqlite:///{tmp_path / 'r.db'}")
    try:
        with store.engine.connect() as conn:
            assert conn.execute(text("PRAGMA journal_mode")).scalar() == "wal"
            assert conn.execute(text("PRAGMA foreign_keys")).scalar() == 1
    finally:
        store.close()


# ---- sequences --------------------------------------------------------------------------


def test_sequences_round_trip_and_rejected_keep_errors(store: Store) -> None:
    steps = [{"command": "NADIR_UPDATE", "args": {}, "line": 2}]
    warn = [{"line": 3, "column": 1, "message": "drive while the AQF is not Fine"}]
    errors = [{"line": i, "column": 5, "message": f"unknown command FOO{i}"} for i in range(1, 13)]
    ok = store.add_sequence("spirit", "sol1", "NADIR_UPDATE\n", "text", "queued", [], warn, steps)
    bad = store.add_sequence("spirit", "broken", "FOO1\n", "text", "rejected", errors, [], [])
    other = store.add_sequence("opportunity", "x", "{}", "json", "queued", [], [], [])
    assert len({ok, bad, other}) == 3

    got = store.get_sequence(bad)
    assert got is not None
    assert got["status"] == "rejected" and got["errors"] == errors and got["steps"] == []
    assert got["rover"] == "spirit" and got["source"] == "FOO1\n" and got["format"] == "text"
    created = datetime.fromisoformat(got["created_at"])
    assert created.utcoffset() == timedelta(0)
    assert abs(datetime.now(UTC) - created) < timedelta(minutes=5)

    first = store.get_sequence(ok)
    assert first is not None and first["steps"] == steps and first["warnings"] == warn
    assert first["detail"] is None

    listed = store.list_sequences("spirit")
    assert [s["id"] for s in listed] == [bad, ok]  # newest first, this rover only
    assert all("source" not in s and "steps" not in s for s in listed)
    assert listed[0]["errors"] == errors

    store.set_sequence_status(ok, "completed", "all 1 steps done")
    after = store.get_sequence(ok)
    assert after is not None
    assert (after["status"], after["detail"]) == ("completed", "all 1 steps done")
    assert after["updated_at"] >= after["created_at"]
    assert store.get_sequence(10**6) is None
    with pytest.raises(KeyError):
        store.set_sequence_status(10**6, "completed")


# ---- commands and events ----------------------------------------------------------------


def test_commands_round_trip_and_overlap(store: Store) -> None:
    seq = store.add_sequence("spirit", "s", "", "text", "running", [], [], [])
    a = store.add_command(
        "spirit", seq, 0, "NADIR_UPDATE", "completed", None, 100.0, 110.0, ["Nadir Update ok"]
    )
    b = store.add_command(
        "spirit", None, None, "SUNFIND", "refused", "sun too low", 200.0, 200.0, []
    )
    store.add_command("opportunity", None, None, "WAIT", "completed", None, 100.0, 300.0, [])

    (got,) = store.commands("spirit", 105.0, 106.0)  # inside the first
    assert got["id"] == a and got["sequence_id"] == seq and got["step_index"] == 0
    assert got["command"] == "NADIR_UPDATE" and got["status"] == "completed"
    assert (got["start_t_s"], got["end_t_s"]) == (100.0, 110.0)
    assert got["events"] == ["Nadir Update ok"] and got["reason"] is None
    assert datetime.fromisoformat(got["created_at"]).utcoffset() == timedelta(0)

    assert [c["id"] for c in store.commands("spirit", 110.0, 200.0)] == [a, b]  # edges touch
    assert store.commands("spirit", 110.5, 199.5) == []
    (refused,) = store.commands("spirit", 150.0, 250.0)
    assert refused["reason"] == "sun too low" and refused["sequence_id"] is None


def test_a_step_recorded_twice_is_one_row_marked_as_a_rerun(store: Store) -> None:
    """Issue 13, defect 8: a step run again after a restart (its checkpoint older than its
    row) updates its row and counts the re-run; only a step of a sequence has a key."""
    seq = store.add_sequence("spirit", "s", "", "text", "running", [], [], [])
    first = store.add_command("spirit", seq, 0, "WAIT", "completed", None, 10.0, 20.0, [])
    other = store.add_command("spirit", seq, 1, "SUNFIND", "failed", "no sun", 20.0, 30.0, [])
    again = store.add_command("spirit", seq, 0, "WAIT", "completed", None, 10.0, 20.5, ["e"])
    assert again == first != other
    rows = store.commands("spirit", 0.0, 100.0)
    assert [(r["step_index"], r["reruns"]) for r in rows] == [(0, 1), (1, 0)]
    assert (rows[0]["end_t_s"], rows[0]["events"]) == (20.5, ["e"])  # the re-run's report
    store.add_command("spirit", seq, 0, "WAIT", "completed", None, 10.0, 20.0, [])
    assert store.commands("spirit", 0.0, 100.0)[0]["reruns"] == 2
    for _ in range(2):  # without a sequence, a command has no key: every one is a row
        store.add_command("spirit", None, None, "WAIT", "completed", None, 50.0, 60.0, [])
    assert len(store.commands("spirit", 0.0, 100.0)) == 4


def test_the_batch_writer_records_a_step_once(store: Store) -> None:
    seq = store.add_sequence("spirit", "s", "", "text", "running", [], [], [])
    writer = BatchWriter(store, interval_s=3600.0)

    def step(index: int, end_t_s: float) -> None:
        writer.command(
            "spirit", CommandRecord(seq, index, "WAIT", "completed", None, float(index), end_t_s)
        )

    step(0, 1.0)
    step(0, 1.5)  # twice in one batch
    step(1, 2.0)
    writer.flush()
    step(1, 2.5)  # and again in a later one
    writer.flush()
    rows = store.commands("spirit", 0.0, 10.0)
    assert [(r["step_index"], r["reruns"], r["end_t_s"]) for r in rows] == [
        (0, 1, 1.5),
        (1, 1, 2.5),
    ]


def test_an_old_database_is_upgraded_and_keeps_its_duplicates_working(store_url: str) -> None:
    """A database of the previous version: no ``reruns`` column, no index on the step, and
    a step already stored twice. Opening it adds both; its rows read back as not re-run, and
    recording that step again updates both of its rows rather than adding a third."""
    from sqlalchemy import inspect, text

    store = Store(store_url)
    seq = store.add_sequence("spirit", "s", "", "text", "running", [], [], [])
    with store.engine.begin() as conn:
        conn.execute(text("DROP INDEX ix_commands_sequence_step"))
        conn.execute(text("ALTER TABLE commands DROP COLUMN reruns"))
        for _ in range(2):  # the defect's duplicate
            conn.execute(
                text(
                    "INSERT INTO commands (rover, sequence_id, step_index, command, status,"
                    " start_t_s, end_t_s, events, created_at) VALUES ('spirit', :seq, 0,"
                    " 'WAIT', 'completed', 1.0, 2.0, '[]', :now)"
                ),
                {"seq": seq, "now": datetime.now(UTC)},
            )
    store.close()

    store = Store(store_url)
    try:
        inspector = inspect(store.engine)
        assert "reruns" in {c["name"] for c in inspector.get_columns("commands")}
        assert "ix_commands_sequence_step" in {i["name"] for i in inspector.get_indexes("commands")}
        assert [r["reruns"] for r in store.commands("spirit", 0.0, 10.0)] == [0, 0]
        store.add_command("spirit", seq, 0, "WAIT", "completed", None, 1.0, 2.0, [])
        store.add_command("spirit", seq, 1, "WAIT", "completed", None, 2.0, 3.0, [])
        rows = store.commands("spirit", 0.0, 10.0)
        assert [(r["step_index"], r["reruns"]) for r in rows] == [(0, 1), (0, 1), (1, 0)]
    finally:
        store.close()
    Store(store_url).close()  # and opening it again changes nothing


def test_missing_columns_are_added_to_any_table(store_url: str) -> None:
    """The schema upgrade is generic: any nullable or server-defaulted column a table of the
    metadata has and the database lacks is added, existing rows taking its default."""
    from sqlalchemy import Column, Integer, MetaData, String, Table, Text, insert, select

    from server.storage.schema import add_missing_columns

    def gadgets(*extra: Column[Any]) -> tuple[MetaData, Table]:
        meta = MetaData()
        table = Table("gadgets", meta, Column("id", Integer, primary_key=True), *extra)
        return meta, table

    store = Store(store_url)
    try:
        v1, table = gadgets(Column("name", String(16)))
        v1.create_all(store.engine)
        with store.engine.begin() as conn:
            conn.execute(insert(table).values(name="old"))
        v2, table = gadgets(
            Column("name", String(16)),
            Column("count", Integer, nullable=False, server_default="7"),
            Column("note", Text),
        )
        assert add_missing_columns(store.engine, v2) == ["gadgets.count", "gadgets.note"]
        assert add_missing_columns(store.engine, v2) == []
        with store.engine.begin() as conn:
            conn.execute(insert(table).values(name="new", note="n"))
            rows = conn.execute(select(table).order_by(table.c.id)).all()
        assert [tuple(r) for r in rows] == [(1, "old", 7, None), (2, "new", 7, "n")]
        v3, _ = gadgets(Column("name", String(16)), Column("size", Integer, nullable=False))
        with pytest.raises(ValueError, match=r"gadgets\.size"):
            add_missing_columns(store.engine, v3)
    finally:
        store.close()


def ev(text: str, kind: str = "site", severity: str = "info") -> dict[str, str]:
    return {"text": text, "kind": kind, "severity": severity}


def test_events_round_trip(store: Store) -> None:
    planted, failed = ev("Site 1 planted"), ev("Sunfind: no sun", "sunfind", "error")
    store.add_events("spirit", [(20.0, planted), (10.0, failed)])
    store.add_events("opportunity", [(15.0, ev("HGA pass, margin 1.2 deg", "hga"))])
    store.add_events("spirit", [])
    assert store.events("spirit", 0.0, 100.0) == [
        {"t_s": 10.0, **failed},
        {"t_s": 20.0, **planted},
    ]
    assert store.events("spirit", 10.0, 10.0) == [{"t_s": 10.0, **failed}]
    assert store.events("spirit", 11.0, 19.0) == []


def test_an_old_events_table_gains_kind_and_severity(
    store_url: str, real_frames: list[dict[str, Any]]
) -> None:
    """A database from before events had a kind and a severity: opening it adds both
    columns; its events, and the bare-text events inside its stored frames, read back as
    kind ``unknown``, severity ``info``, beside the new ones."""
    from sqlalchemy import inspect, text

    store = Store(store_url)
    old_frame = {**real_frames[0], "events": ["Nadir Update succeeded"]}
    store.add_frames("spirit", [old_frame], scores_of([old_frame]))
    with store.engine.begin() as conn:
        conn.execute(text("DROP INDEX ix_events_rover_t"))
        conn.execute(text("ALTER TABLE events DROP COLUMN kind"))
        conn.execute(text("ALTER TABLE events DROP COLUMN severity"))
        conn.execute(
            text("INSERT INTO events (rover, t_s, text) VALUES ('spirit', 1.0, 'Site planted')")
        )
    store.close()

    store = Store(store_url)
    try:
        columns = {c["name"] for c in inspect(store.engine).get_columns("events")}
        assert {"kind", "severity"} <= columns
        store.add_events("spirit", [(2.0, ev("Sunfind: no sun", "sunfind", "error"))])
        assert store.events("spirit", 0.0, 3.0) == [
            {"t_s": 1.0, "text": "Site planted", "kind": "unknown", "severity": "info"},
            {"t_s": 2.0, "text": "Sunfind: no sun", "kind": "sunfind", "severity": "error"},
        ]
        (frame,) = all_frames(store)
        assert frame["events"] == [
            {"text": "Nadir Update succeeded", "kind": "unknown", "severity": "info"}
        ]
        assert store.last_frame("spirit") == frame
    finally:
        store.close()


def test_the_event_log_filters_and_pages(store: Store) -> None:
    """``event_log``: kinds, severities, text (any case, ``%`` and ``_`` literal), a time
    window and before-t_s paging, newest first, with the count of all that match."""
    rows = [
        (1.0, ev("Site 1 planted")),
        (2.0, ev("Sunfind: 100% no sun_x", "sunfind", "error")),
        (3.0, ev("Sungaze: converged", "sungaze")),
        (4.0, ev("HGA pass with AQF Coarse: pointing not assured", "hga", "warning")),
        (5.0, ev("Site 2 planted")),
    ]
    store.add_events("spirit", rows)
    store.add_events("opportunity", rows)

    def texts(**kw: Any) -> tuple[list[str], int]:
        got, total = store.event_log("spirit", 0.0, 10.0, **kw)
        return [e["text"][:6] for e in got], total

    assert texts() == (["Site 2", "HGA pa", "Sungaz", "Sunfin", "Site 1"], 5)
    assert texts(kinds=["site", "hga"]) == (["Site 2", "HGA pa", "Site 1"], 3)
    assert texts(severities=["warning", "error"]) == (["HGA pa", "Sunfin"], 2)
    assert texts(text_contains="SUN") == (["Sungaz", "Sunfin"], 2)
    assert texts(text_contains="100%") == (["Sunfin"], 1)
    assert texts(text_contains="n_x") == (["Sunfin"], 1)
    assert texts(text_contains="0%_") == ([], 0)
    assert texts(limit=2) == (["Site 2", "HGA pa"], 5)
    assert texts(limit=2, offset=2) == (["Sungaz", "Sunfin"], 5)
    assert texts(before_t_s=4.0, limit=2) == (["Sungaz", "Sunfin"], 3)
    assert texts(kinds=["site"], newest_first=False) == (["Site 1", "Site 2"], 2)
    assert store.event_log("spirit", 2.0, 3.0)[1] == 2


# ---- telemetry frames -------------------------------------------------------------------


def test_frames_round_trip_exactly(store: Store, real_frames: list[dict[str, Any]]) -> None:
    store.add_frames("spirit", real_frames, scores_of(real_frames))
    store.add_frames("opportunity", real_frames[:3], scores_of(real_frames[:3]))
    assert all_frames(store) == real_frames  # every field, bit for bit
    t = [f["t_s"] for f in real_frames]
    assert store.frames("spirit", t[5], t[9]) == real_frames[5:10]  # bounds inclusive
    assert store.frames("spirit", t[0], t[-1], limit=4) == real_frames[:4]
    assert store.frames("spirit", t[-1] + 1.0, t[-1] + 2.0) == []
    assert len(all_frames(store, "opportunity")) == 3
    assert store.last_frame("spirit") == real_frames[-1]
    assert store.last_frame("curiosity") is None


def test_non_finite_floats_are_stored_as_null(
    store: Store, real_frames: list[dict[str, Any]]
) -> None:
    frame = {**real_frames[0], "tilt_est_deg": math.nan, "hga_margin_deg": -math.inf}
    store.add_frames("spirit", [frame], scores_of([frame]))
    (got,) = all_frames(store)
    assert got["tilt_est_deg"] is None and got["hga_margin_deg"] is None
    assert got["tilt_accel_deg"] == frame["tilt_accel_deg"]


def test_decimation_keeps_every_frame_with_events(
    store: Store, real_frames: list[dict[str, Any]]
) -> None:
    store.add_frames("spirit", real_frames, scores_of(real_frames))
    every_s = 2.0
    kept = store.frames("spirit", -math.inf, math.inf, every_s=every_s)
    with_events = [f for f in real_frames if f["events"]]
    assert with_events and all(f in kept for f in with_events)
    assert kept[0] == real_frames[0]
    assert len(kept) < len(real_frames) / 4
    for prev, cur in itertools.pairwise(kept):
        gap = cur["t_s"] - prev["t_s"]
        assert gap >= every_s - 1e-9 or cur["events"]  # only events come sooner
        assert gap <= every_s + DT_S + 1e-9  # and nothing more is dropped than asked
    assert store.frames("spirit", -math.inf, math.inf, every_s=every_s, limit=2) == kept[:2]
    assert store.frames("spirit", -math.inf, math.inf, every_s=0.0) == real_frames


def test_sols_and_sol_range(store: Store, real_frames: list[dict[str, Any]]) -> None:
    sol = real_frames[0]["sol"]
    later = [{**f, "t_s": f["t_s"] + SOL_S, "sol": sol + 1} for f in real_frames]
    store.add_frames("spirit", later, scores_of(later))  # out of order on purpose
    store.add_frames("spirit", real_frames, scores_of(real_frames))
    store.add_frames(
        "opportunity", [{**real_frames[0], "sol": 7}], scores_of([{**real_frames[0], "sol": 7}])
    )
    assert store.sols("spirit") == [sol, sol + 1]
    assert store.sols("opportunity") == [7]
    assert store.sols("curiosity") == []
    assert store.sol_range("spirit", sol) == (real_frames[0]["t_s"], real_frames[-1]["t_s"])
    assert store.sol_range("spirit", sol + 1) == (later[0]["t_s"], later[-1]["t_s"])
    assert store.sol_range("spirit", sol + 2) is None
    assert store.last_frame("spirit") == later[-1]


def test_data_survives_a_new_store_on_the_same_url(
    store_url: str, real_frames: list[dict[str, Any]]
) -> None:
    first = Store(store_url)
    first.add_frames("spirit", real_frames, scores_of(real_frames))
    seq = first.add_sequence("spirit", "s", "WAIT\n", "text", "queued", [], [], [])
    first.save_checkpoint("spirit", 123.5, b"state")
    first.close()
    second = Store(store_url)  # create_all again is harmless
    try:
        assert all_frames(second) == real_frames
        assert second.get_sequence(seq) is not None
        assert second.load_checkpoint("spirit") == (123.5, b"state")
    finally:
        second.close()


def test_checkpoint_replace(store: Store) -> None:
    assert store.load_checkpoint("spirit") is None
    big = bytes(range(256)) * 4096  # 1 MiB with every byte value, zeros included
    store.save_checkpoint("spirit", 10.0, big)
    store.save_checkpoint("opportunity", 11.0, b"\x00opp")
    assert store.load_checkpoint("spirit") == (10.0, big)
    store.save_checkpoint("spirit", 20.0, b"newer")
    assert store.load_checkpoint("spirit") == (20.0, b"newer")
    assert store.load_checkpoint("opportunity") == (11.0, b"\x00opp")


def test_5000_frames_in_one_batch(store: Store, real_frames: list[dict[str, Any]]) -> None:
    frames = shifted(real_frames, 5000)
    start = time.perf_counter()
    store.add_frames("spirit", frames, scores_of(frames))
    elapsed = time.perf_counter() - start
    print(f"\n5000 frames, one batch, {store.engine.dialect.name}: {elapsed:.3f} s")
    got = all_frames(store)
    assert len(got) == 5000 and got[-1] == frames[-1] and got[1234] == frames[1234]


# ---- the batch writer -------------------------------------------------------------------


def wait_for(check: Any, deadline_s: float = 10.0) -> float:
    """Poll ``check()`` until true; the seconds it took (fails at the deadline)."""
    start = time.monotonic()
    while not check():
        if time.monotonic() - start > deadline_s:
            pytest.fail(f"not written within {deadline_s} s")
        time.sleep(0.01)
    return time.monotonic() - start


def test_batch_writer_flushes_on_its_own(store: Store, real_frames: list[dict[str, Any]]) -> None:
    seq = store.add_sequence("spirit", "s", "", "text", "running", [], [], [])
    writer = BatchWriter(store, interval_s=0.2)
    writer.start()
    try:
        writer.frames("spirit", real_frames[:10], scores_of(real_frames[:10]))
        writer.events("spirit", [(real_frames[3]["t_s"], ev("Sungaze converged", "sungaze"))])
        writer.command(
            "spirit",
            CommandRecord(seq, 0, "SUNGAZE", "completed", None, 1.0, 2.0, ("Sungaze converged",)),
        )
        writer.checkpoint("spirit", 1.0, b"old")
        writer.checkpoint("spirit", 2.0, b"new")  # last one wins
        took = wait_for(lambda: store.load_checkpoint("spirit") is not None)
        print(f"\nwriter interval 0.2 s, visible after {took:.3f} s")
        # one transaction: once the checkpoint is there, so is the rest
        assert all_frames(store) == real_frames[:10]
        assert store.events("spirit", -math.inf, math.inf)[0]["text"] == "Sungaze converged"
        assert store.commands("spirit", 0.0, 3.0)[0]["sequence_id"] == seq
        assert store.load_checkpoint("spirit") == (2.0, b"new")
        assert writer.flushed_frames == 10

        writer.frames(
            "spirit", real_frames[10:20], scores_of(real_frames[10:20])
        )  # and again, with no flush() called
        wait_for(lambda: len(all_frames(store)) == 20)
    finally:
        writer.stop()


def test_batch_writer_stop_and_flush_write_everything(
    store: Store, real_frames: list[dict[str, Any]]
) -> None:
    writer = BatchWriter(store, interval_s=3600.0)  # never on its own in this test
    writer.start()
    writer.frames("spirit", real_frames[:5], scores_of(real_frames[:5]))
    writer.flush()
    assert len(all_frames(store)) == 5
    writer.frames("spirit", real_frames[5:], scores_of(real_frames[5:]))
    writer.events("spirit", [(1.0, ev("e"))])
    writer.stop()
    assert all_frames(store) == real_frames
    assert store.events("spirit", 0.0, 2.0) == [{"t_s": 1.0, **ev("e")}]


def test_batch_writer_drops_only_a_bad_row(
    store: Store, real_frames: list[dict[str, Any]], caplog: pytest.LogCaptureFixture
) -> None:
    writer = BatchWriter(store, interval_s=3600.0)
    writer.frames("spirit", real_frames[:3], scores_of(real_frames[:3]))
    writer.command(
        "spirit", CommandRecord(10**6, 0, "WAIT", "completed", None, 1.0, 2.0)
    )  # no such sequence: the foreign key refuses it
    writer.flush()
    assert all_frames(store) == real_frames[:3]
    assert store.commands("spirit", 0.0, 3.0) == []
    assert "dropped a batch of commands" in caplog.text


WRITER_SCRIPT = """
import json, sys, time
from server.storage import BatchWriter, Store

template = json.loads(sys.argv[2])
writer = BatchWriter(Store(sys.argv[1]), interval_s=0.1)
writer.on_flush = lambda n: print(n, flush=True)
writer.start()
i = 0
while True:
    batch = [dict(template, t_s=template["t_s"] + (i + k) * 0.125) for k in range(8)]
    writer.frames("spirit", batch, [{"t_s": f["t_s"], "events": []} for f in batch])
    i += len(batch)
    time.sleep(0.005)
"""


def test_sigkill_keeps_everything_flushed(
    store_url: str, real_frames: list[dict[str, Any]]
) -> None:
    template = {**real_frames[0], "events": []}
    proc = subprocess.Popen(
        [sys.executable, "-c", WRITER_SCRIPT, store_url, json.dumps(template)],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
    )
    flushed, lines = 0, 0
    try:
        assert proc.stdout is not None
        deadline = time.monotonic() + 15.0
        while lines < 4 or flushed < 500:  # a few flushes, mid-write
            line = proc.stdout.readline()
            if not line or time.monotonic() > deadline:
                proc.kill()
                pytest.fail(f"writer ended early: {proc.stderr.read() if proc.stderr else ''}")
            flushed, lines = int(line), lines + 1
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=10)
    assert proc.returncode == -signal.SIGKILL

    after = Store(store_url)
    try:
        got = [f["t_s"] for f in all_frames(after)]
    finally:
        after.close()
    print(f"\nkilled after {flushed} frames reported flushed; {len(got)} stored")
    assert len(got) >= flushed  # every flushed frame is there ...
    expected = [template["t_s"] + k * DT_S for k in range(len(got))]
    assert got == expected  # ... with no gap or duplicate (whole batches only)


def test_an_in_memory_store_loses_no_frame_to_a_reader_on_another_thread() -> None:
    """An in-memory SQLite database is one connection that every thread shares: a reader's
    rollback on return undid the writer's uncommitted frames (CI lost a whole sol's)."""
    store = Store("sqlite://")
    sequence_id = store.add_sequence("spirit", "x", "", "text", "queued", [], [], [])
    writer = BatchWriter(store)
    stop = threading.Event()

    def poll() -> None:
        while not stop.is_set():
            store.get_sequence(sequence_id)

    reader = threading.Thread(target=poll)
    reader.start()
    try:
        for batch in range(200):
            frames = [{"t_s": float(batch * 20 + i), "sol": 1, "events": []} for i in range(20)]
            writer.frames("spirit", frames, scores_of(frames))
            writer.flush()
    finally:
        stop.set()
        reader.join()
    assert len(store.frames("spirit", -math.inf, math.inf)) == 4000
