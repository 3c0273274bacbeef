"""A rover runtime's listener for tests (``server.sinks.RuntimeListener``): it keeps what
the runtime reports, in order, as the ``Server`` would store it."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from server.storage.records import CommandRecord


class RecordingListener:
    """Everything a runtime reported: command reports, sequence status changes, checkpoint
    blobs, commits and queue changes. ``on_report`` runs on each command report (a test may
    slow it down as the server's storage would)."""

    def __init__(self, on_report: Callable[[CommandRecord], None] | None = None) -> None:
        self.reports: list[CommandRecord] = []
        self.statuses: list[tuple[int, str, str | None]] = []
        self.blobs: list[bytes] = []
        self.commits = 0
        self.queue_changes = 0
        self.stages: list[tuple[int, str, float]] = []
        self.events: list[tuple[float, dict[str, str]]] = []
        self._on_report = on_report

    def command_reported(self, rover: str, report: CommandRecord) -> None:
        self.reports.append(report)
        if self._on_report is not None:
            self._on_report(report)

    def sequence_status(
        self, sequence_id: int, status: str, detail: str | None, t_s: float | None = None
    ) -> None:
        self.statuses.append((sequence_id, status, detail))

    def checkpoint(self, rover: str, t_s: float, blob: bytes) -> None:
        self.blobs.append(blob)

    def commit(self) -> None:
        self.commits += 1

    def queue_changed(self, rover: str) -> None:
        self.queue_changes += 1

    def sequence_stage(
        self, sequence_id: int, stage: str, t_s: float, detail: str | None = None
    ) -> None:
        self.stages.append((sequence_id, stage, t_s))

    def link_event(
        self, rover: str, t_s: float, event: dict[str, str], recovering: bool,
        received_t_s: float | None = None,
    ) -> None:  # fmt: skip
        self.events.append((t_s, event))

    def stored_frame_times(self, rover: str, downlinks: list[Any]) -> set[float]:
        return set()
