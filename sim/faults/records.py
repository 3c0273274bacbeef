"""The fault records: what a test conductor may inject, one frozen dataclass per kind.

Each record validates its parameters when made (``InputError`` naming the parameter) and
is plain data both ways (``as_dict``, ``fault_from_dict``), so the server, the CLI and a
checkpoint carry it as JSON. The kinds (issue 22, "Fault injection"):

- ``wheel``: a drive motor that stalls (``mode="stall"``: it stops turning and is
  dragged) or fails (``mode="fail"``: no torque, dragged); one of ``WHEEL_NAMES``;
- ``gyro_bias``: a step of ``bias_deg_per_h`` on one gyro axis (``x``, ``y``, ``z`` of
  the body/IMU frame);
- ``accel_bias``: a step of ``bias_ug`` (micro-g, 1 ug = 9.80665e-6 m/s^2) on one
  accelerometer axis;
- ``navcam``: the Navcams fail (no images: every VO step fails);
- ``pancam_dust``: dust on the Pancam window and in the air of optical depth ``tau``
  (0 to 10): the sun images are dimmer and blurred, Sunfind may fail;
- ``sand_trap``: a soil patch of very high slip and sinkage, a disc of ``radius_m``
  centred at ``(x_m, y_m)`` in the mission frame (metres North and East of the rover's
  start, the truth's ``p_mission_true`` axes);
- ``hga_stuck``: the HGA gimbal stuck at the angles it has when the fault is applied.

A ``ScheduledFault`` is a fault in a rover's plan (``sim.faults.plan``): its id, when it is
due, when it was applied and whether the conductor has revealed it.

>>> fault_from_dict({"kind": "gyro_bias", "axis": "z", "bias_deg_per_h": 10.0})
GyroBias(axis='z', bias_deg_per_h=10.0)
>>> fault_from_dict({"kind": "pancam_dust", "tau": 12})
Traceback (most recent call last):
...
sim.errors.InputError: tau: must be in [0, 10], got 12.0
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import MISSING, asdict, dataclass, fields
from typing import Any, ClassVar

from sim.errors import InputError
from sim.rover.truth import WHEEL_NAMES

AXES = ("x", "y", "z")
WHEEL_MODES = ("stall", "fail")
MAX_GYRO_BIAS_DEG_PER_H = 1000.0  # far beyond any LN-200's (1 deg/h): a broken gyro
MAX_ACCEL_BIAS_UG = 100_000.0  # 0.1 g: far beyond the LN-200's 300 ug turn-on bias
MAX_TAU = 10.0  # beyond a global dust storm's optical depth (approximate: about 5)
MAX_SAND_TRAP_RADIUS_M = 50.0
MAX_SAND_TRAP_DISTANCE_M = 10_000.0  # a traverse's reach from the start


def _finite(name: str, value: Any, low: float, high: float) -> float:
    """``value`` as a float within ``[low, high]``, or ``InputError`` naming ``name``."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise InputError(name, f"must be a number, got {value!r}")
    number = float(value)
    if not (math.isfinite(number) and low <= number <= high):
        raise InputError(name, f"must be in [{low:g}, {high:g}], got {number!r}")
    return number


def _choice(name: str, value: Any, allowed: tuple[str, ...]) -> str:
    if value not in allowed:
        raise InputError(name, f"must be one of {', '.join(allowed)}, got {value!r}")
    return str(value)


@dataclass(frozen=True)
class Fault:
    """A fault; ``kind`` names its class (``KINDS``)."""

    kind: ClassVar[str] = ""

    def as_dict(self) -> dict[str, Any]:
        """The record as plain data, its ``kind`` first."""
        return {"kind": self.kind, **asdict(self)}

    def describe(self) -> str:
        """The fault in words, for the truth record's event and the timeline."""
        return self.kind


@dataclass(frozen=True)
class WheelFault(Fault):
    """A drive motor stalls or fails (it is then dragged by the others)."""

    kind: ClassVar[str] = "wheel"
    wheel: str
    mode: str = "fail"

    def __post_init__(self) -> None:
        _choice("wheel", self.wheel, WHEEL_NAMES)
        _choice("mode", self.mode, WHEEL_MODES)

    def describe(self) -> str:
        return f"wheel {self.wheel} motor {'stalled' if self.mode == 'stall' else 'failed'}"


@dataclass(frozen=True)
class GyroBias(Fault):
    """A step in one gyro's bias, deg/h."""

    kind: ClassVar[str] = "gyro_bias"
    axis: str
    bias_deg_per_h: float

    def __post_init__(self) -> None:
        _choice("axis", self.axis, AXES)
        limit = MAX_GYRO_BIAS_DEG_PER_H
        value = _finite("bias_deg_per_h", self.bias_deg_per_h, -limit, limit)
        object.__setattr__(self, "bias_deg_per_h", value)

    def describe(self) -> str:
        return f"gyro {self.axis} bias step {self.bias_deg_per_h:+g} deg/h"


