"""Sequence validation: every error at once, and warnings about risky but legal plans.

``validate(source, context)`` parses the source (``sequences.language``: syntax, commands,
arguments, time tags) and then checks what spans lines: time tags going backwards and the
Articulate state (NATE accepts only ARTICULATE_STOP, WAIT and HGA_PASS while
articulating; Ali et al. 2005, sec. 2.4.1, as ``estimation.sapp.nate`` implements it).

With a ``ValidationContext`` (the rover's clock and state at the start, which the server fills
from ``sim``) it also walks the sequence predicting when each command starts and what SAPP's
Attitude Quality Flag (Ali et al. 2005 sec. 2.1) and IMU integration time (sec. 4) will be, and
warns where the plan is risky. The predictions are estimates, made without the simulator:

- Durations (one row per command in ``_DURATION_S``): drives at 0.0375 m/s along the path
  and turns at 2.1 deg/s (Ali et al. 2005 sec. 2.4.2 and 2.5, ``estimation.geometry``);
  NADIR_UPDATE/NADIR_CHECK their window (10 s by default); SUNFIND 5 min (its upper bound);
  SUNCHECK 1 min; SUNGAZE 10 min (its timer); GET_TILT_ATTITUDE 10 s; GET_COARSE_ATTITUDE
  10 s + 5 min; GET_FINE_ATTITUDE 15 min; SUNCHECK_SUNGAZE 11 min; GYROCOMPASS, HGA_PASS
  and WAIT their duration; the others take no time.
- Every acquisition succeeds: NADIR_UPDATE/GET_TILT_ATTITUDE give TiltOnly, SUNFIND/
  GET_COARSE_ATTITUDE and GYROCOMPASS give Coarse, SUNGAZE/GET_FINE_ATTITUDE/
  SUNCHECK_SUNGAZE give Fine and reset the IMU time; checks leave the flag alone.
- Drives and the time spent in Articulate add their duration to the IMU time (and the gyro
  counter, which is the same away from the wheel-odometry submode); Fine drops to Coarse
  once that exceeds ``fine_to_coarse_s`` (900 s, Ali et al. 2005 sec. 2.4; SET_PARAM may change it).
- ``@ hh:mm LMST`` waits for the next time the LMST clock reads that; a passed
  ``@ sol N hh:mm LMST`` is assumed to start at once, late.
- The commands that image the sun (SUNFIND, SUNGAZE, SUNCHECK, GET_COARSE_ATTITUDE,
  GET_FINE_ATTITUDE, SUNCHECK_SUNGAZE) are refused by NATE when the sun is lower than its
  ``min_sun_elevation_rad`` as the command starts (the camera modes' sanity check). With
  the context's ``sun_elevation_deg`` and ``min_sun_elevation_deg`` (the rover's own
  parameter, which ``server.validation.context`` reads from the rover's NATE) the walk
  warns (``sun-too-low``), and follows a
  ``SET_PARAM param=min_sun_elevation_rad``.
- SUNCHECK_SUNGAZE is meant for an AQF of Coarse or better (Ali et al. 2005 sec. 4: the
  propagated attitude points the camera at the sun): below that it warns
  (``suncheck-not-coarse``); NATE runs it anyway (``estimation.sapp.nate``).

>>> result = validate("DRIVE_STRAIGHT distance_m=0\\nWAIT duration=5")
>>> [(d.line, d.code) for d in result.errors]
[(1, 'bad-value'), (2, 'missing-argument'), (2, 'unknown-argument')]
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, Literal

from estimation.geometry import DRIVE_SPEED_M_S, TURN_RATE_DEG_S
from estimation.protection.keepout import KeepOutZone
from estimation.protection.limits import MobilityLimits
from estimation.sapp.nadir import NadirParams
from estimation.sapp.nate_io import FINE_TO_COARSE_S, NateParams
from estimation.sapp.sun_modes import SungazeParams
from sequences import commands as cmd
from sequences.comm_timing import CommTiming, CommWalk
from sequences.drive_safety import DriveSafety
from sequences.imaging import NAVCAM_STEREO_S, NavcamStereo
from sequences.language import (
    Diagnostic,
    Sequence,
    SequenceStep,
    TimeTag,
    parse_any,
)
from sequences.terrain_grid import TerrainGrid

__all__ = [
    "CODES",
    "MAX_EPHEMERIS_SOL",
    "Diagnostic",
    "ValidationContext",
    "ValidationResult",
    "estimate_duration_s",
    "validate",
]

MAX_DIAGNOSTICS = 1000  # of each severity in one result (``_capped``)

CODES: dict[str, str] = {
    # from the parser (sequences.language)
    "syntax": "error",
    "unknown-command": "error",
    "unknown-argument": "error",
    "missing-argument": "error",
    "duplicate-argument": "error",
    "bad-value": "error",
    "bad-time-tag": "error",
    "missing-command": "error",
    "sequence-not-first": "error",
    "bad-name": "error",
    "empty": "error",
    "too-many": "error",  # or a warning: the severity of what it counts
    "bad-json": "error",
    "bad-structure": "error",
    "bad-character": "error",
    # from this module
    "beyond-ephemeris": "error",
    "time-backwards": "error",
    "refused-in-articulate": "error",
    "not-articulating": "error",
    "articulate-open": "warning",
    "drive-not-fine": "warning",
    "fine-expires": "warning",
    "earth-below-horizon": "warning",
    "sun-too-low": "warning",
    "suncheck-not-coarse": "warning",
    "hga-not-fine": "warning",
    "imu-time": "warning",
    "tag-next-sol": "warning",
    "tag-passed": "warning",
    # from sequences.drive_safety
    "keepout-crossing": "warning",
    "drive-after-halt": "warning",
    "drive-timeout": "warning",
    "lmst-limit": "warning",
    # from sequences.terrain_check (a drive's nominal path on the ground's terrain map)
    "tilt-limit": "warning",
    "tilt-near-limit": "warning",
    # from sequences.comm_timing (a rover whose link crosses the light time)
    "before-onboard": "warning",
    "no-uplink": "warning",
    "restricted-sol": "warning",
}
"""Every diagnostic code and its severity; docs/sequences.md explains each."""

AqfName = Literal["Unknown", "TiltOnly", "Coarse", "Fine"]
AQF_RANK: dict[str, int] = {"Unknown": 0, "TiltOnly": 1, "Coarse": 2, "Fine": 3}

# The flight software's numbers, read from it (the ground learns them from the rover):
# drive rates (Ali et al. 2005 sec. 2.5, 2.4.2), NATE's Nadir window (sec. 2.2.1), the
# Sungaze timer (sec. 2.2.3), the gyrocompass span and Fine's 15 minutes (sec. 2.4).
NADIR_WINDOW_S = NadirParams().window_s
SUNGAZE_S = SungazeParams().timer_s
GYROCOMPASS_S = NateParams().gyrocompass_duration_s
# The ground's own estimates and the operators' limit.
SUNFIND_S = 300.0  # upper bound of a Sunfind search (estimate)
SUNCHECK_S = 60.0  # one pointed image (estimate)
GET_FINE_ATTITUDE_S = 900.0  # estimate: Nadir Update, Sunfind, Sungaze
SUNCHECK_SUNGAZE_S = 660.0  # estimate: Suncheck then Sungaze
IMU_TIME_LIMIT_S = 10_000.0  # Ali et al. 2005 sec. 4: the operators' limit since the last Sungaze
_EPS_S = 1e-6
MAX_EPHEMERIS_SOL = 17_668
"""The last sol whose every LMST lies inside the ephemeris the rover runs on (the bundled
DE421, which ends 2053-10-08, less the simulator's spare day) for both missions:
Opportunity's, since it landed 21 days after Spirit (whose last sol is 17,689). Without a
rover context a ``@ sol N`` tag beyond it is an error (``beyond-ephemeris``): the rover
would refuse it. ``sequences`` may not import ``sim``, so this is a constant;
tests/server/validation/test_validation_context.py ties it to the ephemeris and both
missions' clocks."""

_DRIVES = (cmd.DriveStraight, cmd.DriveArc, cmd.TurnInPlace, cmd.DriveTo)


def _fixed(duration_s: float) -> Callable[[Any, float], float]:
    return lambda _c, _gyrocompass_s: duration_s


# One row per command of the dictionary: its expected duration, s, from the command and the
# gyrocompass span in force (the module docstring's estimates).
_DURATION_S: dict[type[cmd.Command], Callable[[Any, float], float]] = {
    cmd.DriveStraight: lambda c, _g: sum(_drive_times_s(c)),
    cmd.DriveArc: lambda c, _g: sum(_drive_times_s(c)),
    cmd.TurnInPlace: lambda c, _g: sum(_drive_times_s(c)),
    cmd.DriveTo: lambda c, _g: sum(_drive_times_s(c)),
    cmd.PlantSite: _fixed(0.0),
    cmd.NadirUpdate: lambda c, _g: NADIR_WINDOW_S if c.window_s is None else float(c.window_s),
    cmd.NadirCheck: lambda c, _g: NADIR_WINDOW_S if c.window_s is None else float(c.window_s),
    cmd.Sunfind: _fixed(SUNFIND_S),
    cmd.Suncheck: _fixed(SUNCHECK_S),
    cmd.Sungaze: _fixed(SUNGAZE_S),
    cmd.GetTiltAttitude: _fixed(NADIR_WINDOW_S),
    cmd.GetCoarseAttitude: _fixed(NADIR_WINDOW_S + SUNFIND_S),
    cmd.GetFineAttitude: _fixed(GET_FINE_ATTITUDE_S),
    cmd.SuncheckSungaze: _fixed(SUNCHECK_SUNGAZE_S),
    cmd.Gyrocompass: lambda c, g: g if c.duration_s is None else float(c.duration_s),
    cmd.ArticulateStart: _fixed(0.0),
    cmd.ArticulateStop: _fixed(0.0),
    cmd.HgaPass: lambda c, _g: float(c.duration_min) * 60.0,
    cmd.Wait: lambda c, _g: float(c.duration_s),
    cmd.SetParam: _fixed(0.0),
    cmd.KeepoutAdd: _fixed(0.0),
    cmd.KeepoutClear: _fixed(0.0),
    cmd.ClearMobilityFault: _fixed(0.0),
    NavcamStereo: _fixed(NAVCAM_STEREO_S),
}


@dataclass(frozen=True)
class ValidationContext:
    """The rover at the start of the sequence, for the predicting warnings.

    ``start_t_s``: when the sequence starts (TT seconds since J2000, docs/CONVENTIONS.md);
    ``lmst_h(t_s)`` and ``sol(t_s)`` the rover's clock; ``t_s_for(sol, lmst_h)`` its inverse;
    ``earth_elevation_deg(t_s)`` Earth above the rover's horizon. ``aqf`` the flag and
    ``imu_integration_s`` the IMU time since the last Sungaze at the start; ``articulating``
    whether NATE is in Articulate then (without a context: Idle). ``ephemeris_end_t_s``: the
    last instant the rover's ephemeris covers; a step predicted to run past it is an error
    and nothing after it is predicted (the elevation functions are never asked beyond it).
    ``sun_elevation_deg(t_s)``: the sun above the horizon, when the context has it;
    ``min_sun_elevation_deg`` the lowest sun NATE's camera modes accept (the rover's
    ``min_sun_elevation_rad``), when known: with both, the walk warns ``sun-too-low``.
    ``p_s_est`` (North, East, m in Site ``site_index``) and ``heading_rad`` the rover's
    reported estimate, ``position_sigma_m`` its reported uncertainty, ``keepout_zones`` the
    zones it reports holding and ``mobility_fault`` the halt that disabled its mobility, if
    one did, ``mobility_limits`` the mobility limits it reports holding (``None``: the flight
    defaults), ``terrain`` the ground's terrain map around it (``None``: no map, no tilt
    check): the drives' checks (``sequences.drive_safety``, ``sequences.terrain_check``).
    ``comm``: the rover's link when it crosses the light time (``None``: instant, the
    sequence onboard at ``start_t_s``): the walk then starts when the sequence is onboard,
    and warns about tags before that and drives whose results miss the planning time
    (``sequences.comm_timing``).
    """

    start_t_s: float
    lmst_h: Callable[[float], float]
    sol: Callable[[float], int]
    t_s_for: Callable[[int, float], float]
    earth_elevation_deg: Callable[[float], float]
    aqf: AqfName = "Unknown"
    imu_integration_s: float = 0.0
    articulating: bool = False
    ephemeris_end_t_s: float = math.inf
    sun_elevation_deg: Callable[[float], float] | None = None
    min_sun_elevation_deg: float | None = None
    p_s_est: tuple[float, float] | None = None
    heading_rad: float | None = None
    site_index: int = 0
    position_sigma_m: float = 0.0
    keepout_zones: tuple[KeepOutZone, ...] = ()
    mobility_fault: str | None = None
    comm: CommTiming | None = None
    mobility_limits: MobilityLimits | None = None
    terrain: TerrainGrid | None = None

    def __post_init__(self) -> None:
        if self.aqf not in AQF_RANK:
            raise ValueError(f"aqf: must be one of {', '.join(AQF_RANK)}, got {self.aqf!r}")
        if not (math.isfinite(self.start_t_s) and math.isfinite(self.imu_integration_s)):
            raise ValueError("start_t_s, imu_integration_s: must be finite")
        if math.isnan(self.ephemeris_end_t_s):
            raise ValueError("ephemeris_end_t_s: must be a time or inf, got nan")

    def clock(self, t_s: float) -> str:
        """``sol N hh:mm LMST`` at ``t_s``, for messages."""
        lmst = self.lmst_h(t_s) % 24.0
        minutes = int(lmst * 60.0 + 0.5) % 1440
        return f"sol {self.sol(t_s)} {minutes // 60:02d}:{minutes % 60:02d} LMST"


@dataclass
class ValidationResult:
    """``errors`` and ``warnings`` in source order; ``sequence`` when there are no errors."""

    errors: list[Diagnostic] = field(default_factory=list)
    warnings: list[Diagnostic] = field(default_factory=list)
    sequence: Sequence | None = None

    @property
    def ok(self) -> bool:
        """True when there is no error (warnings allowed)."""
        return not self.errors

    def as_dict(self) -> dict[str, Any]:
        """A JSON-ready summary (what the CLI's ``--json`` prints)."""
        return {
            "ok": self.ok,
            "errors": [d.as_dict() for d in self.errors],
            "warnings": [d.as_dict() for d in self.warnings],
        }


def validate(
    source: str | Mapping[str, Any] | list[Any], context: ValidationContext | None = None
) -> ValidationResult:
    """Check a text or JSON sequence; every error at once, warnings only with ``context``."""
    parsed = parse_any(source)
    result = ValidationResult(errors=list(parsed.diagnostics))
    sequence = parsed.sequence
    _check_time_order(sequence, result)
    _check_articulate(sequence, context, result)
    if context is None:
        _check_ephemeris_sols(sequence, result)
    elif sequence.steps:
        _Prediction(context, result, sequence).walk(sequence.steps)
    result.errors.sort(key=_order)  # stable: JSON diagnostics (all at 0:0) keep step order
    result.warnings.sort(key=_order)
    result.errors = _capped(result.errors, "error")
    result.warnings = _capped(result.warnings, "warning")
    if result.ok:
        result.sequence = sequence
    return result


def _capped(found: list[Diagnostic], severity: Literal["error", "warning"]) -> list[Diagnostic]:
    """The first ``MAX_DIAGNOSTICS`` of ``found`` and, if there were more, one more saying
    how many were left out, where the first of them is: one hostile megabyte
    (``x x x ...``) would otherwise answer with half a million diagnostics.

    >>> many = [Diagnostic(i, 1, "error", "syntax", "x") for i in range(1, 1003)]
    >>> capped = _capped(many, "error")
    >>> len(capped), capped[-1].line, capped[-1].message
    (1001, 1001, '2 more errors not listed (the first 1000 are)')
    """
    if len(found) <= MAX_DIAGNOSTICS:
        return found
    left_out = found[MAX_DIAGNOSTICS]
    more = len(found) - MAX_DIAGNOSTICS
    text = f"{more} more {severity}s not listed (the first {MAX_DIAGNOSTICS} are)"
    if left_out.line == 0:  # a JSON problem: its location starts its message (steps[3]...)
        text = f"{left_out.message.split(':', 1)[0]}: {text}"
    summary = Diagnostic(left_out.line, left_out.column, severity, "too-many", text)
    return [*found[:MAX_DIAGNOSTICS], summary]


def _order(d: Diagnostic) -> tuple[int, int]:
    return (d.line, d.column)


def _diag(
    step: SequenceStep, severity: Literal["error", "warning"], code: str, text: str
) -> Diagnostic:
    """A diagnostic about ``step``: at its time tag for the time codes, else its keyword; a
    JSON step's location (``steps[3].time: ``) starts the message."""
    tagged = code.startswith(("time", "tag", "before-onboard")) or (
        code == "beyond-ephemeris" and step.time_tag.kind == "sol_lmst"
    )
    column = step.tag_column if tagged and step.tag_column else step.column
    prefix = f"{step.where}{'.time' if tagged else ''}: " if step.where else ""
    return Diagnostic(step.line, column, severity, code, prefix + text)


def _check_time_order(sequence: Sequence, result: ValidationResult) -> None:
    """An absolute tag earlier than the one before it is an error: ``@ 10:00 LMST`` after
    ``@ 13:00 LMST`` would silently wait for the next sol (write ``@ sol N``), and a
    ``@ sol N`` tag earlier than the previous one can never be met. A sol tag after a bare
    LMST tag cannot be compared without the rover's clock."""
    last: tuple[TimeTag, SequenceStep] | None = None
    for step in sequence.steps:
        tag = step.time_tag
        if not tag.absolute:
            continue
        if last is not None:
            prev, prev_step = last
            where = f"line {prev_step.line}" if prev_step.line else prev_step.where
            before = f"{_tag_words(tag)} is earlier than {_tag_words(prev)} ({where})"
            if tag.kind == "lmst" and (tag.lmst_s or 0) < (prev.lmst_s or 0):
                text = f"{before}: it would wait for the next sol; use @ sol N hh:mm LMST"
                result.errors.append(_diag(step, "error", "time-backwards", text))
            elif (
                tag.kind == "sol_lmst"
                and prev.kind == "sol_lmst"
                and (tag.sol or 0, tag.lmst_s or 0) < (prev.sol or 0, prev.lmst_s or 0)
            ):
                result.errors.append(_diag(step, "error", "time-backwards", before))
        last = (tag, step)


def _check_ephemeris_sols(sequence: Sequence, result: ValidationResult) -> None:
    """Without a rover context: a ``@ sol N`` tag past ``MAX_EPHEMERIS_SOL`` is refused."""
    for step in sequence.steps:
        sol = step.time_tag.sol
        if step.time_tag.kind == "sol_lmst" and sol is not None and sol > MAX_EPHEMERIS_SOL:
            text = (
                f"sol {sol} is beyond the rover's ephemeris (DE421, to 2053-10-08): "
                f"sol {MAX_EPHEMERIS_SOL} is the last one both missions reach"
            )
            result.errors.append(_diag(step, "error", "beyond-ephemeris", text))


def _tag_words(tag: TimeTag) -> str:
    sol = f"sol {tag.sol} " if tag.kind == "sol_lmst" else ""
    return f"{sol}{tag.clock()} LMST"


def _check_articulate(
    sequence: Sequence, context: ValidationContext | None, result: ValidationResult
) -> None:
    """NATE refuses most commands in Articulate and ARTICULATE_STOP outside it
    (``estimation.sapp.nate``: commands are accepted in Idle only, ``stop`` in Articulate)."""
    articulating = context.articulating if context is not None else False
    opened: SequenceStep | None = None
    for step in sequence.steps:
        c = step.command
        if articulating and not c.in_articulate:
            where = f" (ARTICULATE_START on line {opened.line})" if opened and opened.line else ""
            text = f"{c.name} is refused in Articulate{where}: ARTICULATE_STOP first"
            result.errors.append(_diag(step, "error", "refused-in-articulate", text))
        elif isinstance(c, cmd.ArticulateStop) and not articulating:
            text = "ARTICULATE_STOP without ARTICULATE_START: NATE refuses it in Idle"
            result.errors.append(_diag(step, "error", "not-articulating", text))
        if isinstance(c, cmd.ArticulateStart) and not articulating:
            articulating, opened = True, step
        elif isinstance(c, cmd.ArticulateStop):
            articulating = False
    if articulating and opened is not None:
        text = "the sequence ends in Articulate: the next sequence's commands will be refused"
        result.warnings.append(_diag(opened, "warning", "articulate-open", text))


def estimate_duration_s(command: cmd.Command, gyrocompass_s: float = GYROCOMPASS_S) -> float:
    """How long ``command`` is expected to take, s (the module docstring's estimates).

    >>> estimate_duration_s(cmd.DriveStraight(distance_m=3.75))
    100.0
    >>> estimate_duration_s(cmd.HgaPass(duration_min=15))
    900.0
    """
    return _DURATION_S[type(command)](command, gyrocompass_s)


def _drive_times_s(
    c: cmd.DriveStraight | cmd.DriveArc | cmd.TurnInPlace | cmd.DriveTo,
) -> tuple[float, float]:
    """A drive's time moving, and its time standing: ``VO_PROCESSING_S`` per visual
    odometry step with ``vo=on`` (NATE is Idle then: no propagation, no gyro counter).

    >>> _drive_times_s(cmd.DriveStraight(distance_m=1.5, vo=True))  # 40 s + 2 steps
    (40.0, 300.0)
    """
    steps = 0
    if isinstance(c, cmd.DriveStraight):
        moving_s = float(c.distance_m) / DRIVE_SPEED_M_S
        steps = cmd.vo_step_count(c.distance_m, 0.0)
    elif isinstance(c, cmd.DriveArc):
        length = abs(float(c.radius_m)) * math.radians(c.angle_deg)
        moving_s = length / DRIVE_SPEED_M_S
        steps = cmd.vo_step_count(length, c.angle_deg)
    elif isinstance(c, cmd.TurnInPlace):
        moving_s = abs(float(c.angle_deg)) / TURN_RATE_DEG_S
        steps = cmd.vo_step_count(0.0, c.angle_deg)
    else:  # DRIVE_TO: the position is not predicted: as if from the origin, after a half
        # turn (the longest turn it can need)
        distance = math.hypot(c.x_m, c.y_m)
        moving_s = distance / DRIVE_SPEED_M_S + 180.0 / TURN_RATE_DEG_S
        steps = cmd.vo_step_count(distance, 0.0) + cmd.vo_step_count(0.0, 180.0)
    return moving_s, (steps * cmd.VO_PROCESSING_S if c.vo else 0.0)


class _Prediction:
    """The walk of the module docstring: start times, AQF and IMU time per command."""

    def __init__(
        self, context: ValidationContext, result: ValidationResult, sequence: Sequence
    ) -> None:
        self.ctx, self.result = context, result
        self.comm: CommWalk | None = None
        if context.comm is not None:
            self.comm = CommWalk.start(self.warn, context, context.comm, sequence)
        self.t_s = context.start_t_s if self.comm is None else self.comm.start_t_s
        self.aqf: str = context.aqf
        self.imu_s = context.imu_integration_s
        self.articulating = context.articulating
        self.fine_to_coarse_s = FINE_TO_COARSE_S
        self.gyrocompass_s = GYROCOMPASS_S
        self.imu_warned = False
        self.min_sun_elevation_deg = context.min_sun_elevation_deg
        self.safety = DriveSafety.start(self.warn, context)

    def warn(self, step: SequenceStep, code: str, text: str) -> None:
        self.result.warnings.append(_diag(step, "warning", code, text))

    def walk(self, steps: tuple[SequenceStep, ...]) -> None:
        for i, step in enumerate(steps):
            start = self.start_of(step, i)
            duration = estimate_duration_s(step.command, self.gyrocompass_s)
            if start + duration > self.ctx.ephemeris_end_t_s:
                self.beyond_ephemeris(step, start, duration)
                return  # nothing past the ephemeris can be predicted
            self.check_start(step, start, duration)
            self.safety.step(step, start, duration)
            if self.comm is not None:
                self.comm.step(step, start, duration)
            self.advance(step, duration)
            self.t_s = start + duration

    def start_of(self, step: SequenceStep, i: int) -> float:
        tag, ctx, now = step.time_tag, self.ctx, self.t_s
        if tag.kind == "relative":
            return now + (tag.after_s or 0.0)
        if not tag.absolute:
            return now
        lmst_h = tag.lmst_h or 0.0
        if tag.kind == "sol_lmst":
            at = ctx.t_s_for(tag.sol or 0, lmst_h)
            if at < now - _EPS_S:
                if self.comm is None or not self.comm.before_onboard(step, at, now):
                    late = ctx.clock(now)
                    text = f"{_tag_words(tag)} has passed when it comes up ({late}): it starts late"
                    self.warn(step, "tag-passed", text)
                return now
            return at
        sol = ctx.sol(now)
        at = ctx.t_s_for(sol, lmst_h)
        passed = at < now - _EPS_S
        if passed:
            sol += 1
            at = ctx.t_s_for(sol, lmst_h)
        if self.comm is not None and self.comm.before_onboard(  # the reading before it
            step, ctx.t_s_for(sol - 1, lmst_h), at, since_t_s=ctx.start_t_s
        ):
            return at
        if passed and i > 0:
            text = (
                f"the commands before end at {ctx.clock(now)}, after {tag.clock()} LMST: "
                f"this one waits until sol {sol}"
            )
            self.warn(step, "tag-next-sol", text)
        return at

    def beyond_ephemeris(self, step: SequenceStep, start: float, duration: float) -> None:
        ctx, end = self.ctx, self.ctx.ephemeris_end_t_s
        when = f"starts at {ctx.clock(start)}" if start > end else "would run"
        text = (
            f"{step.command.name} {when} past the end of the rover's ephemeris "
            f"({ctx.clock(end)}): the rover cannot run it"
        )
        self.result.errors.append(_diag(step, "error", "beyond-ephemeris", text))

    def check_start(self, step: SequenceStep, start: float, duration: float) -> None:
        c, ctx = step.command, self.ctx
        if isinstance(c, _DRIVES) and self.aqf != "Fine":
            text = f"{c.name} with the AQF predicted {self.aqf}, not Fine: a Sungaze first?"
            self.warn(step, "drive-not-fine", text)
        if isinstance(c, cmd.HgaPass):
            elev = ctx.earth_elevation_deg(start)
            end_elev = ctx.earth_elevation_deg(start + duration)
            if elev < 0.0:
                text = f"Earth is {elev:.1f} deg below the horizon at {ctx.clock(start)}"
                self.warn(step, "earth-below-horizon", text)
            elif end_elev < 0.0:
                text = f"Earth sets before the pass ends ({ctx.clock(start + duration)})"
                self.warn(step, "earth-below-horizon", text)
            if self.aqf != "Fine":
                text = f"HGA pass with the AQF predicted {self.aqf}: pointing not assured"
                self.warn(step, "hga-not-fine", text)
        if isinstance(c, cmd.SuncheckSungaze) and AQF_RANK[self.aqf] < AQF_RANK["Coarse"]:
            text = (
                f"SUNCHECK_SUNGAZE with the AQF predicted {self.aqf}: it is meant for Coarse "
                "or better, or the Suncheck may not see the sun (Ali et al. 2005 sec. 4); "
                "GET_FINE_ATTITUDE?"
            )
            self.warn(step, "suncheck-not-coarse", text)
        limit = self.min_sun_elevation_deg
        if c.images_sun and ctx.sun_elevation_deg is not None and limit is not None:
            sun = ctx.sun_elevation_deg(start)
            if sun < limit:
                text = (
                    f"the sun is {sun:.1f} deg high at {ctx.clock(start)}, below the "
                    f"{limit:.1f} deg NATE needs (min_sun_elevation_rad): "
                    f"{c.name} would be refused"
                )
                self.warn(step, "sun-too-low", text)

    def advance(self, step: SequenceStep, duration: float) -> None:
        c = step.command
        after = c.aqf_after
        if after == "Fine":
            self.aqf, self.imu_s, self.imu_warned = "Fine", 0.0, False
        elif after is not None:
            self.aqf = after
        propagating = self.articulating or isinstance(c, _DRIVES)
        if isinstance(c, _DRIVES) and not self.articulating:
            duration = _drive_times_s(c)[0]  # a VO drive's standing time does not propagate
        if propagating and duration > 0.0:
            before = self.imu_s
            self.imu_s += duration
            if self.aqf == "Fine" and self.imu_s > self.fine_to_coarse_s:
                self.aqf = "Coarse"
                if isinstance(c, _DRIVES) and before < self.fine_to_coarse_s:
                    text = (
                        f"the AQF drops from Fine to Coarse {self.fine_to_coarse_s - before:.0f} s "
                        f"into this command's {duration:.0f} s of driving "
                        f"({self.fine_to_coarse_s:g} s of propagation since the last Sungaze)"
                    )
                    self.warn(step, "fine-expires", text)
        if self.imu_s > IMU_TIME_LIMIT_S and not self.imu_warned:
            self.imu_warned = True
            text = (
                f"IMU integration time since the last Sungaze reaches {self.imu_s:.0f} s "
                f"(more than {IMU_TIME_LIMIT_S:.0f} s): plan a Sungaze"
            )
            self.warn(step, "imu-time", text)
        if isinstance(c, cmd.ArticulateStart):
            self.articulating = True
        elif isinstance(c, cmd.ArticulateStop):
            self.articulating = False
        elif isinstance(c, cmd.SetParam) and not isinstance(c.value, bool):
            if c.param == "fine_to_coarse_s":
                self.fine_to_coarse_s = float(c.value)
            elif c.param == "gyrocompass_duration_s":
                self.gyrocompass_s = float(c.value)
            elif c.param == "min_sun_elevation_rad":
                self.min_sun_elevation_deg = math.degrees(float(c.value))
