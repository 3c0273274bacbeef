"""Reads see what was written (issue 21, "Typed boundaries"): a write queued on the
``BatchWriter`` is what the next read of the store returns, with no ``writer.flush()`` in
the reader; so no route flushes."""

from __future__ import annotations

import ast
import math
from collections.abc import Iterator
from pathlib import Path

import pytest

from server.storage import BatchWriter, CommandRecord, Store

API = Path(__file__).resolve().parents[3] / "server" / "api"
EVENT = {"text": "NADIR_UPDATE done", "kind": "command", "severity": "info"}


@pytest.fixture
def store(store_url: str) -> Iterator[Store]:
    s = Store(store_url)
    yield s
    s.close()


def test_each_queued_write_is_read_back_without_a_flush(store: Store) -> None:
    writer = BatchWriter(store, interval_s=3600.0)  # its thread never started: no flush of its own
    seq = store.add_sequence("spirit", "s", "", "text", "running", [], [], [])
    downlink = {"t_s": 10.0, "sol": 3, "events": [], "aqf": "Fine"}
    writer.frames("spirit", [downlink], [{"t_s": 10.0, "position_error_m": 0.25}])
    writer.events("spirit", [(10.0, EVENT)])
    writer.command("spirit", CommandRecord(seq, 0, "WAIT", "completed", None, 9.0, 10.0))
    writer.checkpoint("spirit", 10.0, b"state")
    assert store.sols("spirit") == [3]
    assert [f["t_s"] for f in store.frames("spirit", -math.inf, math.inf)] == [10.0]
    assert store.truths("spirit", 0.0, 20.0)[10.0]["position_error_m"] == 0.25
    assert store.events("spirit", 0.0, 20.0) == [{"t_s": 10.0, **EVENT}]
    assert [c["command"] for c in store.commands("spirit", 0.0, 20.0)] == ["WAIT"]
    assert store.load_checkpoint("spirit") == (10.0, b"state")
    writer.frames("spirit", [{**downlink, "t_s": 11.0}], [{"t_s": 11.0}])
    last = store.last_frame("spirit")
    assert last is not None and last["t_s"] == 11.0
    assert writer.flushed_frames == 2  # the reads committed them, through the writer


def test_no_route_flushes_the_writer() -> None:
    flushing = [
        f"{path.name}:{node.lineno}"
        for path in sorted(API.glob("*.py"))
        for node in ast.walk(ast.parse(path.read_text()))
        if isinstance(node, ast.Attribute) and node.attr == "flush"
    ]
    assert not flushing, f"routes that flush the writer: {flushing}"
