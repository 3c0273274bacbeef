"""What the rover's events report of its onboard tables: the ground's view of them.

The rover says what it sets (``estimation.events``): its NATE parameters (``parameter``
events), its keep-out zones (``keepout`` events, ``estimation.protection.keepout``) and its
mobility fault (a ``mobility`` event when a halt disables mobility, another when the ground
clears it). The ground rebuilds them from the events that have come down, never from the
simulator, and validation predicts with them (``server.validation.context``).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

from estimation.events import reported_parameter
from estimation.protection.keepout import KeepOutZone, apply_reported

HALT_PREFIX = "drive halted by fault protection: "
CLEARED_PREFIX = "mobility enabled"


class ReportedState:
    """The parameters (NATE's, ``mobility.<name>``, ``vo.<name>``), keep-out zones and mobility
    fault the rover has reported."""

    def __init__(self) -> None:
        self.params: dict[str, float] = {}
        self.zones: dict[str, KeepOutZone] = {}
        self.mobility_fault: str | None = None

    def note(self, events: Iterable[Mapping[str, Any]]) -> None:
        """Take in ``events`` (event dicts, in time order)."""
        for event in events:
            text, kind = str(event.get("text", "")), event.get("kind")
            if kind == "parameter":
                got = reported_parameter(text)
                if got is not None:
                    self.params[got[0]] = got[1]
            elif kind == "keepout":
                apply_reported(self.zones, text)
            elif kind == "mobility":
                if text.startswith(HALT_PREFIX):
                    self.mobility_fault = text.removeprefix(HALT_PREFIX)
                elif text.startswith(CLEARED_PREFIX):
                    self.mobility_fault = None