@dataclass(frozen=True)
class AccelBias(Fault):
    """A step in one accelerometer's bias, micro-g."""

    kind: ClassVar[str] = "accel_bias"
    axis: str
    bias_ug: float

    def __post_init__(self) -> None:
        _choice("axis", self.axis, AXES)
        value = _finite("bias_ug", self.bias_ug, -MAX_ACCEL_BIAS_UG, MAX_ACCEL_BIAS_UG)
        object.__setattr__(self, "bias_ug", value)

    def describe(self) -> str:
        return f"accelerometer {self.axis} bias step {self.bias_ug:+g} ug"


@dataclass(frozen=True)
class NavcamFailure(Fault):
    """The Navcams fail: no images."""

    kind: ClassVar[str] = "navcam"

    def describe(self) -> str:
        return "Navcam failure: no images"


@dataclass(frozen=True)
class PancamDust(Fault):
    """Dust of optical depth ``tau`` between the sun and the Pancam's detector."""

    kind: ClassVar[str] = "pancam_dust"
    tau: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "tau", _finite("tau", self.tau, 0.0, MAX_TAU))

    def describe(self) -> str:
        return f"Pancam obscured by dust, optical depth {self.tau:g}"


@dataclass(frozen=True)
class SandTrap(Fault):
    """A disc of soil with very high slip and sinkage, in the mission frame, m."""

    kind: ClassVar[str] = "sand_trap"
    x_m: float
    y_m: float
    radius_m: float

    def __post_init__(self) -> None:
        reach = MAX_SAND_TRAP_DISTANCE_M
        object.__setattr__(self, "x_m", _finite("x_m", self.x_m, -reach, reach))
        object.__setattr__(self, "y_m", _finite("y_m", self.y_m, -reach, reach))
        radius = _finite("radius_m", self.radius_m, 0.0, MAX_SAND_TRAP_RADIUS_M)
        if radius <= 0.0:
            raise InputError("radius_m", "must be positive")
        object.__setattr__(self, "radius_m", radius)

    def describe(self) -> str:
        return f"sand trap of radius {self.radius_m:g} m at ({self.x_m:g}, {self.y_m:g}) m"


@dataclass(frozen=True)
class HgaStuck(Fault):
    """The HGA gimbal stuck at the angles it has when the fault is applied."""

    kind: ClassVar[str] = "hga_stuck"

    def describe(self) -> str:
        return "HGA gimbal stuck"


KINDS: dict[str, type[Fault]] = {
    c.kind: c for c in (WheelFault, GyroBias, AccelBias, NavcamFailure, PancamDust, SandTrap,
                        HgaStuck)
}  # fmt: skip


def parameters(kind: str) -> list[str]:
    """The parameter names of the fault ``kind`` (``KINDS``), in order."""
    return [f.name for f in fields(KINDS[_choice("kind", kind, tuple(KINDS))])]


def fault_from_dict(data: Mapping[str, Any]) -> Fault:
    """The fault that ``data`` (``{"kind": ..., parameters...}``) describes; ``InputError``
    naming the parameter for an unknown kind, a missing, unknown or invalid parameter."""
    if not isinstance(data, Mapping):
        raise InputError("fault", f"must be an object, got {data!r}")
    kind = _choice("kind", data.get("kind"), tuple(KINDS))
    cls = KINDS[kind]
    names = [f.name for f in fields(cls)]
    given = {k: v for k, v in data.items() if k != "kind"}
    unknown = sorted(set(given) - set(names))
    if unknown:
        its = ", ".join(names) or "none"
        raise InputError(unknown[0], f"is not a parameter of {kind} (its: {its})")
    required = [f.name for f in fields(cls) if f.default is MISSING]
    missing = [n for n in required if n not in given]
    if missing:
        raise InputError(missing[0], f"is required for {kind}")
    return cls(**given)


@dataclass(frozen=True)
class ScheduledFault:
    """A fault of the plan: ``fault_id`` (1, 2, ... per rover), the ``fault``, when it is due
    (``at_t_s``, TT s), when it was applied (``applied_t_s``; ``None`` while pending), why it
    could not be (``error``, else ``None``) and whether it is ``revealed``."""

    fault_id: int
    fault: Fault
    at_t_s: float
    applied_t_s: float | None = None
    error: str | None = None
    revealed: bool = False

    @property
    def applied(self) -> bool:
        return self.applied_t_s is not None

    def as_dict(self) -> dict[str, Any]:
        """Plain data (checkpoints, the server's answers)."""
        return {"fault_id": self.fault_id, "fault": self.fault.as_dict(), "at_t_s": self.at_t_s,
                "applied_t_s": self.applied_t_s, "error": self.error,
                "revealed": self.revealed}  # fmt: skip

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> ScheduledFault:
        applied = data["applied_t_s"]
        return cls(int(data["fault_id"]), fault_from_dict(data["fault"]), float(data["at_t_s"]),
                   None if applied is None else float(applied), data["error"],
                   bool(data["revealed"]))  # fmt: skip
