"""The cases of ``roverops bench faults`` (``bench.faults.report``), one run each.

The cases of the drive-safety issue, each ``RUNS`` runs on fixed seeds (0..RUNS-1; set
``ROVEROPS_FAULTS_RUNS`` for a quicker look), two processes at a time. Every run starts
with GET_FINE_ATTITUDE (the heading known to MER's Fine budget), then:

- **Wopmay** (Cheng, Maimone and Matthies 2005 sec. 4.1): on the Endurance-like slope of
  loose sand (``meridiani:endurance_slope``), 12 m up the wall from its Site origin (about
  22°), a 6 m drive East across it, a keep-out circle of 1 m radius whose edge is 1 m
  downslope (South) of the nominal path, 5 m along it (the rover creeps about 1 m down over
  the 6 m there: at the path's middle it would not reach the circle with or without VO).
  A *true entry* is the true body origin inside the circle at any cycle. VO steps of 0.5 m
  (``WOPMAY_VO_STEP_M``): MER's 0.75 m steps lose VO across this slope.
  ``keepout_true_entry_pct_vo`` with ``vo=on`` (target ≤ 2 %), ``_no_vo`` on wheel odometry
  alone (reported: what VO is for).
- **Sand trap**: on Gusev, a trap (slip ≥ 90 %) of 1.5 m radius across the path 2 m ahead,
  a 10 m VO drive: ``sandtrap_halt_pct`` (target 100 %) and ``sandtrap_halt_distance_m``, the
  worst true distance driven past the trap's edge (target ≤ ``slip_check_m`` + one VO step).
- **Tilt**: up the slope (North, 20.4° at the start, steepening) with the tilt limit set to
  21°: ``tilt_limit_exceeded_deg_max``, the worst true tilt over the limit (target ≤ 1°).
- **Drag**: 20 m on Gusev dragging the right front wheel: ``drag_odometry_err_pct`` (five-wheel
  odometry; reported) and ``drag_vo_err_pct`` (``vo=on``; target ≤ 1 %), the horizontal error
  at the end in % of the true distance, worst run.
- **Position uncertainty**: ``position_sigma_coverage_pct``, the true position error inside the
  onboard 2σ (the downlink's ``position_sigma_m``) at the end of ``COVERAGE_DRIVES`` drives on
  Gusev, half with VO (target 90-99 %).
"""

from __future__ import annotations

import math
import os
from datetime import UTC, datetime
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from sequences import commands as cmd
from sequences.limits import VO_STEP_MAX_M
from sim.errors import InputError
from sim.loop.session import RoverSession
from sim.loop.vo_drive import VoDriveOptions
from sim.world.soil_patches import sand_trap

RUNS = 30
COVERAGE_DRIVES = 100
GUSEV_START = datetime(2004, 4, 14, 16, 30, tzinfo=UTC)  # mid-morning at Gusev
MERIDIANI_START = datetime(2004, 10, 1, 18, 0, tzinfo=UTC)  # 10:15 LMST at Meridiani
SLOPE = "meridiani:endurance_slope"
WOPMAY_RADIUS_M = 1.0
WOPMAY_CENTRE_S = (-(1.0 + WOPMAY_RADIUS_M), 5.0)  # its edge 1 m South of the path, 5 m on
WOPMAY_START_X_M = 12.0  # up the wall from the Site origin: ~22°, where the sand creeps most
TRAP_CENTRE_S, TRAP_RADIUS_M = (3.5, 0.0), 1.5  # its edge 2 m ahead
TILT_LIMIT_DEG = 21.0
# VO steps on the slope: MER's 0.75 m steps lose VO there (fewer than 12 RANSAC inliers on
# every step, heading across the slope); drivers shortened the steps on such ground
WOPMAY_VO_STEP_M = 0.5


def runs_from_env() -> int:
    text = os.environ.get("ROVEROPS_FAULTS_RUNS", str(RUNS))
    if not text.isdigit() or not 1 <= int(text) <= 1000:
        raise InputError("ROVEROPS_FAULTS_RUNS", f"must be a whole number 1-1000, got {text!r}")
    return int(text)


def _session(
    site: str,
    seed: int,
    start: datetime,
    yaw_rad: float = 0.0,
    vo_step_m: float = VO_STEP_MAX_M,
    x_m: float = 0.0,
) -> RoverSession:
    """A rover with a Fine attitude, every cycle a frame (its truth, for the scoring)."""
    options = VoDriveOptions(step_max_m=vo_step_m)
    s = RoverSession(
        site, seed, start, frame_every_s=0.0, yaw_rad=yaw_rad, vo_options=options, x_m=x_m
    )
    report = s.execute(cmd.GetFineAttitude())
    if report.status != "completed":
        raise RuntimeError(f"GET_FINE_ATTITUDE {report.status}: {report.reason}")
    s.take_frames()
    return s


