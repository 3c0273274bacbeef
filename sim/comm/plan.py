"""The communication plan of a rover: when its links may be used, at what rates, and the
deadline that drives a sol's planning (issue 23, "Operate across light time").

MER talked to Earth two ways (NASA/JPL MER mission pages, communications with Earth;
docs/REFERENCES.md):

- Direct to Earth through the high-gain antenna (X band): 3.5 to 12 kbit/s, for at most
  about 3 hours a sol (power and heating limit it). The morning session brings the sol's
  commands (``uplink_*``: the uplink window opens at 09:00 LMST for an hour, 2 kbit/s
  taken) and sends data back in the same session (``dte_*``: 10 kbit/s, an hour). Earth
  must stand ``earth_min_elev_deg`` above the horizon for the antenna (10° taken).
- Relay through an orbiter (UHF): passes of about 8 minutes at 128 kbit/s bringing about
  60 Mbit, later 256 kbit/s; Mars Odyssey carried about 85 % of MER's data. The orbiter
  counts as in view above ``relay_mask_deg`` (10°, as ``sim.sensors.orbiter`` takes it),
  and holds what it received ``relay_latency_s`` (30 minutes taken) before it relays it
  to Earth.

The store's capacity is MER's 256 MB of flash (2,048 Mbit). When the store fills, the
decimated telemetry keeps one frame per ``decimate_s``. A drive's results must be on the
ground by ``planning_lmst_h`` of its sol (18:00 LMST taken) for the team to plan the next
sol on them: MER was operated across the light time on a daily cycle, each sol's plan
built on the data of the sol before (Mishkin, Limonadi, Laubach and Bass 2006).

Values the mission pages do not fix (the window times, 2 kbit/s up, the latency, the
deadline) are this project's plausible choices. Units are in the names: LMST hours,
minutes, bit/s, degrees, seconds, Mbit (an edge of the system: operators set these).
Every field is validated; a bad one raises ``InputError`` naming it.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from collections.abc import Mapping
from dataclasses import dataclass

from sim.errors import InputError

WEEK_S = 7.0 * 86_400.0


@dataclass(frozen=True)
class _Range:
    low: float
    high: float
    low_closed: bool
    high_closed: bool

    def holds(self, value: float) -> bool:
        above = value >= self.low if self.low_closed else value > self.low
        below = value <= self.high if self.high_closed else value < self.high
        return above and below

    def text(self) -> str:
        return (
            f"{'[' if self.low_closed else '('}{self.low:g}, "
            f"{self.high:g}{']' if self.high_closed else ')'}"
        )


_LMST_H = _Range(0.0, 24.0, True, False)
_MINUTES = _Range(0.0, 720.0, False, True)
_RATE_BPS = _Range(0.0, 1.0e7, False, True)
_ELEV_DEG = _Range(0.0, 80.0, True, True)


@dataclass(frozen=True)
class CommPlan:
    """A rover's communication plan (units in the names; see the module docstring)."""

    uplink_lmst_h: float = 9.0  # the morning direct-to-Earth uplink window opens (LMST)
    uplink_minutes: float = 60.0
    uplink_rate_bps: float = 2_000.0
    dte_lmst_h: float = 9.0  # the direct-to-Earth downlink session (the same HGA session)
    dte_minutes: float = 60.0
    dte_rate_bps: float = 10_000.0
    earth_min_elev_deg: float = 10.0  # Earth must be at least this high for the HGA
    relay_mask_deg: float = 10.0  # the orbiter counts as in view above this elevation
    relay_rate_bps: float = 128_000.0
    relay_latency_s: float = 1_800.0  # the orbiter's store-and-forward delay to Earth
    store_capacity_mbit: float = 2_048.0  # MER's 256 MB of flash
    decimate_s: float = 60.0  # the decimated telemetry keeps one frame per this many s
    planning_lmst_h: float = 18.0  # a drive's results must be on the ground by this LMST

    def __post_init__(self) -> None:
        for field in dataclasses.fields(self):
            value = _number(field.name, getattr(self, field.name))
            bounds = RANGES[field.name]
            if not bounds.holds(value):
                raise InputError(field.name, f"must be in {bounds.text()}, got {value!r}")
            object.__setattr__(self, field.name, value)  # an int becomes a float

    def replaced(self, changes: Mapping[str, object]) -> CommPlan:
        """A validated copy with ``changes`` (field name -> value) applied.

        >>> CommPlan().replaced({"relay_mask_deg": 20}).relay_mask_deg
        20.0
        """
        if not isinstance(changes, Mapping):
            raise InputError("changes", f"must be a mapping of fields, got {changes!r}")
        _known_names(changes)
        return dataclasses.replace(self, **{str(k): v for k, v in changes.items()})  # type: ignore[arg-type]

    def as_json(self) -> dict[str, float]:
        """Every field by name, as plain floats."""
        return {f.name: float(getattr(self, f.name)) for f in dataclasses.fields(self)}

    @classmethod
    def from_json(cls, data: Mapping[str, object]) -> CommPlan:
        """The plan ``as_json`` wrote (a checkpoint's), validated; a field it lacks (a
        checkpoint from before the field existed) takes its default."""
        if not isinstance(data, Mapping):
            raise InputError("comm_plan", f"must be a mapping of fields, got {data!r}")
        return cls().replaced(data)


# the range of each field: LMST hours, window minutes, rates, elevations, the rest
RANGES: dict[str, _Range] = {
    "uplink_lmst_h": _LMST_H,
    "uplink_minutes": _MINUTES,
    "uplink_rate_bps": _RATE_BPS,
    "dte_lmst_h": _LMST_H,
    "dte_minutes": _MINUTES,
    "dte_rate_bps": _RATE_BPS,
    "earth_min_elev_deg": _ELEV_DEG,
    "relay_mask_deg": _ELEV_DEG,
    "relay_rate_bps": _RATE_BPS,
    "relay_latency_s": _Range(0.0, WEEK_S, True, True),
    "store_capacity_mbit": _Range(0.0, 1.0e6, False, True),
    "decimate_s": _Range(1.0, 3_600.0, True, True),
    "planning_lmst_h": _LMST_H,
}


def _number(name: str, value: object) -> float:
    """``value`` as a finite float; ``InputError(name, ...)`` for a bool, a non-number or
    a non-finite one."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise InputError(name, f"must be a number, got {value!r}")
    out = float(value)
    if not math.isfinite(out):
        raise InputError(name, f"must be finite, got {value!r}")
    return out


def _known_names(changes: Mapping[str, object]) -> None:
    known = [f.name for f in dataclasses.fields(CommPlan)]
    for name in changes:
        if name not in known:
            raise InputError(str(name), f"not a field of the comm plan; known: {', '.join(known)}")
