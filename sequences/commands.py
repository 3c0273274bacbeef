"""The rover's command dictionary as typed, validated commands.

One frozen dataclass per command; construction checks every argument and raises
``ValueError`` naming it, so an object that exists is a command the rover can be given.
Units are in the argument names; angles are degrees here, at the edge (docs/CONVENTIONS.md), and
the sequencer converts them. The text and JSON sequence formats (the operations-server
issue) parse into these.

SAPP's commands follow Ali et al. 2005: the NATE primitives (sec. 2.2-2.4), the
acquisition commands of sec. 2.2.4, and the two lessons of sec. 5 (Suncheck then Sungaze
as one command, the operators' practice of sec. 4; gyrocompassing).

Each command declares its arguments once, in ``specs`` (an ``ArgSpec`` per argument: kind,
unit, range, note); construction checks them and the server publishes them, so the console
form and the validation cannot disagree. Rules that tie arguments together stay as code in
``_check_rules`` and are described by the spec's ``note``. Each command also says what NATE
does with it (``in_articulate``, ``images_sun``, ``aqf_after``), which the validator's walk
reads instead of lists of its own. The numbers come from their owners: NATE's defaults and
the rover's geometry from the flight software (``estimation``), the drive and visual
odometry limits the ground shares with the simulator from ``sequences.limits``.

>>> DriveStraight(distance_m=2.0).name
'DRIVE_STRAIGHT'
>>> DriveStraight(distance_m=-1.0)
Traceback (most recent call last):
...
ValueError: distance_m: must be in (0, 100] m, got -1.0
>>> DriveStraight.specs["distance_m"].range_text()
'(0, 100] m'
"""

from __future__ import annotations

import math
import numbers
import reprlib
from collections.abc import Mapping
from dataclasses import MISSING, dataclass, fields
from typing import ClassVar, Literal

from estimation.geometry import FLIGHT_GEOMETRY, WHEEL_KEYS
from estimation.sapp.nate_io import CONTROL_DT_S, NateParams

# The shared limits, re-exported: the dictionary's users read them as ``cmd.MAX_DRIVE_M``.
from sequences.limits import MAX_DRIVE_M as MAX_DRIVE_M
from sequences.limits import VO_PROCESSING_S as VO_PROCESSING_S
from sequences.limits import VO_STEP_MAX_DEG as VO_STEP_MAX_DEG
from sequences.limits import VO_STEP_MAX_M as VO_STEP_MAX_M

MAX_WAIT_S = 2 * 88775.244  # two sols
MAX_HGA_PASS_MIN = 120.0
MIN_ARC_RADIUS_M = 0.5 * FLIGHT_GEOMETRY.track_m  # sim.rover.drive refuses a tighter arc
_NATE = NateParams()  # NATE's defaults, for the notes
_NADIR = _NATE.nadir


ArgKind = Literal["number", "boolean", "string", "number_or_boolean"]


class _Short(reprlib.Repr):
    """``repr`` cut short, for messages: strings and containers shortened, nesting depth
    bounded, and an integer too long for ``repr`` (over 4,300 digits) described instead."""

    def __init__(self) -> None:
        super().__init__()
        self.maxstring = self.maxother = self.maxlong = 40
        self.maxlevel = 3

    def repr_int(self, x: int, level: int) -> str:
        if x.bit_length() > 128:
            sign = "a negative" if x < 0 else "an"
            return f"{sign} integer of about {int(x.bit_length() * math.log10(2)) + 1} digits"
        return super().repr_int(x, level)


_SHORT = _Short()


def shown(value: object) -> str:
    """``value`` as a message shows it: its ``repr``, at most about 40 characters, for any
    value (a 5,000-digit integer or a list nested a thousand deep included).

    >>> shown(1.5), shown("x" * 100)[:12], shown(10**5000)
    ('1.5', "'xxxxxxxxxxx", 'an integer of about 5001 digits')
    """
    return _SHORT.repr(value)


