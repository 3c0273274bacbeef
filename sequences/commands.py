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
from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import ClassVar

from estimation.geometry import FLIGHT_GEOMETRY, WHEEL_KEYS
from estimation.protection.keepout import parse_polygon
from estimation.protection.limits import LIMITS, check_limit
from estimation.sapp.nate_io import CONTROL_DT_S, NateParams
from sequences.command_base import ArgKind as ArgKind
from sequences.command_base import ArgSpec as ArgSpec
from sequences.command_base import Argument as Argument
from sequences.command_base import Command as Command
from sequences.command_base import shown as shown

# The shared limits, re-exported: the dictionary's users read them as ``cmd.MAX_DRIVE_M``.
from sequences.limits import MAX_DRIVE_M as MAX_DRIVE_M
from sequences.limits import VO_PROCESSING_S as VO_PROCESSING_S
from sequences.limits import VO_RIGS_PX as VO_RIGS_PX
from sequences.limits import VO_STEP_MAX_DEG as VO_STEP_MAX_DEG
from sequences.limits import VO_STEP_MAX_M as VO_STEP_MAX_M
from sequences.vo_settings import VO_POINTING_SPECS as VO_POINTING_SPECS
from sequences.vo_settings import check_vo_pointing, check_vo_setting

MAX_WAIT_S = 2 * 88775.244  # two sols
MAX_HGA_PASS_MIN = 120.0
MIN_ARC_RADIUS_M = 0.5 * FLIGHT_GEOMETRY.track_m  # sim.rover.drive refuses a tighter arc
_NATE = NateParams()  # NATE's defaults, for the notes
_NADIR = _NATE.nadir


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


# A drive's own mobility limits (``estimation.protection``): omitted, the rover's.
PROTECTION_SPECS: Mapping[str, ArgSpec] = {
    "slip_limit_pct": ArgSpec(
        "number",
        "pct",
        0.0,
        100.0,
        note=f"with vo=on: halt when the slip over a slip check exceeds it; omit: the "
        f"rover's mobility.slip_limit ({100 * LIMITS.slip_limit:g} %)",
    ),
    "vo_fail": ArgSpec(
        "string",
        note=f"halt or continue: when VO fails mobility.vo_max_failures_in_row "
        f"({LIMITS.vo_max_failures_in_row}) steps in a row; omit: halt",
    ),
    "timeout_s": ArgSpec(
        "number",
        "s",
        0.0,
        86400.0,
        lo_open=True,
        note=f"halt when the drive has not ended by then; omit: mobility.drive_timeout_s "
        f"({LIMITS.drive_timeout_s:g} s)",
    ),
    "lmst_limit_h": ArgSpec(
        "number",
        "h",
        0.0,
        24.0,
        note="halt when Local Mean Solar Time reaches it (15.5: 15:30; 24: midnight); omit: none",
    ),
}


def _check_protection(command: Command) -> None:
    vo_fail = getattr(command, "vo_fail", None)
    if vo_fail is not None and vo_fail not in ("halt", "continue"):
        raise ValueError(f"vo_fail: must be halt or continue, got {shown(vo_fail)}")


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
    _check_protection(command)
    check_vo_pointing(command)


