"""The hub's notices (``server.hub``): typed records of what changed, each a WebSocket
message with its ``type`` (the union of them, with the frames, is published at
``GET /api/schema/ws``: ``server.api.answers.WsMessage``).

A notice is built by the part of the server that saw the change: the alarm engine
(``AlarmNotice``), the server's command reports and events (``CommandNotice``,
``EventNotice``) and the queue notices' thread (``QueueNotice``). ``message()`` is the JSON
sent, the same keys as ever (``web/`` reads them).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar


@dataclass(frozen=True)
class AlarmNotice:
    """An alarm raised, updated, acknowledged, shelved or cleared (``alarm_json``)."""

    type: ClassVar[str] = "alarm"
    alarm: dict[str, Any]

    def message(self) -> dict[str, Any]:
        return {"type": self.type, "alarm": self.alarm}


@dataclass(frozen=True)
class CommandNotice:
    """A command run, as the live timeline lists it (``server.timeline.command_entry``)."""

    type: ClassVar[str] = "command"
    command: dict[str, Any]

    def message(self) -> dict[str, Any]:
        return {"type": self.type, "command": self.command}


@dataclass(frozen=True)
class EventNotice:
    """An event the server makes (in no frame): text, kind, severity, t_s, sol, lmst_h."""

    type: ClassVar[str] = "event"
    event: dict[str, Any]

    def message(self) -> dict[str, Any]:
        return {"type": self.type, "event": self.event}


@dataclass(frozen=True)
class QueueNotice:
    """A rover's queue as it is now (``server.queue_view.queue_json``)."""

    type: ClassVar[str] = "queue"
    rover: str
    queue: list[dict[str, Any]]

    def message(self) -> dict[str, Any]:
        return {"type": self.type, "rover": self.rover, "queue": self.queue}


Notice = AlarmNotice | CommandNotice | EventNotice | QueueNotice
