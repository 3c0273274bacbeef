"""The drive commands in the loop: a drive primitive with SAPP's wheel odometry, the same
in visual-odometry steps (``vo=on``, ``sim.loop.vo_drive``: a Navcam pair before the first
step and after each, SAPP's pose updated from each converged VO step), and DRIVE_TO's aim
and drive by the estimate. Each returns the command's details for its report.

A drive is refused before the rover moves when NATE is not Idle, or when the simulator
refuses its size (``sim.rover.drive``). The side estimators run through every segment
beside SAPP (``sim.loop.side``).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from estimation.protection.monitor import DriveMonitor
from estimation.sapp.nate import DriveCommand, NateMode
from estimation.sapp.wheel_odometry import DriveKind
from estimation.vo.odometry import VisualOdometry, VoMotion
from sequences import commands as cmd
from sim.errors import InputError
from sim.loop import guard
from sim.loop.context import CommandRefusedError, LoopContext
from sim.loop.rover_sim import Segment
from sim.loop.vo_drive import (
    EstimatedPose,
    corrected_pose,
    predicted_motion,
    split_drive,
    update_text,
    vo_pointing,
    vo_rig,
)

VoDrive = cmd.DriveStraight | cmd.DriveArc | cmd.TurnInPlace | cmd.DriveTo


def drive(
    ctx: LoopContext,
    command: DriveCommand,
    kind: str,
    *args: float,
    monitor: DriveMonitor | None = None,
) -> dict[str, Any]:
    """One drive primitive (``kind`` ``straight`` (distance_m,), ``arc`` (radius_m,
    angle_rad) or ``turn`` (angle_rad,)) on wheel odometry, watched by ``monitor``
    (mobility fault protection, ``sim.loop.guard``); cut at the cycle where a check trips,
    with ``details["halt"]``."""
    nate, sim = ctx.nate, ctx.sim
    if nate.mode is not NateMode.IDLE:  # checked before the rover moves
        raise CommandRefusedError(f"mobility: refused in mode {nate.mode.value}")
    if monitor is None:
        monitor = guard.begin_drive(ctx, None)
    wheel0 = sim.wheel_angle_rad_now()
    sim_before, nate_before = sim.state(), nate.state()
    seg = _primitive(ctx, kind, args, None, command.drag_wheel)  # bad sizes refused first
    start = ctx.mission_estimate()
    p_before = nate.p_s.copy()
    nate.mobility(command, wheel_angle_rad=wheel0)
    series = ctx.step_segment(seg)
    trip = guard.check_segment(ctx, monitor, seg, series, p_before)
    if trip is not None:  # the world stops where the flight software decided
        sim.load_state(sim_before)
        nate.load_state(nate_before)
        seg = _primitive(ctx, kind, args, trip.index + 1, command.drag_wheel)
        nate.mobility(command, wheel_angle_rad=wheel0)
        series = ctx.step_segment(seg)
    steps_m = guard.odometry_steps_m(p_before, series)
    recorder = ctx.recorder
    recorder.segment_sigma_m = monitor.sigma_along(steps_m)
    monitor.drove(float(np.sum(steps_m)))
    nate.stop()
    side = ctx.side.drive(seg, kind, args, start, series, recorder.events)
    recorder.segment(seg, series, side)
    recorder.segment_sigma_m = None
    details: dict[str, Any] = {}
    if trip is None:
        recorder.now(force=True)
    else:  # the halt is reported at once, in a frame of its own (the next cycle at rest)
        details["halt"] = guard.halt(ctx, trip.halt)
        ctx.report()
    distance = float(np.sum(np.linalg.norm(np.diff(seg.truth.p_s, axis=0), axis=1)))
    return {"distance_truth_m": distance, **details}


def _primitive(
    ctx: LoopContext, kind: str, args: tuple[float, ...], cut: int | None, drag: str | None
) -> Segment:
    """The simulator's primitive, cut after ``cut`` cycles, dragging ``drag`` (the
    simulator also drags a failed motor's wheel)."""
    sim = ctx.sim
    if kind == "straight":
        return sim.drive_straight(args[0], max_cycles=cut, drag_wheel=drag)
    if kind == "arc":
        return sim.drive_arc(args[0], args[1], max_cycles=cut, drag_wheel=drag)
    return sim.turn_in_place(args[0], max_cycles=cut, drag_wheel=drag)


