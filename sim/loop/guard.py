"""Mobility fault protection in the loop: the flight software's checks
(``estimation.protection``) fed what the rover senses during a drive, and a halt acted on.

The simulator computes a drive segment's truth before the flight software sees it
(``sim.loop.rover_sim``). The checks then run over the segment's cycles on NATE's estimate
and the sensors (accelerometers, suspension encoders); when one trips at a cycle, the world
is stopped there: the simulator and NATE are loaded back to before the segment, the segment
is made again cut at that cycle (``max_cycles``: the same truth and slip draws up to it), and
NATE steps through the cut segment (``sim.loop.drives``). What reaches the monitor is the
flight software's own: its estimate, its sensors, its clock; never the truth.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from estimation.protection.halt import Halt
from estimation.protection.monitor import DriveMonitor, Trip
from estimation.sapp.nate import NateSeries
from sim.loop.context import CommandRefusedError, LoopContext
from sim.loop.rover_sim import Segment

FloatArray = NDArray[np.float64]


def begin_drive(ctx: LoopContext, command: Any) -> DriveMonitor:
    """The monitor of a drive command, under its own limits where it gives them; refused
    while a halt has mobility disabled."""
    protection = ctx.protection
    try:
        protection.require_enabled(getattr(command, "name", "drive"))
    except ValueError as exc:
        raise CommandRefusedError(str(exc)) from None
    pct = getattr(command, "slip_limit_pct", None)
    limits = protection.drive_limits(
        slip_limit=None if pct is None else float(pct) / 100.0,
        vo_fail=getattr(command, "vo_fail", None),
        timeout_s=getattr(command, "timeout_s", None),
        lmst_limit_h=_time_of_day(getattr(command, "lmst_limit_h", None)),
    )
    nate = ctx.nate
    heading_3sigma_deg = ctx.recorder.knowledge.three_sigma_deg(nate.imu_integration_s)
    return protection.begin_drive(nate.t_s, math.radians(heading_3sigma_deg), limits)


def _time_of_day(hours: float | None) -> float | None:
    """24:00 is midnight, 00:00."""
    return None if hours is None else float(hours) % 24.0


def zone_positions(ctx: LoopContext, p_s: FloatArray) -> dict[str, FloatArray]:
    """Positions ``p_s`` (..., 3) of the current Site in each keep-out zone's Site."""
    sites = ctx.nate.sites
    here = sites.site(sites.current.index).origin_mission_m
    out: dict[str, FloatArray] = {}
    for name, zone in ctx.protection.zones.items():
        shift = here - sites.site(zone.site_index).origin_mission_m
        out[name] = np.asarray(p_s, dtype=np.float64) + shift
    return out


def odometry_steps_m(p_before_s: FloatArray, series: NateSeries) -> FloatArray:
    """The horizontal distance NATE's estimate moved at each cycle of ``series``, m."""
    p = np.vstack([p_before_s[None, :], series.p_s])
    out: FloatArray = np.hypot(*np.diff(p[:, :2], axis=0).T)
    return out


def check_segment(
    ctx: LoopContext,
    monitor: DriveMonitor,
    seg: Segment,
    series: NateSeries,
    p_before_s: FloatArray,
) -> Trip | None:
    """The first cycle of ``seg`` at which a check trips (NATE's ``series`` through it)."""
    rocker_rad, bogie_rad = ctx.sim.suspension_readings(seg)
    return monitor.check_cycles(
        series.t_s,
        zone_positions(ctx, series.p_s),
        odometry_steps_m(p_before_s, series),
        seg.imu.delta_velocity_b,
        seg.imu.dt_s,
        rocker_rad,
        bogie_rad,
        series.p_s,
    )


def halt(ctx: LoopContext, what: Halt) -> dict[str, Any]:
    """Latch the fault and say so; the halt for the command's details."""
    ctx.protection.fault = what
    ctx.event(f"drive halted by fault protection: {what.reason}", "mobility", "error")
    return what.as_dict()


def vo_step_halt(
    ctx: LoopContext,
    monitor: DriveMonitor,
    commanded_m: float,
    before_s: FloatArray,
    wheel_s: FloatArray,
    vo_s: FloatArray | None,
) -> Halt | None:
    """After a VO step: the slip check (VO's motion against wheel odometry's, along wheel
    odometry's direction) and, on a VO update, the keep-out zones on the updated position.
    ``before_s`` the pose at the previous pair, ``wheel_s`` wheel odometry's at this one,
    ``vo_s`` VO's (``None``: VO failed)."""
    wheel = (wheel_s - before_s)[:2]
    wheel_m = float(np.hypot(*wheel))
    vo_m = None
    if vo_s is not None:
        along = wheel / wheel_m if wheel_m > 0.0 else np.zeros(2)
        vo_m = float(np.dot((vo_s - before_s)[:2], along))
    now = ctx.nate.p_s.copy()
    found = monitor.after_vo_step(ctx.nate.t_s, now, commanded_m, wheel_m, vo_m)
    if found is None and vo_s is not None:
        found = monitor.check_zones_now(ctx.nate.t_s, zone_positions(ctx, now), now)
    return found
