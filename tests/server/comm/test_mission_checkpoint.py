"""Across light time the checkpoint holds the link whole: what waits on the ground, what is on
its way both ways, the rover's store. What the ground changes (an upload, a cancel) is stored
before it is answered, and a rover restored from any checkpoint, mid-pass or mid-uplink,
delivers exactly what an uninterrupted one does."""

from __future__ import annotations

import math

from sequences.validate import validate
from server.runtime import ROVERS, RoverRuntime
from server.sinks import FrameBatch
from server.storage.checkpoint import decode
from tests.runtime_listener import RecordingListener

DRIVE = "SEQUENCE d\nNADIR_UPDATE\nDRIVE_STRAIGHT distance_m=2\n"


class Ground:
    """A frame sink that keeps every downlink record's time, and the truth's."""

    def __init__(self) -> None:
        self.downlink: list[float] = []
        self.truth: list[float] = []

    def publish(self, rover: str, batch: FrameBatch) -> None:
        self.downlink += [float(d["t_s"]) for d in batch.downlink]
        self.truth += [float(t["t_s"]) for t in batch.truth]


def mission_runtime(listener: RecordingListener, ground: Ground) -> RoverRuntime:
    runtime = RoverRuntime(ROVERS["spirit"], listener=listener, sinks=[ground], comm="mission")
    runtime.set_clock(speed=math.inf)
    return runtime


def waiting_ids(blob: bytes) -> list[int]:
    link = decode("spirit", blob)["comm"]["mission"]["link"]
    return [int(u["sequence_id"]) for u in link["waiting"]]


def test_an_upload_and_a_cancel_on_the_ground_are_stored_before_they_are_answered() -> None:
    listener = RecordingListener()
    runtime = mission_runtime(listener, Ground())
    runtime.checkpoint()
    sequence = validate(DRIVE).sequence
    assert sequence is not None
    runtime.enqueue(5, sequence)
    assert waiting_ids(listener.blobs[-1]) == [5]
    runtime.enqueue(6, sequence)
    assert waiting_ids(listener.blobs[-1]) == [5, 6]
    runtime.cancel(5)
    assert waiting_ids(listener.blobs[-1]) == [6]
    restored = RoverRuntime.restore(ROVERS["spirit"], listener.blobs[-1])
    assert restored.queued_ids() == [6]


def test_a_rover_restored_mid_link_delivers_what_an_uninterrupted_one_does() -> None:
    sequence = validate(DRIVE).sequence
    assert sequence is not None
    ticks = 400

    def run(stop_at: int | None) -> Ground:
        listener, ground = RecordingListener(), Ground()
        runtime = mission_runtime(listener, ground)
        runtime.enqueue(1, sequence)
        for tick in range(ticks):
            if tick == stop_at:  # a kill: a new runtime from the state taken now
                runtime.checkpoint()
                blob = listener.blobs[-1]
                runtime = RoverRuntime.restore(ROVERS["spirit"], blob, listener, [ground])
                runtime.watermark_t_s = max(ground.truth, default=-math.inf)
            runtime._tick(0.25)
        return ground

    whole = run(None)
    assert len(whole.downlink) > 50 and whole.truth  # the drive came down
    for stop_at in (37, 151, 263):
        again = run(stop_at)
        assert again.downlink == whole.downlink, f"stopped at tick {stop_at}"
        assert again.truth == whole.truth