@dataclass(frozen=True)
class ArgSpec:
    """One argument as the dictionary publishes it and construction checks it.

    ``number``: a real number in ``[lo, hi] unit`` (``(lo, hi]`` when ``lo_open``).
    ``boolean``: true or false. ``number_or_boolean``: either; the number finite.
    ``string``: text whose meaning the command checks in its rules (``note`` says it).
    ``note``: what the range cannot say (rules across arguments, sign conventions).
    An argument whose default is ``None`` may be omitted: the rover uses its parameter."""

    kind: ArgKind
    unit: str = ""
    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    note: str = ""

    def __post_init__(self) -> None:
        numeric = self.kind == "number"
        if numeric != (self.lo is not None and self.hi is not None) or (numeric and not self.unit):
            raise TypeError(f"ArgSpec: a number has lo, hi and a unit; got {self!r}")

    def range_text(self) -> str:
        """``(lo, hi] unit`` as in the error messages; ``""`` for a non-number."""
        if self.lo is None or self.hi is None:
            return ""
        left = "(" if self.lo_open else "["
        return f"{left}{self.lo:g}, {self.hi:g}] {self.unit}"

    def contains(self, value: float) -> bool:
        """Whether ``value`` (finite) lies in the range; ``False`` for a non-number spec."""
        if self.lo is None or self.hi is None or not math.isfinite(value):
            return False
        return (value > self.lo if self.lo_open else value >= self.lo) and value <= self.hi

    def check(self, name: str, value: object) -> None:
        """Raise ``ValueError`` naming ``name`` unless ``value`` is of this kind and range."""
        if self.kind == "number":
            _check_number(name, value, self)
        elif self.kind == "boolean" and not isinstance(value, bool):
            raise ValueError(f"{name}: must be true or false, got {shown(value)}")
        elif self.kind == "number_or_boolean" and not isinstance(value, bool):
            _finite_number_or_boolean(name, value)


def _check_number(name: str, value: object, spec: ArgSpec) -> None:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ValueError(f"{name}: must be a number, got {shown(value)}")
    try:
        v = float(value)
    except OverflowError:  # an int beyond float
        v = math.inf
    if not spec.contains(v):
        raise ValueError(f"{name}: must be in {spec.range_text()}, got {shown(value)}")


def _finite_number_or_boolean(name: str, value: object) -> None:
    if not isinstance(value, numbers.Real):
        raise ValueError(f"{name}: must be a number or true/false, got {shown(value)}")
    try:
        finite = math.isfinite(float(value))
    except OverflowError:
        finite = False
    if not finite:
        raise ValueError(f"{name}: must be finite, got {shown(value)}")


@dataclass(frozen=True)
class Argument:
    """One argument of a command for the dictionary: its spec, and whether it may be
    omitted (``default``, ``None`` meaning the rover's parameter)."""

    name: str
    spec: ArgSpec
    required: bool
    default: object


@dataclass(frozen=True)
class Command:
    """Base of every command: ``name`` is the sequence-language keyword; ``specs`` holds an
    ``ArgSpec`` per argument, in field order."""

    name: ClassVar[str] = ""
    specs: ClassVar[Mapping[str, ArgSpec]] = {}
    # What NATE does with the command (Ali et al. 2005; ``estimation.sapp.nate``), for the
    # ground's checks and predictions (``sequences.validate``): accepted while articulating
    # (sec. 2.4.1), refused with the sun below its minimum elevation (the camera modes'
    # sanity check), and the Attitude Quality Flag a success leaves (sec. 2.1).
    in_articulate: ClassVar[bool] = False
    images_sun: ClassVar[bool] = False
    aqf_after: ClassVar[str | None] = None

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if value is None and f.default is None:
                continue  # omitted: the rover uses its parameter
            self.specs[f.name].check(f.name, value)
        self._check_rules()

    def _check_rules(self) -> None:
        """Rules a range cannot express; the arguments' ``note`` describes them."""

    @classmethod
    def argument_table(cls) -> tuple[Argument, ...]:
        """Every argument with its spec, in field order (what ``GET /api/commands`` shows)."""
        return tuple(
            Argument(
                f.name,
                cls.specs[f.name],
                required=f.default is MISSING,
                default=None if f.default is MISSING else f.default,
            )
            for f in fields(cls)
        )

    def arguments(self) -> dict[str, object]:
        """The arguments as a plain dict (for telemetry and storage)."""
        return {f.name: getattr(self, f.name) for f in fields(self)}

    def describe(self) -> str:
        """``NAME arg=value ...`` as in a sequence file."""
        args = " ".join(
            f"{k}={str(v).lower() if isinstance(v, bool) else v}"  # on/off as the language
            for k, v in self.arguments().items()
            if v is not None
        )
        return f"{self.name} {args}".strip()