def move(
    ctx: LoopContext,
    command: DriveCommand,
    kind: str,
    args: tuple[float, ...],
    c: VoDrive,
    monitor: DriveMonitor | None = None,
) -> dict[str, Any]:
    """A drive primitive, stepped with visual odometry when the command says ``vo``;
    ``monitor`` the drive command's (a new one for ``c`` when not given)."""
    if monitor is None:
        monitor = guard.begin_drive(ctx, c)
    if c.vo:
        return drive_vo(ctx, command, kind, args, bool(c.vo_attitude), monitor, vo_pointing(c))
    return drive(ctx, command, kind, *args, monitor=monitor)


def set_vo_rig(ctx: LoopContext, width_px: object) -> None:
    """``SET_PARAM param=vo.rig``: VO images through the rig ``width_px`` wide from now on
    (``sim.loop.vo_drive.vo_rig``), its VO made anew with the parameters for that width;
    the same rig: nothing changes. ``InputError`` naming ``vo_rig`` for another width."""
    rig = vo_rig(width_px)
    if ctx.vo.rig != rig:
        ctx.vo = ctx.make_vo(rig)


def drive_vo(
    ctx: LoopContext,
    command: DriveCommand,
    kind: str,
    args: tuple[float, ...],
    attitude: bool,
    monitor: DriveMonitor,
    pointing: tuple[float, float],
) -> dict[str, Any]:
    """A drive in VO steps (module docstring), with the slip check after each; the mast
    at ``pointing`` (``(az_rad, el_rad)``, ``sim.loop.vo_drive.vo_pointing``) for every
    pair."""
    nate = ctx.nate
    if nate.mode is not NateMode.IDLE:  # checked before the rover moves
        raise CommandRefusedError(f"mobility: refused in mode {nate.mode.value}")
    steps = split_drive(kind, args, ctx.vo_options)
    vo = ctx.vo
    vo.reset()
    before = ctx.estimate()
    _vo_step(ctx, vo, before, before, (0, len(steps)), attitude, pointing)  # the first pair
    distance = 0.0
    updates = 0
    halted: dict[str, Any] | None = None
    for i, step in enumerate(steps, start=1):
        sigma_at_pair = ctx.protection.uncertainty.sigma_m
        out = drive(ctx, command, kind, *step, monitor=monitor)
        distance += out["distance_truth_m"]
        if "halt" in out:
            halted = out["halt"]
            break
        after = ctx.estimate()
        motion = _vo_step(ctx, vo, before, after, (i, len(steps)), attitude, pointing)
        vo_s = None
        if motion is not None:
            updates += 1
            ctx.protection.uncertainty.vo_update(sigma_at_pair, motion.covariance)
            vo_s = ctx.nate.p_s.copy()
        found = guard.vo_step_halt(
            ctx, monitor, _commanded_m(kind, step), before.p_s, after.p_s, vo_s
        )
        if found is not None:
            halted = guard.halt(ctx, found)
        # the rover stands while VO computes: the step's outcome is known at the stand's end,
        # so its events are reported there, the stand one jump (sim.loop.frames)
        ctx.wait(cmd.VO_PROCESSING_S, report_waiting_first=False)
        ctx.recorder.now(force=True)
        if halted is not None:
            break
        before = ctx.estimate()
    vo.reset()  # the last pair's images are not needed again (and checkpoints stay small)
    details: dict[str, Any] = {
        "distance_truth_m": distance,
        "vo_steps": len(steps),
        "vo_updates": updates,
        "vo_failures": len(steps) - updates,
    }
    if halted is not None:
        details["halt"] = halted
    return details


def _commanded_m(kind: str, step: tuple[float, ...]) -> float:
    """The motion a step commands along its path, m (a turn in place: none)."""
    if kind == "straight":
        return abs(step[0])
    if kind == "arc":
        return abs(step[0] * step[1])
    return 0.0


