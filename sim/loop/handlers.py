"""One handler per command type: what the session does with each command of the dictionary
(``sequences.commands.COMMANDS``), from one table, ``HANDLERS``.

A handler takes the loop (``sim.loop.context.LoopContext``) and its command, runs it to
completion and returns the details for its report (``"failure"``: the mode ran and failed,
with the reason). It refuses, with nothing changed, by raising ``CommandRefusedError``,
``ValueError`` or ``InputError`` (NATE refuses a wrong mode, an out-of-range parameter, the
sun too low; the simulator a drive outside its limits). Adding a command: its class in
``sequences.commands`` and its handler here, in ``HANDLERS``.

The HGA figures of an HGA pass are those of its frames' truth records (``sim.scoring``): the
pass fails when its worst true error leaves no margin. That is the world's outcome (the
link closes or it does not, and the ground sees the signal go), not the rover's knowledge; its
figures are a score, an event of the truth record.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any

from estimation.events import Event, Severity, parameter_text
from estimation.ivp import earth_ll
from estimation.protection.keepout import (
    KeepOutZone,
    parse_polygon,
    zone_added_text,
    zones_cleared_text,
)
from estimation.sapp.aqf import AttitudeQuality
from estimation.sapp.hga_pointing import point_hga
from estimation.sapp.nate import DriveCommand, Nate
from estimation.sapp.sun_modes import SunResult
from estimation.sapp.wheel_odometry import DriveKind
from sequences import commands as cmd
from sim.loop import drives
from sim.loop.context import CommandRefusedError, LoopContext, imu_sample, imu_series
from sim.rover.truth import CONTROL_DT_S

Details = dict[str, Any]
Handler = Callable[[LoopContext, Any], Details]

HGA_FRAME_S = 60.0  # one frame a minute during an Idle HGA pass

# ---- drives (sim.loop.drives) --------------------------------------------------------------


def drive_straight(ctx: LoopContext, c: cmd.DriveStraight) -> Details:
    command = DriveCommand(DriveKind.STRAIGHT, drag_wheel=c.drag_wheel)
    return drives.move(ctx, command, "straight", (c.distance_m,), c)


def drive_arc(ctx: LoopContext, c: cmd.DriveArc) -> Details:
    arc = (c.radius_m, math.radians(c.angle_deg))
    command = DriveCommand(DriveKind.ARC, c.radius_m, c.drag_wheel)
    return drives.move(ctx, command, "arc", arc, c)


def turn_in_place(ctx: LoopContext, c: cmd.TurnInPlace) -> Details:
    turn = (math.radians(c.angle_deg),)
    command = DriveCommand(DriveKind.TURN_IN_PLACE, drag_wheel=c.drag_wheel)
    return drives.move(ctx, command, "turn", turn, c)


# ---- NATE's settings and modes at once ----------------------------------------------------


def plant_site(ctx: LoopContext, c: cmd.PlantSite) -> Details:
    index = ctx.nate.plant_site()
    ctx.recorder.scorer.plant_site(ctx.sim.drive_state.p_s)
    ctx.event(f"Site {index} planted", "site")
    ctx.report()
    return {"site_index": index}


def set_param(ctx: LoopContext, c: cmd.SetParam) -> Details:
    if c.param.startswith(("mobility.", "vo.")) and ctx.nate.busy:
        raise CommandRefusedError(f"SET_PARAM: refused while {ctx.nate.mode.value} runs")
    if c.param.startswith("mobility."):  # mobility fault protection's limits
        ctx.protection.set_limit(c.param.removeprefix("mobility."), c.value)
    elif c.param == "vo.rig":  # the VO pairs' size (sim.loop.vo_drive.VO_RIGS)
        drives.set_vo_rig(ctx, c.value)
    else:
        ctx.nate.set_param(c.param, c.value)
    ctx.event(parameter_text(c.param, c.value), "parameter")
    ctx.report()
    return {}


# ---- mobility fault protection's tables (estimation.protection) ----------------------------


def keepout_add(ctx: LoopContext, c: cmd.KeepoutAdd) -> Details:
    site = ctx.nate.sites.current.index
    if c.polygon_m is not None:
        zone = KeepOutZone.polygon(c.zone, site, parse_polygon(c.polygon_m))
    else:
        assert c.x_m is not None and c.y_m is not None and c.radius_m is not None
        zone = KeepOutZone.circle(c.zone, site, c.x_m, c.y_m, c.radius_m)
    ctx.protection.add_zone(zone)
    ctx.event(zone_added_text(zone), "keepout")
    ctx.report()
    return {}


def keepout_clear(ctx: LoopContext, c: cmd.KeepoutClear) -> Details:
    cleared = ctx.protection.clear_zones(c.zone)
    ctx.event(zones_cleared_text(cleared), "keepout")
    ctx.report()
    return {}


def clear_mobility_fault(ctx: LoopContext, c: cmd.ClearMobilityFault) -> Details:
    fault = ctx.protection.clear_fault()
    said = "no mobility fault to clear" if fault is None else f"cleared the halt: {fault.reason}"
    ctx.event(f"mobility enabled ({said})", "mobility")
    ctx.report()
    return {}


def articulate_start(ctx: LoopContext, c: cmd.ArticulateStart) -> Details:
    ctx.nate.articulate()
    ctx.recorder.now(force=True)
    return {}


def articulate_stop(ctx: LoopContext, c: cmd.ArticulateStop) -> Details:
    ctx.nate.stop()
    ctx.recorder.now(force=True)
    return {}


def wait(ctx: LoopContext, c: cmd.Wait) -> Details:
    ctx.wait(c.duration_s)
    return {}


# ---- acquisitions: a NATE mode started, then run until NATE is idle again -----------------

# How each acquisition command starts its NATE mode.
ACQUISITIONS: Mapping[type[cmd.Command], Callable[[Nate, Any], object]] = {
    cmd.NadirUpdate: lambda nate, c: nate.nadir_update(c.window_s),
    cmd.NadirCheck: lambda nate, c: nate.nadir_check(c.window_s, c.tolerance_deg),
    cmd.Sunfind: lambda nate, c: nate.sunfind(),
    cmd.Suncheck: lambda nate, c: nate.suncheck(c.tolerance_deg),
    cmd.Sungaze: lambda nate, c: nate.sungaze(c.use_gravity),
    cmd.GetTiltAttitude: lambda nate, c: nate.get_tilt_attitude(),
    cmd.GetCoarseAttitude: lambda nate, c: nate.get_coarse_attitude(),
    cmd.GetFineAttitude: lambda nate, c: nate.get_fine_attitude(),
    cmd.SuncheckSungaze: lambda nate, c: nate.suncheck_sungaze(),
    cmd.Gyrocompass: lambda nate, c: nate.gyrocompass(c.duration_s),
}


def acquisition(ctx: LoopContext, c: cmd.Command) -> Details:
    ACQUISITIONS[type(c)](ctx.nate, c)
    return ctx.run_until_idle()


def suncheck_sungaze(ctx: LoopContext, c: cmd.SuncheckSungaze) -> Details:
    """SUNCHECK_SUNGAZE's result names its Suncheck's failure (Ali et al. 2005 sec. 4's
    practice, ``estimation.sapp.nate``): out of tolerance, the command goes on to Sungaze
    and, if Sungaze converges, completes (its purpose, a Fine attitude, is reached; the
    Suncheck only pointed the camera) with ``details["suncheck"]`` saying how far off the
    estimate was; with no sun in the image, it fails with that as its reason."""
    details = acquisition(ctx, c)
    results = ctx.results
    check = results[0] if results else None
    if not isinstance(check, SunResult) or check.success:
        return details
    said = f"Suncheck failed: {check.outcome.value}"
    if math.isfinite(check.error_rad):
        said += f" (error {math.degrees(check.error_rad):.2f} deg)"
    if len(results) > 1:
        details["suncheck"] = f"{said}; Sungaze ran on the sun it saw"
    else:
        details["failure"] = f"{said}; Sungaze not run, AQF {details['aqf']}"
    return details


# ---- the HGA pass --------------------------------------------------------------------------


def hga_pass(ctx: LoopContext, c: cmd.HgaPass) -> Details:
    """An HGA pass of ``c.duration_min``: a frame a minute (every cycle when NATE runs at
    8 Hz); the worst pointing error over the frames with Earth up is its figure."""
    nate, sim, recorder = ctx.nate, ctx.sim, ctx.recorder
    duration_s = c.duration_min * 60.0
    if nate.busy:
        raise CommandRefusedError(f"HGA_PASS: refused while {nate.mode.value} runs")
    earth = earth_ll(sim.t_s, sim.lat_rad, sim.lon_east_rad)
    if not point_hga(nate.q_b_ll, earth).earth_above_horizon:
        raise CommandRefusedError("HGA_PASS: Earth is below the horizon (IVP): no link possible")
    if nate.aqf < AttitudeQuality.FINE:
        ctx.event(
            f"HGA pass with AQF {nate.aqf.paper_name}: pointing not assured", "hga", "warning"
        )
    first = len(recorder.truths)
    recorder.now(force=True)
    end = sim.t_s + duration_s
    while sim.t_s < end - 1e-9:
        step = min(HGA_FRAME_S, end - sim.t_s)
        if nate.wait_hint_s > CONTROL_DT_S:
            recorder.at_rest(nate.step(imu_sample(sim.rest(step), 0)), force=True)
        else:
            recorder.at_rest_series(nate.step_series(imu_series(sim.rest_cycles(step))))
    truths = recorder.truths[first:]  # the pass's link: a world outcome, scored
    errors = [f.hga_error_deg for f in truths if f.earth_up]
    worst = max(errors) if errors else math.nan
    margin = 2.0 - worst
    earth_set = len(errors) != len(truths)
    text = f"HGA pass: worst error {worst:.2f} deg, margin {margin:.2f} deg" + (
        ", Earth set during the pass" if earth_set else ""
    )
    severity: Severity = "error" if margin < 0.0 else "warning" if earth_set else "info"
    recorder.truths[-1].events.append(Event(text, "hga", severity))
    # the figures are scores (the report's details stay in the simulator); what the ground
    # learns of a failed pass is that the link was lost, not by how far the HGA was off
    out: Details = {"hga_worst_error_deg": worst, "hga_min_margin_deg": margin}
    if margin < 0.0:
        out["failure"] = "HGA link lost during the pass: the pointing left the 2 deg beam"
    return out


# ---- the table -----------------------------------------------------------------------------

HANDLERS: Mapping[type[cmd.Command], Handler] = {
    cmd.DriveStraight: drive_straight,
    cmd.DriveArc: drive_arc,
    cmd.TurnInPlace: turn_in_place,
    cmd.DriveTo: drives.drive_to,
    cmd.PlantSite: plant_site,
    cmd.SetParam: set_param,
    cmd.ArticulateStart: articulate_start,
    cmd.ArticulateStop: articulate_stop,
    cmd.Wait: wait,
    cmd.HgaPass: hga_pass,
    cmd.KeepoutAdd: keepout_add,
    cmd.KeepoutClear: keepout_clear,
    cmd.ClearMobilityFault: clear_mobility_fault,
    **{kind: acquisition for kind in ACQUISITIONS},
    cmd.SuncheckSungaze: suncheck_sungaze,
}
