"""Where a rover's telemetry goes: the frame sinks.

A ``RoverRuntime`` plays its frames out as its clock reaches them and hands each batch, in
order, to every sink in its ``sinks`` list: storage (frames and their events), the alarm
engine, the WebSocket hub and the 3D view. A frame is ``TelemetryFrame.as_dict()``
(``sim.loop.telemetry``), the one definition of its fields.

``server.state.Server`` wires them: every runtime gets ``StorageSink``, the alarm engine
(``server.alarms.AlarmEngine``) and the hub (``server.hub.TelemetryHub``), in that order,
and a 3D view (``server.scene3d.scene.RoverScene``) joins its rover's sinks when it starts.
"""

from __future__ import annotations

from typing import Any, Protocol

Frame = dict[str, Any]


class FrameSink(Protocol):
    """Receives every frame batch of the rovers it is attached to, in play-out order, on the
    rover's clock thread: it must not block (queue the work if it is slow)."""

    def publish(self, rover: str, frames: list[Frame]) -> None: ...


class StorageSink:
    """Frames and the events they carry, handed to the storage writer (it batches them into
    transactions off the clock thread)."""

    def __init__(self, writer: Any) -> None:  # server.storage.BatchWriter
        self.writer = writer

    def publish(self, rover: str, frames: list[Frame]) -> None:
        self.writer.frames(rover, frames)
        events = [(float(f["t_s"]), e) for f in frames for e in f.get("events", [])]
        if events:
            self.writer.events(rover, events)
