"""Where a rover's telemetry and reports go: the frame sinks and the runtime's listener.

A ``RoverRuntime`` plays its frames out as its clock reaches them and hands each batch, in
order, to every sink in its ``sinks`` list: storage (the records and their events), the alarm
engine, the WebSocket hub and the 3D view. A batch (``FrameBatch``) is two lists of the same
length: the rover's downlink records (``sim.loop.downlink.DownlinkDict``, what
``Downlink.as_dict()`` gives) and, at the same times, the scorer's truth records
(``sim.scoring.truth.TruthDict``). The records are typed dicts, not the dataclasses: every
sink sends or stores them as JSON, so each is made once, when it is played out. A sink that
serves the ground reads the downlink; the truth goes only where the truth view allows it
(docs/DESIGN.md, "Two records").

``server.state.Server`` wires them: every runtime gets ``StorageSink``, the alarm engine
(``server.alarms.AlarmEngine``) and the hub (``server.hub.TelemetryHub``), in that order,
and a 3D view (``server.scene3d.scene.RoverScene``) joins its rover's sinks when it starts.

What a runtime reports beside its frames (a command's report, a sequence's status, a
checkpoint, a queue change) goes to the one ``RuntimeListener`` it is built with: the
``Server``, which stores and announces it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol

from sim.loop.downlink import DownlinkDict
from sim.scoring.truth import TruthDict, merged

if TYPE_CHECKING:
    from server.storage.records import CommandRecord

Frame = dict[str, Any]  # a merged frame (downlink and truth) as a JSON-ready dict
PlayedFrame = tuple[DownlinkDict, TruthDict]  # a downlink record and its truth record


@dataclass(frozen=True)
class FrameBatch:
    """Records played out together: ``downlink[i]`` and ``truth[i]`` share their ``t_s``."""

    downlink: list[DownlinkDict]
    truth: list[TruthDict]

    def __post_init__(self) -> None:
        if len(self.downlink) != len(self.truth):
            raise ValueError(
                f"a batch pairs its records: {len(self.downlink)} downlink, {len(self.truth)} truth"
            )

    def __len__(self) -> int:
        return len(self.downlink)


def with_truth(downlink: DownlinkDict | None, truth: TruthDict | None) -> Frame | None:
    """``downlink`` merged with its ``truth`` record (``sim.scoring.truth.merged``) when
    there is one of its time, else ``downlink`` as it is."""
    if downlink is None:
        return None
    if truth is None or truth["t_s"] != downlink["t_s"]:
        return dict(downlink)
    return merged(downlink, truth)


class FrameSink(Protocol):
    """Receives every frame batch of the rovers it is attached to, in play-out order, on the
    rover's clock thread: it must not block (queue the work if it is slow)."""

    def publish(self, rover: str, batch: FrameBatch) -> None: ...


class RuntimeListener(Protocol):
    """What a rover runtime reports beside its frames, given to it when it is built. Called
    on the runtime's clock thread (``checkpoint`` under its lock, so checkpoints arrive in
    the order they were taken), or on the thread that changed the queue or the clock."""

    def command_reported(self, rover: str, report: CommandRecord) -> None:
        """A queued step ended (completed, refused or failed)."""

    def sequence_status(self, sequence_id: int, status: str, detail: str | None) -> None:
        """A sequence started, completed or failed."""

    def checkpoint(self, rover: str, t_s: float, blob: bytes) -> None:
        """The runtime's encoded state at ``t_s``, to be stored (queued, not waited for)."""

    def commit(self) -> None:
        """Store what ``checkpoint`` queued, now: a clock or queue change is stored before
        the request that made it is answered."""

    def queue_changed(self, rover: str) -> None:
        """The queue or the step executing changed (it must not wait)."""


class StorageSink:
    """Both records of every frame and the events they carry, handed to the storage writer
    (it batches them into transactions off the clock thread)."""

    def __init__(self, writer: Any) -> None:  # server.storage.BatchWriter
        self.writer = writer

    def publish(self, rover: str, batch: FrameBatch) -> None:
        self.writer.frames(rover, batch.downlink, batch.truth)
        events = [(float(f["t_s"]), e) for f in batch.downlink for e in f.get("events", [])]
        if events:
            self.writer.events(rover, events)
