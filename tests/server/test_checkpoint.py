"""Checkpoints as versioned plain data (``server.storage.checkpoint``): a session restored from the
bytes runs on as the uninterrupted one, number for number; a blob of another format, or of
none, is refused with a message saying that the rover starts fresh."""

from __future__ import annotations

import json
import math
import pickle
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from sequences import commands as cmd
from server.runtime import ROVERS, RoverRuntime
from server.sinks import FrameBatch
from server.storage.checkpoint import CHECKPOINT_FORMAT, CheckpointFormatError, decode, encode
from sim.loop.rover_sim import RoverSim
from sim.loop.session import RoverSession
from sim.scoring.truth import merged
from tests.runtime_listener import RecordingListener

START = datetime(2004, 4, 14, 16, 30, tzinfo=UTC)  # Spirit sol 100, ~10 LMST
ESTIMATORS = ("sapp", "kinematic_ekf", "radio_ekf")


def _session() -> RoverSession:
    return RoverSession("gusev", 5, START, estimators=ESTIMATORS)


def _frames(session: RoverSession) -> list[dict[str, Any]]:
    return [
        merged(d.as_dict(), t.as_dict())
        for d, t in zip(session.downlinks, session.truths, strict=True)
    ]


def test_a_simulator_loaded_from_its_state_runs_on_sample_for_sample() -> None:
    def run(sim: RoverSim) -> list[np.ndarray]:
        a = sim.drive_straight(0.8)
        b = sim.rest(120.0)
        c = sim.turn_in_place(-0.3)
        return [a.imu.delta_angle_b, a.encoders.wheel_counts, b.delta_velocity_b,
                c.truth.p_s, c.encoders.steer_rad, np.array([sim.t_s])]  # fmt: skip

    first = RoverSim("gusev", 3, START)
    first.drive_arc(2.0, 0.3)
    blob = encode("spirit", {"sim": first.state()})
    second = RoverSim("gusev", 3, START)
    second.load_state(decode("spirit", blob)["sim"])
    for x, y in zip(run(first), run(second), strict=True):
        np.testing.assert_array_equal(x, y)
    assert first.totals.distance_truth_m == second.totals.distance_truth_m


def test_a_session_restored_from_its_checkpoint_runs_on_as_if_never_stopped() -> None:
    before = [cmd.GetFineAttitude(), cmd.DriveStraight(distance_m=0.8, vo=True)]
    after = [cmd.DriveArc(radius_m=3.0, angle_deg=15.0), cmd.Wait(duration_s=60.0)]
    whole = _session()
    whole.run(before)
    blob = encode("spirit", whole.state())
    del whole.downlinks[:], whole.truths[:]
    whole.run(after)

    restored = _session()
    restored.load_state(decode("spirit", blob))
    restored.run(after)
    assert _frames(restored) == _frames(whole)  # exact: every number, bit for bit


def test_encode_takes_plain_data_only() -> None:
    with pytest.raises(TypeError, match="not plain data: RoverSim"):
        encode("spirit", {"sim": RoverSim("flat", 1, START)})
    state = {"a": np.arange(6, dtype=np.int64).reshape(2, 3), "b": [1.5, None, "x"], "c": -np.inf}
    back = decode("spirit", encode("spirit", state))
    np.testing.assert_array_equal(back["a"], state["a"])
    assert back["a"].dtype == np.int64 and back["b"] == state["b"] and back["c"] == -np.inf


def test_a_large_checkpoint_is_compressed_and_reads_back_whole() -> None:
    state = {"frames": [{"t_s": float(i), "x": [0.5] * 20} for i in range(2_000)]}
    blob = encode("spirit", state)
    assert blob[:1] == b"Z" and len(blob) < len(json.dumps(state)) / 4
    assert decode("spirit", blob) == state
    with pytest.raises(CheckpointFormatError):
        decode("spirit", b"Z" + b"not zlib at all")


def test_a_pickle_of_an_older_roverops_is_refused_and_says_the_rover_starts_fresh() -> None:
    blob = pickle.dumps({"session": None, "queue": []}, protocol=pickle.HIGHEST_PROTOCOL)
    with pytest.raises(CheckpointFormatError) as caught:
        RoverRuntime.restore(ROVERS["spirit"], blob)
    assert str(caught.value) == (
        "checkpoint of rover spirit was written in format 1 (a pickle of an older roverops); "
        "the rover starts fresh, its stored telemetry stays"
    )


def test_a_checkpoint_of_a_future_format_is_refused() -> None:
    blob = encode("spirit", {}).replace(
        f'"format":{CHECKPOINT_FORMAT}'.encode(), f'"format":{CHECKPOINT_FORMAT + 1}'.encode()
    )
    with pytest.raises(CheckpointFormatError, match="format 3, this roverops reads format 2"):
        RoverRuntime.restore(ROVERS["spirit"], blob)


