"""The rover's command dictionary as typed, validated commands.

One frozen dataclass per command; construction checks every argument and raises
``ValueError`` naming it, so an object that exists is a command the rover can be given.
Units are in the argument names; angles are degrees here, at the edge (CONVENTIONS.md), and
the sequencer converts them. The text and JSON sequence formats (the operations-server
issue) parse into these.

SAPP's commands follow Ali et al. 2005 (seed 000): the NATE primitives (sec. 2.2-2.4), the
acquisition commands of sec. 2.2.4, and the two lessons of sec. 4-5 (Suncheck then
Sungaze as one command; gyrocompassing).

>>> DriveStraight(distance_m=2.0).name
'DRIVE_STRAIGHT'
>>> DriveStraight(distance_m=-1.0)
Traceback (most recent call last):
...
ValueError: distance_m: must be in (0, 100] m, got -1.0
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, fields
from typing import ClassVar

MAX_DRIVE_M = 100.0  # one drive command; matches sim.drive.MAX_PATH_M
MAX_WAIT_S = 2 * 88775.244  # two sols
MAX_HGA_PASS_MIN = 120.0


def _number(name: str, value: object, lo: float, hi: float, unit: str, lo_open: bool) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ValueError(f"{name}: must be a number, got {value!r}")
    try:
        v = float(value)
    except OverflowError:
        v = math.inf
    ok = math.isfinite(v) and (v > lo if lo_open else v >= lo) and v <= hi
    if not ok:
        left = "(" if lo_open else "["
        raise ValueError(f"{name}: must be in {left}{lo:g}, {hi:g}] {unit}, got {value!r}")
    return v


@dataclass(frozen=True)
class Command:
    """Base of every command: ``name`` is the sequence-language keyword."""

    name: ClassVar[str] = ""

    def arguments(self) -> dict[str, object]:
        """The arguments as a plain dict (for telemetry and storage)."""
        return {f.name: getattr(self, f.name) for f in fields(self)}

    def describe(self) -> str:
        """``NAME arg=value ...`` as in a sequence file."""
        args = " ".join(f"{k}={v}" for k, v in self.arguments().items() if v is not None)
        return f"{self.name} {args}".strip()


@dataclass(frozen=True)
class DriveStraight(Command):
    """Drive ``distance_m`` straight ahead."""

    name: ClassVar[str] = "DRIVE_STRAIGHT"
    distance_m: float

    def __post_init__(self) -> None:
        _number("distance_m", self.distance_m, 0.0, MAX_DRIVE_M, "m", lo_open=True)


@dataclass(frozen=True)
class DriveArc(Command):
    """Drive forwards along an arc of signed ``radius_m`` (> 0 centre on the right)
    through a heading change of ``angle_deg``."""

    name: ClassVar[str] = "DRIVE_ARC"
    radius_m: float
    angle_deg: float

    def __post_init__(self) -> None:
        r = _number("radius_m", self.radius_m, -1e3, 1e3, "m", lo_open=False)
        if abs(r) < 0.6:
            raise ValueError(f"radius_m: must be at least 0.6 m (half the track), got {r!r}")
        a = _number("angle_deg", self.angle_deg, 0.0, 360.0, "deg", lo_open=True)
        if abs(r) * math.radians(a) > MAX_DRIVE_M:
            raise ValueError(f"angle_deg: the arc would be longer than {MAX_DRIVE_M:g} m")


@dataclass(frozen=True)
class TurnInPlace(Command):
    """Turn in place by ``angle_deg`` (> 0 clockwise seen from above)."""

    name: ClassVar[str] = "TURN_IN_PLACE"
    angle_deg: float

    def __post_init__(self) -> None:
        a = _number("angle_deg", self.angle_deg, -360.0, 360.0, "deg", lo_open=False)
        if a == 0.0:
            raise ValueError("angle_deg: must not be zero")


@dataclass(frozen=True)
class DriveTo(Command):
    """Drive to ``(x_m, y_m)`` (North, East) in the current Site: turn in place towards the
    goal and drive straight, both by the onboard estimate (the rover goes where it
    *believes* the goal is; the difference is the estimate's error). The goal must be
    0.01-100 m from the rover's estimated position when the command starts."""

    name: ClassVar[str] = "DRIVE_TO"
    x_m: float
    y_m: float

    def __post_init__(self) -> None:
        _number("x_m", self.x_m, -1000.0, 1000.0, "m", lo_open=False)
        _number("y_m", self.y_m, -1000.0, 1000.0, "m", lo_open=False)


@dataclass(frozen=True)
class PlantSite(Command):
    """Plant a new Site frame at the rover (position resets, index increments)."""

    name: ClassVar[str] = "PLANT_SITE"


@dataclass(frozen=True)
class NadirUpdate(Command):
    """Nadir Update over ``window_s`` (default: the parameter, 10 s)."""

    name: ClassVar[str] = "NADIR_UPDATE"
    window_s: float | None = None

    def __post_init__(self) -> None:
        if self.window_s is not None:
            _number("window_s", self.window_s, 0.0, 600.0, "s", lo_open=True)


@dataclass(frozen=True)
class NadirCheck(Command):
    """Nadir Check with an optional ``tolerance_deg`` and ``window_s``."""

    name: ClassVar[str] = "NADIR_CHECK"
    tolerance_deg: float | None = None
    window_s: float | None = None

    def __post_init__(self) -> None:
        if self.tolerance_deg is not None:
            _number("tolerance_deg", self.tolerance_deg, 0.0, 90.0, "deg", lo_open=True)
        if self.window_s is not None:
            _number("window_s", self.window_s, 0.0, 600.0, "s", lo_open=True)


@dataclass(frozen=True)
class Sunfind(Command):
    """Sunfind: search for the sun along its elevation cone and correct the heading."""

    name: ClassVar[str] = "SUNFIND"


@dataclass(frozen=True)
class Suncheck(Command):
    """Suncheck with an optional ``tolerance_deg``."""

    name: ClassVar[str] = "SUNCHECK"
    tolerance_deg: float | None = None

    def __post_init__(self) -> None:
        if self.tolerance_deg is not None:
            _number("tolerance_deg", self.tolerance_deg, 0.0, 90.0, "deg", lo_open=True)


@dataclass(frozen=True)
class Sungaze(Command):
    """Sungaze; ``use_gravity`` selects the variation with the accelerometers."""

    name: ClassVar[str] = "SUNGAZE"
    use_gravity: bool | None = None

    def __post_init__(self) -> None:
        if self.use_gravity is not None and not isinstance(self.use_gravity, bool):
            raise ValueError(f"use_gravity: must be true or false, got {self.use_gravity!r}")


@dataclass(frozen=True)
class GetTiltAttitude(Command):
    """GetTiltAttitude (seed 000 sec. 2.2.4)."""

    name: ClassVar[str] = "GET_TILT_ATTITUDE"


@dataclass(frozen=True)
class GetCoarseAttitude(Command):
    """GetCoarseAttitude (seed 000 sec. 2.2.4)."""

    name: ClassVar[str] = "GET_COARSE_ATTITUDE"


@dataclass(frozen=True)
class GetFineAttitude(Command):
    """GetFineAttitude (seed 000 sec. 2.2.4)."""

    name: ClassVar[str] = "GET_FINE_ATTITUDE"


@dataclass(frozen=True)
class SuncheckSungaze(Command):
    """Suncheck followed by Sungaze as one command (seed 000 sec. 5)."""

    name: ClassVar[str] = "SUNCHECK_SUNGAZE"


@dataclass(frozen=True)
class Gyrocompass(Command):
    """Gyrocompass at rest for ``duration_s`` (default: the parameter, 1800 s)."""

    name: ClassVar[str] = "GYROCOMPASS"
    duration_s: float | None = None

    def __post_init__(self) -> None:
        if self.duration_s is not None:
            _number("duration_s", self.duration_s, 0.0, 6 * 3600.0, "s", lo_open=True)


@dataclass(frozen=True)
class ArticulateStart(Command):
    """Enter Articulate: propagate the attitude at 8 Hz while instruments move."""

    name: ClassVar[str] = "ARTICULATE_START"


@dataclass(frozen=True)
class ArticulateStop(Command):
    """Leave Articulate."""

    name: ClassVar[str] = "ARTICULATE_STOP"


@dataclass(frozen=True)
class HgaPass(Command):
    """Point the HGA at Earth for ``duration_min`` minutes (re-pointed every minute)."""

    name: ClassVar[str] = "HGA_PASS"
    duration_min: float = 15.0

    def __post_init__(self) -> None:
        _number("duration_min", self.duration_min, 0.0, MAX_HGA_PASS_MIN, "min", lo_open=True)


@dataclass(frozen=True)
class Wait(Command):
    """Do nothing for ``duration_s`` (NATE keeps its mode: Articulate keeps propagating)."""

    name: ClassVar[str] = "WAIT"
    duration_s: float

    def __post_init__(self) -> None:
        _number("duration_s", self.duration_s, 0.0, MAX_WAIT_S, "s", lo_open=True)


@dataclass(frozen=True)
class SetParam(Command):
    """Set a NATE parameter by dotted name (``sungaze.timer_s``), SI units."""

    name: ClassVar[str] = "SET_PARAM"
    param: str
    value: float | bool

    def __post_init__(self) -> None:
        if not isinstance(self.param, str) or not self.param.strip():
            raise ValueError(f"param: must be a parameter name, got {self.param!r}")
        if not isinstance(self.value, (bool, numbers.Real)):
            raise ValueError(f"value: must be a number or true/false, got {self.value!r}")
        if not isinstance(self.value, bool):
            try:
                finite = math.isfinite(float(self.value))
            except OverflowError:
                finite = False
            if not finite:
                raise ValueError(f"value: must be finite, got {self.value!r}")


COMMANDS: dict[str, type[Command]] = {
    c.name: c
    for c in (
        DriveStraight,
        DriveArc,
        TurnInPlace,
        DriveTo,
        PlantSite,
        NadirUpdate,
        NadirCheck,
        Sunfind,
        Suncheck,
        Sungaze,
        GetTiltAttitude,
        GetCoarseAttitude,
        GetFineAttitude,
        SuncheckSungaze,
        Gyrocompass,
        ArticulateStart,
        ArticulateStop,
        HgaPass,
        Wait,
        SetParam,
    )
}