# Specs shared by several commands.
_WINDOW_S = ArgSpec(
    "number",
    "s",
    0.0,
    600.0,
    lo_open=True,
    note=f"omit: the parameter ({_NADIR.window_s:g} s); the rover refuses a window holding "
    f"fewer than min_valid_samples 8 Hz samples "
    f"({_NADIR.min_valid_samples * CONTROL_DT_S:g} s by default)",
)
_TOLERANCE_DEG = ArgSpec("number", "deg", 0.0, 90.0, lo_open=True, note="omit: the parameter")
_DRIVE_TO_NOTE = (
    f"the goal must be 0.01-{MAX_DRIVE_M:g} m from the estimated position when it starts"
)


VO_SPECS: Mapping[str, ArgSpec] = {
    "vo": ArgSpec(
        "boolean",
        note=f"visual odometry: steps of at most {VO_STEP_MAX_M:g} m and "
        f"{VO_STEP_MAX_DEG:g} deg, a Navcam pair after each, SAPP's position updated",
    ),
    "vo_attitude": ArgSpec("boolean", note="with vo=on: VO updates the attitude too"),
    "drag_wheel": ArgSpec("string", note=f"{'|'.join(WHEEL_KEYS)}: not driven but dragged"),
}


def vo_step_count(
    length_m: float,
    turn_deg: float,
    max_step_m: float = VO_STEP_MAX_M,
    max_step_deg: float = VO_STEP_MAX_DEG,
) -> int:
    """Steps a ``vo=on`` drive of path ``length_m`` turning ``turn_deg`` is split into,
    each at most ``max_step_m`` and ``max_step_deg`` (MER's limits unless told).

    >>> vo_step_count(2.0, 0.0), vo_step_count(0.0, -90.0), vo_step_count(0.5, 40.0)
    (3, 5, 3)
    >>> vo_step_count(2.45, 0.0, max_step_m=0.35)  # Cheng, Maimone and Matthies 2005's rock course
    7
    """
    if not (math.isfinite(max_step_m) and max_step_m > 0.0):
        raise ValueError(f"max_step_m: must be positive, got {max_step_m}")
    if not (math.isfinite(max_step_deg) and max_step_deg > 0.0):
        raise ValueError(f"max_step_deg: must be positive, got {max_step_deg}")
    by_length = math.ceil(abs(length_m) / max_step_m - 1e-9)
    by_turn = math.ceil(abs(turn_deg) / max_step_deg - 1e-9)
    return max(1, by_length, by_turn)


def _check_vo(command: Command) -> None:
    if getattr(command, "vo_attitude", False) and not getattr(command, "vo", False):
        raise ValueError("vo_attitude: needs vo=on")
    if (drag := getattr(command, "drag_wheel", None)) not in (None, *WHEEL_KEYS):
        raise ValueError(f"drag_wheel: must be one of {', '.join(WHEEL_KEYS)}, got {shown(drag)}")


@dataclass(frozen=True)
class DriveStraight(Command):
    """Drive ``distance_m`` straight ahead."""

    name: ClassVar[str] = "DRIVE_STRAIGHT"
    specs: ClassVar[Mapping[str, ArgSpec]] = {
        "distance_m": ArgSpec("number", "m", 0.0, MAX_DRIVE_M, lo_open=True),
        **VO_SPECS,
    }
    distance_m: float
    vo: bool | None = None  # None: off
    vo_attitude: bool | None = None
    drag_wheel: str | None = None  # None: all six wheels driven

    def _check_rules(self) -> None:
        _check_vo(self)


@dataclass(frozen=True)
class DriveArc(Command):
    """Drive forwards along an arc of signed ``radius_m`` (> 0 centre on the right)
    through a heading change of ``angle_deg``."""

    name: ClassVar[str] = "DRIVE_ARC"
    specs: ClassVar[Mapping[str, ArgSpec]] = {
        "radius_m": ArgSpec(
            "number",
            "m",
            -1e3,
            1e3,
            note=f"|radius_m| at least {MIN_ARC_RADIUS_M:g} m (half the track); "
            "> 0 centre on the right",
        ),
        "angle_deg": ArgSpec(
            "number",
            "deg",
            0.0,
            360.0,
            lo_open=True,
            note=f"the arc (|radius_m| × angle) at most {MAX_DRIVE_M:g} m long",
        ),
        **VO_SPECS,
    }
    radius_m: float
    angle_deg: float
    vo: bool | None = None  # None: off
    vo_attitude: bool | None = None
    drag_wheel: str | None = None  # None: all six wheels driven

    def _check_rules(self) -> None:
        _check_vo(self)
        r, a = float(self.radius_m), float(self.angle_deg)
        if abs(r) < MIN_ARC_RADIUS_M:
            raise ValueError(
                f"radius_m: must be at least {MIN_ARC_RADIUS_M:g} m (half the track), "
                f"got {shown(r)}"
            )
        if abs(r) * math.radians(a) > MAX_DRIVE_M:
            raise ValueError(f"angle_deg: the arc would be longer than {MAX_DRIVE_M:g} m")


