"""A sol at max speed through the server (issue 16, item 4): the clock thread goes from a
command to its play-out and to the next step without pausing, the play-out goes out before
the checkpoint (which then does not carry it), and what is stored is exactly what the
rover's session made: the frames of the same commands run in a bare ``RoverSession`` (the
reference), field for field and bit for bit, the events and the command rows with them."""

from __future__ import annotations

import json
import math
import time
from typing import Any

import pytest

from sequences.language import Sequence
from sequences.validate import validate
from server.runtime import FRAME_EVERY_S, ROVERS, RoverRuntime
from server.sinks import FrameBatch
from server.state import Server, ServerConfig
from server.storage.checkpoint import decode
from server.storage.store import json_dumps
from sim.loop.session import RoverSession
from tests.runtime_listener import RecordingListener

SOL = "SEQUENCE short_sol\nNADIR_UPDATE\nDRIVE_STRAIGHT distance_m=3\nHGA_PASS duration_min=2\n"


def _seq(text: str) -> Sequence:
    result = validate(text)
    assert result.sequence is not None, result.errors
    return result.sequence


def _reference(sequence: Sequence) -> tuple[list[dict[str, Any]], list[float]]:
    """The sequence's frames from a bare session made as the server makes Spirit's, as
    storage reads them back (JSON, no NaN), and each command's end time."""
    spec = ROVERS["spirit"]
    session = RoverSession(
        spec.site, spec.seed, spec.start_utc, frame_every_s=FRAME_EVERY_S, estimators=("sapp",)
    )
    ends = []
    for step in sequence.steps:
        ends.append(session.execute(step.command, label=step.command.describe()).end_t_s)
    return [json.loads(json_dumps(f.as_dict())) for f in session.downlinks], ends


def test_a_sol_at_max_stores_exactly_the_frames_of_the_session() -> None:
    server = Server.open(ServerConfig(database_url="sqlite://", start_clocks=False))
    runtime = server.rovers["spirit"]
    sequence = _seq(SOL)
    seq_id = server.store.add_sequence("spirit", "short_sol", SOL, "text", "queued", [], [], [])
    server.start()
    try:
        runtime.set_clock(speed=math.inf)
        runtime.enqueue(seq_id, sequence)
        runtime.start()
        deadline = time.monotonic() + 120.0
        while (server.store.get_sequence(seq_id) or {}).get("status") != "completed":
            assert time.monotonic() < deadline, "the sequence did not complete"
            time.sleep(0.05)
        expected, ends = _reference(sequence)
        # "completed" is set once its frames are committed (the writer flushed first)
        stored = server.store.frames("spirit", -math.inf, ends[-1])
        commands = server.store.commands("spirit", -math.inf, math.inf)
    finally:
        server.stop()
    assert len(stored) == len(expected) > 50
    for got, want in zip(stored, expected, strict=True):
        assert got == want  # every field, every bit (floats survive JSON exactly)
    assert [c["status"] for c in commands] == ["completed"] * 3
    assert [c["end_t_s"] for c in commands] == ends


@pytest.fixture
def ticked(monkeypatch: pytest.MonkeyPatch) -> tuple[RoverRuntime, list[bytes], list[float]]:
    """A runtime at max speed whose clock the test ticks, checkpointing every tick; its
    checkpoints and the times of the frames it publishes."""
    monkeypatch.setattr("server.runtime.CHECKPOINT_EVERY_S", 0.0)
    listener = RecordingListener()
    runtime = RoverRuntime(ROVERS["spirit"], listener=listener)
    runtime.set_clock(speed=math.inf)
    blobs = listener.blobs
    published: list[float] = []

    class Times:
        def publish(self, rover: str, batch: FrameBatch) -> None:
            published.extend(f["t_s"] for f in batch.downlink)

    runtime.sinks.append(Times())
    return runtime, blobs, published


def test_at_max_a_command_s_frames_go_out_before_the_checkpoint(
    ticked: tuple[RoverRuntime, list[bytes], list[float]],
) -> None:
    runtime, blobs, published = ticked
    runtime.enqueue(1, _seq("SEQUENCE d\nDRIVE_STRAIGHT distance_m=2\n"))
    assert runtime._tick(0.05) is True  # the drive ran: its play-out is due at once
    assert runtime._playout and not published
    assert runtime._tick(0.05) is True  # played out, then checkpointed
    assert not runtime._playout and len(published) > 10
    state = decode("spirit", blobs[-1])
    assert state["playout"] == [] and state["executing"] == "" and state["current_step"] is None
    assert state["clock_t_s"] == published[-1]
    assert runtime._tick(0.05) is False  # the sequence ended: nothing to do at once
    assert not runtime.queue


def test_at_a_finite_speed_the_clock_is_paced_by_wall_time(
    ticked: tuple[RoverRuntime, list[bytes], list[float]],
) -> None:
    runtime, blobs, published = ticked
    runtime.set_clock(speed=10.0)
    runtime.enqueue(1, _seq("SEQUENCE d\nDRIVE_STRAIGHT distance_m=2\n"))
    assert runtime._tick(0.05) is False  # the drive ran; its frames wait for the clock
    assert runtime._tick(0.05) is False
    # the checkpoint came before this tick's play-out: it holds the frames still to come
    assert len(decode("spirit", blobs[-1])["playout"]) > len(runtime._playout) > 0
    assert published and published[-1] <= runtime.t_s


def test_a_new_sequence_wakes_the_clock_thread() -> None:
    runtime = RoverRuntime(ROVERS["spirit"])
    runtime.set_clock(running=False)
    runtime._wake.clear()
    runtime.enqueue(1, _seq("SEQUENCE n\nNADIR_UPDATE\n"))
    assert runtime._wake.is_set()
    runtime._wake.clear()
    runtime.set_clock(running=True, speed=math.inf)
    assert runtime._wake.is_set()
