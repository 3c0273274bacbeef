"""A halt: a mobility fault protection stopped the drive.

What the flight software reports when one of its checks trips (Biesiadecki and Maimone
2006 sec. 3): which check, a sentence an operator reads, and the values that tripped it in
SI units (the console shows them in degrees and percent). After a halt mobility stays
disabled until the ground sends ``CLEAR_MOBILITY_FAULT``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Literal

HaltCheck = Literal[
    "keepout",  # the grown position disc would touch a keep-out zone
    "slip",  # VO-measured slip above the limit
    "vo_fail",  # VO failed too often in a row and the drive says vo_fail=halt
    "timeout",  # the drive has not reached its goal within its time budget
    "lmst",  # the drive ran past its time-of-day limit
    "tilt",  # roll or pitch from the accelerometers above the limit
    "suspension",  # a rocker or bogie angle above its limit
]

HALT_CHECKS: tuple[str, ...] = (
    "keepout",
    "slip",
    "vo_fail",
    "timeout",
    "lmst",
    "tilt",
    "suspension",
)


@dataclass(frozen=True)
class Halt:
    """One halt: ``check`` (``HaltCheck``), ``reason`` (a sentence), ``values`` (the
    numbers that tripped it, SI, names with units), and where and when the flight software
    decided: ``t_s`` (its clock), ``p_s`` (its estimated position in the current Site, m)."""

    check: str
    reason: str
    values: dict[str, float] = field(default_factory=dict)
    t_s: float = math.nan
    p_s: tuple[float, float, float] = (math.nan, math.nan, math.nan)

    def __post_init__(self) -> None:
        if self.check not in HALT_CHECKS:
            raise ValueError(f"check: must be one of {', '.join(HALT_CHECKS)}, got {self.check!r}")

    def as_dict(self) -> dict[str, Any]:
        """Plain data for a report, the downlink and a checkpoint."""
        return {
            "check": self.check,
            "reason": self.reason,
            "values": {k: float(v) for k, v in self.values.items()},
            "t_s": float(self.t_s),
            "p_s": [float(x) for x in self.p_s],
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Halt:
        """The halt of ``as_dict``."""
        p = data["p_s"]
        return cls(
            check=str(data["check"]),
            reason=str(data["reason"]),
            values={str(k): float(v) for k, v in data["values"].items()},
            t_s=float(data["t_s"]),
            p_s=(float(p[0]), float(p[1]), float(p[2])),
        )