@dataclass(frozen=True)
class TurnInPlace(Command):
    """Turn in place by ``angle_deg`` (> 0 clockwise seen from above)."""

    name: ClassVar[str] = "TURN_IN_PLACE"
    specs: ClassVar[Mapping[str, ArgSpec]] = {
        "angle_deg": ArgSpec(
            "number", "deg", -360.0, 360.0, note="not zero; > 0 clockwise seen from above"
        ),
        **VO_SPECS,
    }
    angle_deg: float
    vo: bool | None = None  # None: off
    vo_attitude: bool | None = None
    drag_wheel: str | None = None  # None: all six wheels driven

    def _check_rules(self) -> None:
        _check_vo(self)
        if float(self.angle_deg) == 0.0:
            raise ValueError("angle_deg: must not be zero")


@dataclass(frozen=True)
class DriveTo(Command):
    """Drive to ``(x_m, y_m)`` (North, East) in the current Site: turn in place towards the
    goal and drive straight, both by the onboard estimate (the rover goes where it
    *believes* the goal is; the difference is the estimate's error). The goal must be
    0.01-100 m from the rover's estimated position when the command starts."""

    name: ClassVar[str] = "DRIVE_TO"
    specs: ClassVar[Mapping[str, ArgSpec]] = {
        "x_m": ArgSpec("number", "m", -1000.0, 1000.0, note=f"North in the Site; {_DRIVE_TO_NOTE}"),
        "y_m": ArgSpec("number", "m", -1000.0, 1000.0, note=f"East in the Site; {_DRIVE_TO_NOTE}"),
        **VO_SPECS,
    }
    x_m: float
    y_m: float
    vo: bool | None = None  # None: off
    vo_attitude: bool | None = None
    drag_wheel: str | None = None  # None: all six wheels driven

    def _check_rules(self) -> None:
        _check_vo(self)


@dataclass(frozen=True)
class PlantSite(Command):
    """Plant a new Site frame at the rover (position resets, index increments)."""

    name: ClassVar[str] = "PLANT_SITE"


@dataclass(frozen=True)
class NadirUpdate(Command):
    """Nadir Update over ``window_s`` (default: the parameter, 10 s)."""

    name: ClassVar[str] = "NADIR_UPDATE"
    aqf_after: ClassVar[str | None] = "TiltOnly"
    specs: ClassVar[Mapping[str, ArgSpec]] = {"window_s": _WINDOW_S}
    window_s: float | None = None


@dataclass(frozen=True)
class NadirCheck(Command):
    """Nadir Check with an optional ``tolerance_deg`` and ``window_s``."""

    name: ClassVar[str] = "NADIR_CHECK"
    specs: ClassVar[Mapping[str, ArgSpec]] = {
        "tolerance_deg": _TOLERANCE_DEG,
        "window_s": _WINDOW_S,
    }
    tolerance_deg: float | None = None
    window_s: float | None = None


@dataclass(frozen=True)
class Sunfind(Command):
    """Sunfind: search for the sun along its elevation cone and correct the heading."""

    name: ClassVar[str] = "SUNFIND"
    images_sun: ClassVar[bool] = True
    aqf_after: ClassVar[str | None] = "Coarse"


@dataclass(frozen=True)
class Suncheck(Command):
    """Suncheck with an optional ``tolerance_deg``."""

    name: ClassVar[str] = "SUNCHECK"
    images_sun: ClassVar[bool] = True
    specs: ClassVar[Mapping[str, ArgSpec]] = {"tolerance_deg": _TOLERANCE_DEG}
    tolerance_deg: float | None = None


@dataclass(frozen=True)
class Sungaze(Command):
    """Sungaze; ``use_gravity`` selects the variation with the accelerometers."""

    name: ClassVar[str] = "SUNGAZE"
    images_sun: ClassVar[bool] = True
    aqf_after: ClassVar[str | None] = "Fine"
    specs: ClassVar[Mapping[str, ArgSpec]] = {
        "use_gravity": ArgSpec(
            "boolean", note="true: the variation with the accelerometers; omit: the parameter"
        ),
    }
    use_gravity: bool | None = None


@dataclass(frozen=True)
class GetTiltAttitude(Command):
    """GetTiltAttitude (Ali et al. 2005 sec. 2.2.4)."""

    name: ClassVar[str] = "GET_TILT_ATTITUDE"
    aqf_after: ClassVar[str | None] = "TiltOnly"