@dataclass(frozen=True)
class DriveStraight(Command):
    """Drive ``distance_m`` straight ahead."""

    name: ClassVar[str] = "DRIVE_STRAIGHT"
    specs: ClassVar[Mapping[str, ArgSpec]] = {
        "distance_m": ArgSpec("number", "m", 0.0, MAX_DRIVE_M, lo_open=True),
        **VO_SPECS,
        **PROTECTION_SPECS,
        **VO_POINTING_SPECS,
    }
    distance_m: float
    vo: bool | None = None  # None: off
    vo_attitude: bool | None = None
    drag_wheel: str | None = None  # None: all six wheels driven
    slip_limit_pct: float | None = None  # None: the rover's limits (PROTECTION_SPECS)
    vo_fail: str | None = None
    timeout_s: float | None = None
    lmst_limit_h: float | None = None
    vo_az_deg: float | None = None  # None: VO_MAST_AZ_DEG (VO_POINTING_SPECS)
    vo_el_deg: float | None = None

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
        **PROTECTION_SPECS,
        **VO_POINTING_SPECS,
    }
    radius_m: float
    angle_deg: float
    vo: bool | None = None  # None: off
    vo_attitude: bool | None = None
    drag_wheel: str | None = None  # None: all six wheels driven
    slip_limit_pct: float | None = None  # None: the rover's limits (PROTECTION_SPECS)
    vo_fail: str | None = None
    timeout_s: float | None = None
    lmst_limit_h: float | None = None
    vo_az_deg: float | None = None  # None: VO_MAST_AZ_DEG (VO_POINTING_SPECS)
    vo_el_deg: float | None = None

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
        **PROTECTION_SPECS,
        **VO_POINTING_SPECS,
    }
    angle_deg: float
    vo: bool | None = None  # None: off
    vo_attitude: bool | None = None
    drag_wheel: str | None = None  # None: all six wheels driven
    slip_limit_pct: float | None = None  # None: the rover's limits (PROTECTION_SPECS)
    vo_fail: str | None = None
    timeout_s: float | None = None
    lmst_limit_h: float | None = None
    vo_az_deg: float | None = None  # None: VO_MAST_AZ_DEG (VO_POINTING_SPECS)
    vo_el_deg: float | None = None

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
        **PROTECTION_SPECS,
        **VO_POINTING_SPECS,
    }
    x_m: float
    y_m: float
    vo: bool | None = None  # None: off
    vo_attitude: bool | None = None
    drag_wheel: str | None = None  # None: all six wheels driven
    slip_limit_pct: float | None = None  # None: the rover's limits (PROTECTION_SPECS)
    vo_fail: str | None = None
    timeout_s: float | None = None
    lmst_limit_h: float | None = None
    vo_az_deg: float | None = None  # None: VO_MAST_AZ_DEG (VO_POINTING_SPECS)
    vo_el_deg: float | None = None

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
    """Set a NATE parameter by dotted name (``sungaze.timer_s``), or a mobility limit
    (``mobility.slip_limit``: ``estimation.protection.limits``), SI units."""

    name: ClassVar[str] = "SET_PARAM"
    specs: ClassVar[Mapping[str, ArgSpec]] = {
        "param": ArgSpec(
            "string",
            note="a NATE parameter by dotted name, e.g. sungaze.timer_s, or a mobility "
            "limit, e.g. mobility.slip_limit, or vo.rig (the width of the VO pairs: "
            f"{' or '.join(str(w) for w in VO_RIGS_PX)} px)",
        ),
        "value": ArgSpec("number_or_boolean", note="in the parameter's SI unit, or true/false"),
    }
    param: str
    value: float | bool

    def _check_rules(self) -> None:
        if not isinstance(self.param, str) or not self.param.strip():
            raise ValueError(f"param: must be a parameter name, got {shown(self.param)}")
        if self.param.startswith("mobility."):  # the ground knows every mobility limit
            try:
                check_limit(self.param.removeprefix("mobility."), self.value)
            except ValueError as exc:
                raise ValueError(f"value: {exc}") from None
        elif self.param.startswith("vo."):  # the ground knows the VO settings too
            check_vo_setting(self.param, self.value)


_ZONE_NAME = "letters, digits and _ (1-64); KEEPOUT_CLEAR zone=all clears every zone"


@dataclass(frozen=True)
class KeepoutAdd(Command):
    """Add a keep-out zone in the current Site: a circle (``x_m``, ``y_m``, ``radius_m``)
    or a polygon (``polygon_m="x1,y1 x2,y2 x3,y3"``). Drives halt before the rover's
    position, grown by ``mobility.keepout_k_sigma`` times its uncertainty, touches it."""

    name: ClassVar[str] = "KEEPOUT_ADD"
    specs: ClassVar[Mapping[str, ArgSpec]] = {
        "zone": ArgSpec("string", note=f"the zone's name: {_ZONE_NAME}"),
        "x_m": ArgSpec("number", "m", -1e4, 1e4, note="North in the Site: a circle's centre"),
        "y_m": ArgSpec("number", "m", -1e4, 1e4, note="East in the Site: a circle's centre"),
        "radius_m": ArgSpec("number", "m", 0.0, 1e3, lo_open=True, note="a circle's radius"),
        "polygon_m": ArgSpec(
            "string", note='a polygon instead: "x1,y1 x2,y2 ..." (3 to 64 corners, m)'
        ),
    }
    zone: str
    x_m: float | None = None
    y_m: float | None = None
    radius_m: float | None = None
    polygon_m: str | None = None

    def _check_rules(self) -> None:
        _check_zone_name(self.zone, allow_all=False)
        circle = (self.x_m, self.y_m, self.radius_m)
        if self.polygon_m is not None:
            if any(v is not None for v in circle):
                raise ValueError("polygon_m: give a polygon or x_m, y_m, radius_m, not both")
            if not isinstance(self.polygon_m, str):
                raise ValueError(f"polygon_m: must be text, got {shown(self.polygon_m)}")
            parse_polygon(self.polygon_m)
        elif any(v is None for v in circle):
            raise ValueError("x_m, y_m, radius_m: a circle needs all three (or polygon_m)")


@dataclass(frozen=True)
class KeepoutClear(Command):
    """Remove the keep-out zone ``zone`` (``all``: every zone)."""

    name: ClassVar[str] = "KEEPOUT_CLEAR"
    specs: ClassVar[Mapping[str, ArgSpec]] = {
        "zone": ArgSpec("string", note=f"the zone's name: {_ZONE_NAME}"),
    }
    zone: str

    def _check_rules(self) -> None:
        _check_zone_name(self.zone, allow_all=True)


@dataclass(frozen=True)
class ClearMobilityFault(Command):
    """Enable mobility again after a halt (drives are refused until then)."""

    name: ClassVar[str] = "CLEAR_MOBILITY_FAULT"


def _check_zone_name(zone: object, allow_all: bool) -> None:
    ok = isinstance(zone, str) and 0 < len(zone) <= 64 and zone.replace("_", "").isalnum()
    if not ok or (zone == "all" and not allow_all):
        raise ValueError(f"zone: {_ZONE_NAME}, got {shown(zone)}")


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
        KeepoutAdd,
        KeepoutClear,
        ClearMobilityFault,
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
