"""At max speed with nothing queued the clock runs on in real time, and /state says so
(issue 14, item 1: the clock stood still while the header said "running at max"). The
clock thread's ticks are run by the test with a given wall time, so nothing here reads a
wall clock."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from sequences.validate import validate
from server.runtime import IDLE_SPEED_AT_MAX, IDLE_STEP_S, ROVERS, RoverRuntime
from server.sinks import FrameBatch


@pytest.fixture(scope="module")
def runtime() -> RoverRuntime:
    rover = RoverRuntime(ROVERS["spirit"])
    rover.set_clock(speed=math.inf)
    return rover


def test_an_empty_queue_at_max_keeps_the_clock_running_in_real_time(
    runtime: RoverRuntime,
) -> None:
    frames: list[float] = []

    class Times:  # a frame sink keeping each played-out frame's time
        def publish(self, rover: str, batch: FrameBatch) -> None:
            frames.extend(f["t_s"] for f in batch.downlink)

    runtime.sinks.append(Times())
    start = runtime.t_s
    for _ in range(200):  # 10 s of wall time in 0.05 s ticks
        runtime._tick(0.05)
    assert runtime.t_s == pytest.approx(start + 200 * 0.05 * IDLE_SPEED_AT_MAX, abs=1e-3)
    # the idle rover is simulated in IDLE_STEP_S steps: one frame each, not one per tick
    assert 1 <= len(frames) <= 200 * 0.05 * IDLE_SPEED_AT_MAX / IDLE_STEP_S + 1
    state = runtime.state()
    assert state["clock"] == {"running": True, "speed": "max"}
    assert state["effective_speed"] == IDLE_SPEED_AT_MAX


def test_a_late_tick_does_not_burst(runtime: RoverRuntime) -> None:
    start = runtime.t_s
    runtime._tick(60.0)  # a tick a minute late accounts for MAX_TICK_S at most
    assert start < runtime.t_s <= start + 0.25 * IDLE_SPEED_AT_MAX + 1e-6


def test_a_time_tag_at_max_is_still_skipped_to_at_once(runtime: RoverRuntime) -> None:
    """Work queued: idle time is skipped (a sol at most per tick), /state says max."""
    result = validate("SEQUENCE later\n@ +02:00:00 NADIR_UPDATE\n")
    assert result.sequence is not None, result.errors
    runtime.enqueue(1, result.sequence)
    assert runtime.state()["effective_speed"] == "max"
    start = runtime.t_s
    for _ in range(20):
        runtime._tick(0.05)
        if not runtime.queue:
            break
    assert not runtime.queue  # it ran, two hours on, after at most twenty ticks
    assert runtime.t_s > start + 3600.0
    assert runtime.state()["effective_speed"] == IDLE_SPEED_AT_MAX


def test_a_sequence_starts_at_the_clock_its_operators_saw(tmp_path: Path) -> None:
    """Issue 21: "sequence #1 started" was stamped 7 s after its first command's events.
    At max with nothing queued the played-out clock runs up to IDLE_STEP_S ahead of the
    simulated rover, and a sequence sent then started at the rover's older time while its
    started event took the clock's. The started event (``server.state``, stored) carries the
    time its first step started: no later than that step's first event, and not before the
    clock the operators saw when they sent it."""
    from server.state import Server, ServerConfig

    server = Server.open(
        ServerConfig(database_url=f"sqlite:///{tmp_path / 'r.db'}", start_clocks=False)
    )
    try:
        rover = server.rovers["spirit"]
        rover.set_clock(speed=math.inf)
        for _ in range(28):  # 7 s of idle wall time: the clock is ahead of the rover
            rover._tick(0.25)
        sent_at = rover.t_s
        assert sent_at > rover.session.sim.t_s + 1.0  # the situation of the defect
        text = "SEQUENCE first\nPLANT_SITE\nNADIR_UPDATE\n"  # its event at its start
        seq_id = server.store.add_sequence("spirit", "first", text, "text", "queued", [], [], [])
        result = validate(text)
        assert result.sequence is not None
        rover.enqueue(seq_id, result.sequence)
        for _ in range(20):
            if not rover.queue and not rover._playout:
                break
            rover._tick(0.05)
        server.writer.flush()
        events = server.store.events("spirit", -math.inf, math.inf)
        started = next(e for e in events if e["text"] == f"sequence #{seq_id} first started")
        planted = next(e for e in events if e["text"] == "Site 1 planted")
        assert sent_at - 1e-6 <= started["t_s"] <= planted["t_s"]
    finally:
        server.stop()