@dataclass(frozen=True)
class GetCoarseAttitude(Command):
    """GetCoarseAttitude (Ali et al. 2005 sec. 2.2.4)."""

    name: ClassVar[str] = "GET_COARSE_ATTITUDE"
    images_sun: ClassVar[bool] = True
    aqf_after: ClassVar[str | None] = "Coarse"


@dataclass(frozen=True)
class GetFineAttitude(Command):
    """GetFineAttitude (Ali et al. 2005 sec. 2.2.4)."""

    name: ClassVar[str] = "GET_FINE_ATTITUDE"
    images_sun: ClassVar[bool] = True
    aqf_after: ClassVar[str | None] = "Fine"


@dataclass(frozen=True)
class SuncheckSungaze(Command):
    """Suncheck followed by Sungaze as one command: the operators' practice of Ali et al.
    2005 sec. 4, and sec. 5's wish for it as one command. Meant for an AQF of Coarse or
    better (the validator warns below); Sungaze follows a Suncheck that saw the sun."""

    name: ClassVar[str] = "SUNCHECK_SUNGAZE"
    images_sun: ClassVar[bool] = True
    aqf_after: ClassVar[str | None] = "Fine"


@dataclass(frozen=True)
class Gyrocompass(Command):
    """Gyrocompass at rest for ``duration_s`` (default: the parameter, 1800 s)."""

    name: ClassVar[str] = "GYROCOMPASS"
    aqf_after: ClassVar[str | None] = "Coarse"
    specs: ClassVar[Mapping[str, ArgSpec]] = {
        "duration_s": ArgSpec(
            "number",
            "s",
            0.0,
            6 * 3600.0,
            lo_open=True,
            note=f"omit: the parameter ({_NATE.gyrocompass_duration_s:g} s)",
        ),
    }
    duration_s: float | None = None


@dataclass(frozen=True)
class ArticulateStart(Command):
    """Enter Articulate: propagate the attitude at 8 Hz while instruments move."""

    name: ClassVar[str] = "ARTICULATE_START"


@dataclass(frozen=True)
class ArticulateStop(Command):
    """Leave Articulate."""

    name: ClassVar[str] = "ARTICULATE_STOP"
    in_articulate: ClassVar[bool] = True


@dataclass(frozen=True)
class HgaPass(Command):
    """Point the HGA at Earth for ``duration_min`` minutes (re-pointed every minute)."""

    name: ClassVar[str] = "HGA_PASS"
    in_articulate: ClassVar[bool] = True
    specs: ClassVar[Mapping[str, ArgSpec]] = {
        "duration_min": ArgSpec("number", "min", 0.0, MAX_HGA_PASS_MIN, lo_open=True),
    }
    duration_min: float = 15.0


@dataclass(frozen=True)
class Wait(Command):
    """Do nothing for ``duration_s`` (NATE keeps its mode: Articulate keeps propagating)."""

    name: ClassVar[str] = "WAIT"
    in_articulate: ClassVar[bool] = True
    specs: ClassVar[Mapping[str, ArgSpec]] = {
        "duration_s": ArgSpec(
            "number", "s", 0.0, MAX_WAIT_S, lo_open=True, note="two sols at most"
        ),
    }
    duration_s: float


@dataclass(frozen=True)
class SetParam(Command):
    """Set a NATE parameter by dotted name (``sungaze.timer_s``), SI units."""

    name: ClassVar[str] = "SET_PARAM"
    specs: ClassVar[Mapping[str, ArgSpec]] = {
        "param": ArgSpec("string", note="a NATE parameter by dotted name, e.g. sungaze.timer_s"),
        "value": ArgSpec("number_or_boolean", note="in the parameter's SI unit, or true/false"),
    }
    param: str
    value: float | bool

    def _check_rules(self) -> None:
        if not isinstance(self.param, str) or not self.param.strip():
            raise ValueError(f"param: must be a parameter name, got {shown(self.param)}")


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


def _check_specs_match_arguments() -> None:
    """Every argument needs its spec (to be checked and published) and every spec its
    argument: a command that breaks this fails when the module loads, not when an operator
    first sends it."""
    for kind in COMMANDS.values():
        arguments = [f.name for f in fields(kind)]
        if list(kind.specs) != arguments:
            raise TypeError(f"{kind.__name__}.specs: {list(kind.specs)}, arguments {arguments}")


_check_specs_match_arguments()
