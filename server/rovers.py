"""The rovers a server hosts (their names, sites, missions, start times and seeds) and a
rover's clock setting: plain data the runtime (``server.runtime``) and the routes share."""

from __future__ import annotations

from dataclasses import dataclass
from datetime import UTC, datetime


@dataclass(frozen=True)
class RoverSpec:
    """A rover the server hosts: its name, site, mission and start time."""

    name: str
    site: str
    mission: str
    start_utc: datetime
    seed: int


ROVERS: dict[str, RoverSpec] = {
    "spirit": RoverSpec("spirit", "gusev", "spirit", datetime(2004, 4, 14, 15, 0, tzinfo=UTC), 1),
    "opportunity": RoverSpec(
        "opportunity", "meridiani", "opportunity", datetime(2004, 4, 14, 3, 0, tzinfo=UTC), 2
    ),
}


@dataclass
class ClockState:
    """The clock: ``running`` and ``speed`` (simulated s per wall s; ``inf`` = max)."""

    running: bool = True
    speed: float = 1.0
