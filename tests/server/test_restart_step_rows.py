"""A step has one command row whatever the restarts (issue 13, defect 8).

A server killed after a step's row was stored, but before a checkpoint after that step,
restarts from the older checkpoint and runs the step again: its row is updated and counts
the re-run, never doubled. First the rule in process, the kill played out exactly (the
writer flushed by hand, the clock ticked by hand); then the real server (``roverops
serve``) killed with SIGKILL at seeded random moments of a sequence
(``bench.restart``, which ``roverops bench restart`` runs twenty times).
"""

from __future__ import annotations

import json
import random
from pathlib import Path
from typing import Any

import pytest

from bench.restart import expected_steps, measure_kills
from sequences.validate import validate
from server.app import Server, ServerConfig
from server.runtime import RoverRuntime
from server.timeline import sol_timeline

STEPS = ["GET_TILT_ATTITUDE", "NADIR_UPDATE", "WAIT duration_s=30"]
SEQ = "SEQUENCE three\n" + "\n".join(STEPS) + "\n"


def _server(url: str) -> tuple[Server, RoverRuntime]:
    """A server whose clocks and writer threads are not started: the test ticks and
    flushes, so it decides exactly what is stored when the "kill" comes."""
    server = Server.open(
        ServerConfig(database_url=url, operator_token="unused", start_clocks=False)
    )
    runtime = server.rovers["spirit"]
    runtime.set_clock(speed=float("inf"))
    return server, runtime


def _queue(
    server: Server, runtime: RoverRuntime, source: str | dict[str, Any], immediate: bool = False
) -> int:
    result = validate(source)
    assert result.sequence is not None, result.errors
    text, fmt = (source, "text") if isinstance(source, str) else (json.dumps(source), "command")
    seq_id = server.store.add_sequence(
        "spirit", result.sequence.name or "cmd", text, fmt, "queued", [], [], []
    )
    runtime.enqueue(seq_id, result.sequence, immediate=immediate)
    return seq_id


def _tick_until_done(server: Server, runtime: RoverRuntime, *seq_ids: int) -> None:
    for _ in range(200):
        runtime._tick(0.05)  # the clock thread's step, run by the test
        if all((server.store.get_sequence(i) or {}).get("status") == "completed" for i in seq_ids):
            server.writer.flush()
            return
    raise AssertionError("the sequences did not complete in 200 ticks")


def _rows(server: Server) -> list[tuple[int, int, str, int]]:
    return [
        (r["sequence_id"], r["step_index"], r["command"], r["reruns"])
        for r in server.store.commands("spirit", -1e18, 1e18)
    ]


def test_a_step_run_again_after_a_restart_keeps_its_one_row(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """An immediate command and a sequence's first step stored after the last checkpoint,
    then the kill: after the restart each has one row, marked as re-run once, in the
    storage and in the sol timeline the API serves."""
    monkeypatch.setattr("server.runtime.CHECKPOINT_EVERY_S", 1e9)  # none but the test's
    url = f"sqlite:///{tmp_path / 'roverops.db'}"
    first, runtime = _server(url)
    seq_id = _queue(first, runtime, SEQ)
    cmd_id = _queue(first, runtime, {"steps": [{"command": "SUNFIND"}]}, immediate=True)
    runtime.checkpoint()  # the last checkpoint: before any step
    while len(_rows(first)) < 2:  # the immediate command, then the sequence's first step
        runtime._tick(0.05)
        first.writer.flush()  # their rows stored, with the checkpoint still before them
    first.store.close()  # ... and the server killed: no graceful stop, no final checkpoint

    second, runtime = _server(url)  # restored from that checkpoint: both steps run again
    _tick_until_done(second, runtime, seq_id, cmd_id)
    rows = _rows(second)
    assert sorted(rows) == sorted(
        [(cmd_id, 0, "SUNFIND", 1)] + [(seq_id, i, s, int(i == 0)) for i, s in enumerate(STEPS)]
    )
    timeline = sol_timeline(second.store, runtime, runtime.sol(runtime.t_s))
    assert timeline is not None
    assert sorted(
        (c["sequence_id"], c["step_index"], c["reruns"]) for c in timeline["commands"]
    ) == sorted((r[0], r[1], r[3]) for r in rows)
    second.stop()


def test_kills_at_random_moments_leave_one_row_per_step(tmp_path: Path) -> None:
    run = measure_kills(tmp_path, kills=3, rng=random.Random(13))
    assert run.kills == 3 and run.sequences and len(run.rows_after_restart) == 3
    for counts in run.rows_after_restart:  # after each restart: no step stored twice
        assert all(n == 1 for n in counts.values()), counts
    expected = list(enumerate(expected_steps()))
    for seq_id in run.sequences:  # at the end: each step once, in order, with its command
        assert run.statuses[seq_id] == "completed"
        assert [(i, c) for i, c, _reruns in run.final_rows[seq_id]] == expected


def test_an_immediate_command_stays_first_after_a_restart(tmp_path: Path) -> None:
    """An immediate command sent after the last checkpoint is queued again on restart
    from its stored record, and still runs before the queued sequence, as it would have."""
    url = f"sqlite:///{tmp_path / 'roverops.db'}"
    first, runtime = _server(url)
    seq_id = _queue(first, runtime, SEQ)
    runtime.checkpoint()
    first.writer.flush()
    cmd_id = _queue(first, runtime, {"steps": [{"command": "SUNFIND"}]}, immediate=True)
    assert runtime.queued_ids() == [cmd_id, seq_id]
    first.store.close()  # killed before the next checkpoint

    second, runtime = _server(url)
    assert runtime.queued_ids() == [cmd_id, seq_id]
    second.stop()