def _true_path_s(s: RoverSession) -> np.ndarray:
    """The true positions (N, 3) of the frames made since the last take, Site 0."""
    return np.array([t["p_s_true"] for _, t in s.take_frames()], dtype=np.float64)


def wopmay_run(seed: int, vo: bool) -> dict[str, Any]:
    s = _session(SLOPE, seed, MERIDIANI_START, math.pi / 2.0, WOPMAY_VO_STEP_M, WOPMAY_START_X_M)
    x_c, y_c = WOPMAY_CENTRE_S
    s.execute(cmd.KeepoutAdd(zone="wopmay", x_m=x_c, y_m=y_c, radius_m=WOPMAY_RADIUS_M))
    report = s.execute(cmd.DriveStraight(distance_m=6.0, vo=vo))
    path = _true_path_s(s)
    closest = float(np.min(np.hypot(path[:, 0] - x_c, path[:, 1] - y_c)))
    return {
        "entered": closest < WOPMAY_RADIUS_M,
        "halted": report.status == "halted",
        "closest_m": closest,
    }


def sandtrap_run(seed: int) -> dict[str, Any]:
    s = _session("gusev", seed, GUSEV_START)
    s.sim.add_soil_patch("trap", sand_trap(*TRAP_CENTRE_S, TRAP_RADIUS_M))
    report = s.execute(cmd.DriveStraight(distance_m=10.0, vo=True))
    path = _true_path_s(s)
    edge_x = TRAP_CENTRE_S[0] - TRAP_RADIUS_M
    halt = report.details.get("halt") or {}
    return {
        "halted": report.status == "halted" and halt.get("check") == "slip",
        "past_edge_m": max(0.0, float(np.max(path[:, 0])) - edge_x),
        "slip": halt.get("values", {}).get("slip", math.nan),
    }


def tilt_run(seed: int) -> dict[str, Any]:
    s = _session(SLOPE, seed, MERIDIANI_START)
    s.execute(cmd.SetParam(param="mobility.tilt_limit_rad", value=math.radians(TILT_LIMIT_DEG)))
    report = s.execute(cmd.DriveStraight(distance_m=15.0))
    tilts = []
    for _, truth in s.take_frames():
        q = np.asarray(truth["q_b_ll_true"], dtype=np.float64)
        z_ll = Rotation.from_quat(q).inv().apply([0.0, 0.0, 1.0])  # body z in LL
        tilts.append(math.degrees(math.acos(max(-1.0, min(1.0, float(z_ll[2]))))))
    return {
        "halted": report.status == "halted",
        "check": (report.details.get("halt") or {}).get("check"),
        "excess_deg": max(tilts) - TILT_LIMIT_DEG,
    }


def drag_run(seed: int, vo: bool) -> dict[str, Any]:
    s = _session("gusev", seed, GUSEV_START)
    before = s.sim.totals.distance_truth_m
    s.execute(cmd.DriveStraight(distance_m=20.0, drag_wheel="rf", vo=vo))
    frames = s.take_frames()
    down, truth = frames[-1]
    err = math.hypot(
        down["p_s_est"][0] - truth["p_s_true"][0], down["p_s_est"][1] - truth["p_s_true"][1]
    )
    return {"err_pct": 100.0 * err / (s.sim.totals.distance_truth_m - before)}


def coverage_run(seed: int) -> dict[str, Any]:
    """One drive, VO on odd seeds, a length and turn drawn from the seed."""
    rng = np.random.default_rng([seed, 22])
    vo = seed % 2 == 1
    s = _session("gusev", seed, GUSEV_START, yaw_rad=float(rng.uniform(0, 2 * math.pi)))
    length = float(rng.uniform(2.0, 5.0) if vo else rng.uniform(3.0, 25.0))
    if rng.uniform() < 0.5:
        c: cmd.Command = cmd.DriveStraight(distance_m=length, vo=vo)
    else:
        radius = float(rng.choice([-1, 1]) * rng.uniform(3.0, 12.0))
        angle = min(math.degrees(length / abs(radius)), 120.0)
        c = cmd.DriveArc(radius_m=radius, angle_deg=angle, vo=vo)
    s.execute(c)
    down, truth = s.take_frames()[-1]
    err = math.hypot(
        down["p_s_est"][0] - truth["p_s_true"][0], down["p_s_est"][1] - truth["p_s_true"][1]
    )
    sigma = float(down["position_sigma_m"] or math.nan)
    return {"vo": vo, "err_m": err, "sigma_m": sigma, "inside": err <= 2.0 * sigma}