@pytest.mark.parametrize("blob", [b"", b"garbage", b'{"format":2,"rover":"spirit","sta', b"\xff"])
def test_a_truncated_or_garbage_checkpoint_is_refused(blob: bytes) -> None:
    with pytest.raises(CheckpointFormatError, match="the rover starts fresh"):
        RoverRuntime.restore(ROVERS["spirit"], blob)


def test_a_checkpoint_without_the_state_needed_is_refused() -> None:
    with pytest.raises(CheckpointFormatError, match="does not hold the state"):
        RoverRuntime.restore(ROVERS["spirit"], encode("spirit", {"estimators": ["sapp"]}))


def test_a_runtime_restored_from_its_checkpoint_has_its_queue_and_clock() -> None:
    listener = RecordingListener()
    runtime = RoverRuntime(ROVERS["spirit"], listener=listener)
    blobs = listener.blobs
    runtime.set_clock(speed=float("inf"))
    text = "SEQUENCE two\nNADIR_UPDATE\n@ +30s WAIT duration_s=30\n"
    from sequences.language import parse

    runtime.enqueue(7, parse(text))
    runtime.checkpoint()
    restored = RoverRuntime.restore(ROVERS["spirit"], blobs[-1])
    assert restored.queued_ids() == [7]
    assert restored.queue[0].sequence == runtime.queue[0].sequence
    assert restored.clock.speed == float("inf") and restored.t_s == runtime.t_s


class _Collect:
    """A frame sink that keeps what it is given."""

    def __init__(self) -> None:
        self.frames: list[dict[str, Any]] = []

    def publish(self, rover: str, batch: FrameBatch) -> None:
        self.frames.extend(merged(d, t) for d, t in zip(batch.downlink, batch.truth, strict=True))


def _run_queue_out(runtime: RoverRuntime) -> list[dict[str, Any]]:
    sink = _Collect()
    runtime.sinks.append(sink)
    for _ in range(200):
        if not runtime.queue and not runtime._playout:
            break
        runtime._tick(0.25)
    return sink.frames


def test_a_runtime_restored_mid_sequence_runs_on_as_if_never_stopped() -> None:
    from sequences.language import parse

    text = (
        "SEQUENCE drive\nGET_FINE_ATTITUDE\nDRIVE_STRAIGHT distance_m=0.8 vo=on\n"
        "DRIVE_ARC radius_m=3 angle_deg=15\nWAIT duration_s=60\n"
    )
    listener = RecordingListener()
    runtime = RoverRuntime(ROVERS["spirit"], estimators=ESTIMATORS, listener=listener)
    blobs = listener.blobs
    runtime.set_clock(speed=float("inf"))
    runtime.enqueue(1, parse(text))
    for _ in range(100):  # up to the end of the second step, its frames played out
        if runtime.queue[0].next_step == 2 and not runtime._playout:
            break
        runtime._tick(0.25)
    runtime.checkpoint()
    restored = RoverRuntime.restore(ROVERS["spirit"], blobs[-1])
    assert restored.queue[0].next_step == 2
    frames = _run_queue_out(runtime)
    assert len(frames) > 10 and frames[-1]["command"] == "WAIT duration_s=60"  # to the end
    assert _run_queue_out(restored) == frames


def test_a_refused_checkpoint_cancels_the_sequences_it_held_and_says_so(tmp_path: Path) -> None:
    """An upgrade over an older data directory: the rover starts fresh with an empty queue,
    so the sequences the old checkpoint held are cancelled (not left "queued" for ever), and
    the event log says why."""
    from server.app import Server, ServerConfig
    from server.storage import Store

    url = f"sqlite:///{tmp_path / 'roverops.db'}"
    store = Store(url)
    queued = store.add_sequence("spirit", "old_plan", "SEQUENCE old_plan\nWAIT duration_s=5\n",
                                "text", "queued", [], [], [])  # fmt: skip
    done = store.add_sequence("spirit", "old_done", "SEQUENCE old_done\nWAIT duration_s=5\n",
                              "text", "completed", [], [], [])  # fmt: skip
    store.save_checkpoint("spirit", 100.0, pickle.dumps({"session": None, "queue": []}))
    store.engine.dispose()
    server = Server.open(ServerConfig(database_url=url, start_clocks=False))
    try:
        server.writer.flush()
        plan = server.store.get_sequence(queued)
        assert plan is not None and plan["status"] == "cancelled"
        assert "format 1" in plan["detail"] and "starts fresh" in plan["detail"]
        finished = server.store.get_sequence(done)
        assert finished is not None and finished["status"] == "completed"
        texts = [e["text"] for e in server.store.events("spirit", -math.inf, math.inf)]
        assert any("checkpoint" in t and "old_plan" in t for t in texts), texts
        assert server.rovers["spirit"].queue_snapshot() == []
    finally:
        server.stop()
