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

from estimation.sapp.nate import DriveCommand, NateMode
from estimation.sapp.wheel_odometry import DriveKind
from estimation.vo.odometry import VisualOdometry
from sequences import commands as cmd
from sim.errors import InputError
from sim.loop.context import CommandRefusedError, LoopContext
from sim.loop.vo_drive import (
    VO_MAST_AZ_RAD,
    VO_MAST_EL_RAD,
    VO_RIG,
    EstimatedPose,
    corrected_pose,
    predicted_motion,
    split_drive,
    update_text,
)

VoDrive = cmd.DriveStraight | cmd.DriveArc | cmd.TurnInPlace | cmd.DriveTo


def drive(ctx: LoopContext, command: DriveCommand, kind: str, *args: float) -> dict[str, Any]:
    """One drive primitive (``kind`` ``straight`` (distance_m,), ``arc`` (radius_m,
    angle_rad) or ``turn`` (angle_rad,)) on wheel odometry."""
    nate, sim = ctx.nate, ctx.sim
    wheel0 = sim.wheel_angle_rad_now()
    if nate.mode is not NateMode.IDLE:  # checked before the rover moves
        raise CommandRefusedError(f"mobility: refused in mode {nate.mode.value}")
    drag = command.drag_wheel  # the simulator also drags a failed motor's wheel
    if kind == "straight":  # the simulator refuses bad sizes before anything moves
        seg = sim.drive_straight(args[0], drag_wheel=drag)
    elif kind == "arc":
        seg = sim.drive_arc(args[0], args[1], drag_wheel=drag)
    else:
        seg = sim.turn_in_place(args[0], drag_wheel=drag)
    start = ctx.mission_estimate()
    nate.mobility(command, wheel_angle_rad=wheel0)
    series = ctx.step_segment(seg)
    nate.stop()
    side = ctx.side.drive(seg, kind, args, start, series, ctx.recorder.events)
    ctx.recorder.segment(seg, series, side)
    ctx.recorder.now(force=True)
    distance = float(np.sum(np.linalg.norm(np.diff(seg.truth.p_s, axis=0), axis=1)))
    return {"distance_truth_m": distance}


def move(
    ctx: LoopContext, command: DriveCommand, kind: str, args: tuple[float, ...], c: VoDrive
) -> dict[str, Any]:
    """A drive primitive, stepped with visual odometry when the command says ``vo``."""
    if c.vo:
        return drive_vo(ctx, command, kind, args, attitude=bool(c.vo_attitude))
    return drive(ctx, command, kind, *args)


def drive_vo(
    ctx: LoopContext, command: DriveCommand, kind: str, args: tuple[float, ...], attitude: bool
) -> dict[str, Any]:
    """A drive in VO steps (module docstring)."""
    nate = ctx.nate
    if nate.mode is not NateMode.IDLE:  # checked before the rover moves
        raise CommandRefusedError(f"mobility: refused in mode {nate.mode.value}")
    steps = split_drive(kind, args, ctx.vo_options)
    vo = ctx.vo
    vo.reset()
    before = ctx.estimate()
    _vo_step(ctx, vo, before, before, 0, len(steps), attitude)  # the first pair
    distance = 0.0
    updates = 0
    for i, step in enumerate(steps, start=1):
        distance += drive(ctx, command, kind, *step)["distance_truth_m"]
        after = ctx.estimate()
        updates += _vo_step(ctx, vo, before, after, i, len(steps), attitude)
        # the rover stands while VO computes: the step's outcome is known at the stand's end,
        # so its events are reported there, the stand one jump (sim.loop.frames)
        ctx.wait(cmd.VO_PROCESSING_S, report_waiting_first=False)
        ctx.recorder.now(force=True)
        before = ctx.estimate()
    vo.reset()  # the last pair's images are not needed again (and checkpoints stay small)
    return {
        "distance_truth_m": distance,
        "vo_steps": len(steps),
        "vo_updates": updates,
        "vo_failures": len(steps) - updates,
    }


def _vo_step(
    ctx: LoopContext,
    vo: VisualOdometry,
    before: EstimatedPose,
    after: EstimatedPose,
    step: int,
    steps: int,
    attitude: bool,
) -> int:
    """Take a pair and run VO on it; adopt a converged update. 1 if adopted."""
    R_pred, p_pred = predicted_motion(before, after)
    try:
        pair = ctx.sim.navcam_pair(
            VO_MAST_AZ_RAD, VO_MAST_EL_RAD, rig=VO_RIG, rover_shadow=ctx.vo_options.rover_shadow
        )
        result = vo.step(
            pair.left,
            pair.right,
            R_b0_b1_predicted=R_pred,
            p_b1_b0_predicted=p_pred,
            R_s_b0=before.R_s_b,
            mast_az_rad=VO_MAST_AZ_RAD,
            mast_el_rad=VO_MAST_EL_RAD,
        )
    except (InputError, ValueError) as exc:  # e.g. the mast looking at nothing
        vo.reset()
        _vo_failed(ctx, step)
        ctx.event(f"VO step {step}/{steps} failed: {exc}; wheel odometry kept", "vo", "warning")
        return 0
    if step == 0:
        return 0  # the first pair: nothing to compare with yet
    if not result.converged or result.motion is None:
        _vo_failed(ctx, step)
        text = f"VO step {step}/{steps} failed: {result.reason}; wheel odometry kept"
        ctx.event(text, "vo", "warning")
        return 0
    ctx.recorder.vo_failures_in_row = 0
    p_s, q_b_ll = corrected_pose(before, result.motion)
    ctx.nate.visual_odometry_update(p_s, q_b_ll if attitude else None)
    ctx.event(update_text(step, steps, p_s - after.p_s, result.n_inliers, result.n_tracked), "vo")
    return 1


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
    details: dict[str, Any] = {"turn_deg": math.degrees(turn), "distance_m": distance}
    for _ in range(2):
        if abs(turn) <= math.radians(0.5):  # close enough for the straight drive
            break
        move(
            ctx, DriveCommand(DriveKind.TURN_IN_PLACE, drag_wheel=c.drag_wheel), "turn", (turn,), c
        )
        turn, distance = _aim(ctx, x_m, y_m)
    if distance >= 0.01:
        straight = DriveCommand(DriveKind.STRAIGHT, drag_wheel=c.drag_wheel)
        out = move(ctx, straight, "straight", (distance,), c)
        details["distance_truth_m"] = out["distance_truth_m"]
    return details


def _aim(ctx: LoopContext, x_m: float, y_m: float) -> tuple[float, float]:
    """Turn (rad, > 0 clockwise) and distance (m) to the goal by the estimate."""
    nate = ctx.nate
    d_n, d_e = x_m - float(nate.p_s[0]), y_m - float(nate.p_s[1])
    x_ll = Rotation.from_quat(nate.q_b_ll).inv().apply([1.0, 0.0, 0.0])  # body x in LL
    heading = math.atan2(float(x_ll[1]), float(x_ll[0]))
    turn = (math.atan2(d_e, d_n) - heading + math.pi) % (2.0 * math.pi) - math.pi
    return turn, math.hypot(d_n, d_e)