def _vo_step(
    ctx: LoopContext,
    vo: VisualOdometry,
    before: EstimatedPose,
    after: EstimatedPose,
    step_of: tuple[int, int],
    attitude: bool,
    pointing: tuple[float, float],
) -> VoMotion | None:
    """Take a pair (step ``step_of[0]`` of ``step_of[1]``) through VO's rig with the mast at
    ``pointing`` and run VO on it; adopt a converged update, and return its motion."""
    step, steps = step_of
    az_rad, el_rad = pointing  # commanded: the mast's bias is the simulator's, unknown to VO
    R_pred, p_pred = predicted_motion(before, after)
    try:
        pair = ctx.sim.navcam_pair(
            az_rad, el_rad, rig=vo.rig, rover_shadow=ctx.vo_options.rover_shadow
        )
        result = vo.step(
            pair.left,
            pair.right,
            R_b0_b1_predicted=R_pred,
            p_b1_b0_predicted=p_pred,
            R_s_b0=before.R_s_b,
            mast_az_rad=az_rad,
            mast_el_rad=el_rad,
        )
    except (InputError, ValueError) as exc:  # e.g. the mast looking at nothing
        vo.reset()
        _vo_failed(ctx, step)
        ctx.event(f"VO step {step}/{steps} failed: {exc}; wheel odometry kept", "vo", "warning")
        return None
    if step == 0:
        return None  # the first pair: nothing to compare with yet
    if not result.converged or result.motion is None:
        _vo_failed(ctx, step)
        text = f"VO step {step}/{steps} failed: {result.reason}; wheel odometry kept"
        ctx.event(text, "vo", "warning")
        return None
    ctx.recorder.vo_failures_in_row = 0
    p_s, q_b_ll = corrected_pose(before, result.motion)
    ctx.nate.visual_odometry_update(p_s, q_b_ll if attitude else None)
    ctx.event(update_text(step, steps, p_s - after.p_s, result.n_inliers, result.n_tracked), "vo")
    return result.motion


def _vo_failed(ctx: LoopContext, step: int) -> None:
    """Count a failed VO step (the first pair of a drive is not a step)."""
    if step > 0:
        ctx.recorder.vo_failures_in_row += 1


def drive_to(ctx: LoopContext, c: cmd.DriveTo) -> dict[str, Any]:
    """DRIVE_TO: turn towards the goal and drive to it, both by NATE's estimate. A turn in
    place slips and creeps, so the aim is taken again after it (twice at most) before the
    straight drive."""
    x_m, y_m = c.x_m, c.y_m
    if ctx.nate.mode is not NateMode.IDLE:
        raise CommandRefusedError(f"DRIVE_TO: refused in mode {ctx.nate.mode.value}")
    turn, distance = _aim(ctx, x_m, y_m)
    if not 0.01 <= distance <= cmd.MAX_DRIVE_M:
        raise CommandRefusedError(
            f"DRIVE_TO: the goal is {distance:.2f} m from the estimated position "
            f"(0.01-{cmd.MAX_DRIVE_M:g} m)"
        )
    monitor = guard.begin_drive(ctx, c)
    details: dict[str, Any] = {"turn_deg": math.degrees(turn), "distance_m": distance}
    for _ in range(2):
        if abs(turn) <= math.radians(0.5):  # close enough for the straight drive
            break
        turn_command = DriveCommand(DriveKind.TURN_IN_PLACE, drag_wheel=c.drag_wheel)
        out = move(ctx, turn_command, "turn", (turn,), c, monitor)
        if "halt" in out:
            return {**details, "halt": out["halt"]}
        turn, distance = _aim(ctx, x_m, y_m)
    if distance >= 0.01:
        straight = DriveCommand(DriveKind.STRAIGHT, drag_wheel=c.drag_wheel)
        out = move(ctx, straight, "straight", (distance,), c, monitor)
        details["distance_truth_m"] = out["distance_truth_m"]
        if "halt" in out:
            details["halt"] = out["halt"]
    return details


def _aim(ctx: LoopContext, x_m: float, y_m: float) -> tuple[float, float]:
    """Turn (rad, > 0 clockwise) and distance (m) to the goal by the estimate."""
    nate = ctx.nate
    d_n, d_e = x_m - float(nate.p_s[0]), y_m - float(nate.p_s[1])
    x_ll = Rotation.from_quat(nate.q_b_ll).inv().apply([1.0, 0.0, 0.0])  # body x in LL
    heading = math.atan2(float(x_ll[1]), float(x_ll[0]))
    turn = (math.atan2(d_e, d_n) - heading + math.pi) % (2.0 * math.pi) - math.pi
    return turn, math.hypot(d_n, d_e)
