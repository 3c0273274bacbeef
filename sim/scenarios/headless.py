"""Built-in headless scenarios for ``roverops run``: truth and sensors at 8 Hz.

Each scenario is a site, a start time and a short list of commands. The summary puts the
truth beside what the sensors report (wheel odometry against the distance really covered,
the gyros against the rotation of Mars), the figures an operator checks first.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from sequences import commands as cmd
from sim.errors import InputError
from sim.loop.downlink import ESTIMATORS
from sim.loop.rover_sim import RoverSim
from sim.loop.session import run_commands
from sim.rover.drive import MAX_PATH_M, MAX_TURN_RAD
from sim.rover.truth import CONTROL_DT_S
from sim.world.marsclock import SOL_S, lmst_h_from_t_s, sol_number_t_s, t_s_to_utc

DEG_PER_H_PER_RAD_S = math.degrees(1.0) * 3600.0
# A scenario with SAPP in the loop is read from its summary (the last frame and the
# commands' events), so it keeps a frame a minute of 8 Hz activity; frames with events or
# a mode change are kept whatever the rate (sim.loop.frames).
SUMMARY_FRAME_EVERY_S = 60.0


@dataclass(frozen=True)
class Scenario:
    """A named scenario: one command (``rest``, ``straight`` or ``turn``) at a site.

    ``amount`` is the command's default size: seconds for ``rest``, metres for
    ``straight``, degrees for ``turn``; the CLI can override it and the site.
    """

    name: str
    site: str
    kind: str
    amount: float
    description: str
    start_utc: datetime = datetime(2004, 4, 14, 16, 30, 0, tzinfo=UTC)  # Spirit sol 100, ~10 LMST


SCENARIOS: dict[str, Scenario] = {
    s.name: s
    for s in (
        Scenario("rest_1h", "gusev", "rest", 3600.0, "rest at the site, idle time jumped over"),
        Scenario("drive_100m", "gusev", "straight", 100.0, "a straight drive north"),
        Scenario("turn_360_eq22", "eq22", "turn", 360.0, "a turn in place on Balaram 2000 eq. 22"),
        Scenario(
            "fine_drive_hga",
            "gusev",
            "sapp",
            100.0,
            "SAPP in the loop: GetFineAttitude, a straight drive, a 15 min HGA pass",
        ),
    )
}
# The parameter that overrides each kind's amount, and its limits (outside input).
_AMOUNT_PARAMETER = {
    "rest": "duration_s",
    "straight": "distance_m",
    "turn": "angle_deg",
    "sapp": "distance_m",
}
# Lower limits: one control cycle, a centimetre, a tenth of a degree (a smaller command is
# below what the sensors resolve); upper: ten sols, sim.rover.drive's longest path and turn.
_AMOUNT_LIMITS = {
    "rest": (CONTROL_DT_S, 10 * SOL_S),
    "straight": (0.01, MAX_PATH_M),
    "turn": (0.1, math.degrees(MAX_TURN_RAD)),
    "sapp": (0.01, MAX_PATH_M),
}


def get_scenario(name: str) -> Scenario:
    """The scenario called ``name``; InputError('scenario', ...) naming the choices."""
    if name not in SCENARIOS:
        choices = ", ".join(SCENARIOS)
        raise InputError("scenario", f"unknown scenario {name!r}; choose one of {choices}")
    return SCENARIOS[name]


def _amount(scenario: Scenario, overrides: dict[str, float | None]) -> float:
    own = _AMOUNT_PARAMETER[scenario.kind]
    for parameter, value in overrides.items():
        if value is not None and parameter != own:
            raise InputError(parameter, f"does not apply to scenario {scenario.name!r}")
    value = overrides.get(own)
    if value is None:
        return scenario.amount
    low, high = _AMOUNT_LIMITS[scenario.kind]
    if not (math.isfinite(value) and low <= value <= high):
        raise InputError(own, f"must be between {low:g} and {high:g}, got {value!r}")
    return value


def run_scenario(
    name: str,
    seed: int,
    site: str | None = None,
    duration_s: float | None = None,
    distance_m: float | None = None,
    angle_deg: float | None = None,
    estimators: tuple[str, ...] = ("sapp",),
) -> dict[str, Any]:
    """Run scenario ``name`` with ``seed`` (and optional overrides); its summary as a dict.

    Overrides are validated before anything runs: an unknown site, a size out of range or
    one that does not apply to the scenario raise ``InputError`` naming the parameter.
    ``estimators``: what runs beside SAPP in a scenario with the flight software in the
    loop (``sim.loop.side.kinematic.ESTIMATORS``); the summary gives each one's final errors.
    """
    if estimators != ("sapp",):
        unknown = [e for e in estimators if e not in ESTIMATORS]
        if unknown or "sapp" not in estimators:
            raise InputError(
                "estimators", f"must include sapp, from {', '.join(ESTIMATORS)}; got {estimators}"
            )
    scenario = get_scenario(name)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise InputError("seed", f"must be a non-negative integer, got {seed!r}")
    amount = _amount(
        scenario, {"duration_s": duration_s, "distance_m": distance_m, "angle_deg": angle_deg}
    )
    if scenario.kind == "sapp":
        return _run_sapp(scenario, amount, seed, site, estimators)
    if estimators != ("sapp",):
        raise InputError("estimators", f"scenario {name!r} runs no flight software")
    wall_start = time.perf_counter()
    sim = RoverSim(scenario.site if site is None else site, seed, scenario.start_utc)
    t_start = sim.t_s
    if scenario.kind == "rest":
        sim.rest(amount)
    elif scenario.kind == "straight":
        sim.drive_straight(amount)
    else:
        sim.turn_in_place(math.radians(amount))
    wall_s = time.perf_counter() - wall_start
    return summarize(scenario, amount, seed, sim, t_start, wall_s)


def summarize(
    scenario: Scenario, amount: float, seed: int, sim: RoverSim, t_start_s: float, wall_s: float
) -> dict[str, Any]:
    """The scenario summary: clock, truth beside sensors, and run statistics."""
    lon_west_deg = (360.0 - sim.site.lon_east_deg) % 360.0
    mission = sim.site.mission  # sols count from the landing of this site's rover
    totals = sim.totals
    roll, pitch, yaw = Rotation.from_quat(sim.drive_state.q_s_b).as_euler("ZYX")[::-1]
    summary: dict[str, Any] = {
        "scenario": scenario.name,
        "description": scenario.description,
        "command": {scenario.kind: amount},
        "seed": seed,
        "site": sim.site.name,
        "start_utc": t_s_to_utc(t_start_s).isoformat(),
        "end_utc": t_s_to_utc(sim.t_s).isoformat(),
        "mission": mission,
        "sol": int(sol_number_t_s(mission, t_start_s)),
        "lmst_start_h": float(lmst_h_from_t_s(t_start_s, lon_west_deg)),
        "lmst_end_h": float(lmst_h_from_t_s(sim.t_s, lon_west_deg)),
        "sim_duration_s": sim.t_s - t_start_s,
        "cycles_simulated": totals.cycles_simulated,
        "idle_s_jumped": totals.idle_s_jumped,
        "wall_s": wall_s,
        "distance_truth_m": totals.distance_truth_m,
        "final_p_s": [float(v) for v in sim.drive_state.p_s],
        "final_heading_deg": round(math.degrees(yaw), 9) % 360.0,  # -1e-16 is North, not 360
        "final_roll_deg": math.degrees(roll),
        "final_pitch_deg": math.degrees(pitch),
        "max_wheel_gap_mm": totals.max_wheel_gap_m * 1e3,
        "unsettled_poses": totals.unsettled_poses,
    }
    if scenario.kind == "turn":
        summary["heading_change_truth_deg"] = math.degrees(totals.heading_change_rad)
    if scenario.kind == "straight" and totals.distance_truth_m > 0.0:
        summary["distance_odometry_m"] = totals.distance_odometry_m
        summary["odometry_error_pct"] = (
            100.0 * (totals.distance_odometry_m - totals.distance_truth_m) / totals.distance_truth_m
        )
    if totals.rest_s > 0.0:
        gyro_rate = totals.gyro_rest_angle_b / totals.rest_s * DEG_PER_H_PER_RAD_S
        mars_rate = totals.truth_rest_angle_b / totals.rest_s * DEG_PER_H_PER_RAD_S
        summary["gyro_rate_b_deg_per_h"] = [float(v) for v in gyro_rate]
        summary["mars_rate_b_deg_per_h"] = [float(v) for v in mars_rate]
        summary["gyro_minus_mars_deg_per_h"] = float(np.linalg.norm(gyro_rate - mars_rate))
        # What only a simulator can show: the bias the gyros really had.
        bias = sim.imu.gyro_bias_rad_s * DEG_PER_H_PER_RAD_S
        summary["gyro_bias_truth_deg_per_h"] = [float(v) for v in bias]
    return summary


def _run_sapp(
    scenario: Scenario, distance_m: float, seed: int, site: str | None, estimators: tuple[str, ...]
) -> dict[str, Any]:
    """A scenario with the flight software in the loop (``sim.loop.session``)."""
    commands = [cmd.GetFineAttitude(), cmd.DriveStraight(distance_m), cmd.HgaPass(15.0)]
    session, reports, wall_s = run_commands(
        scenario.site if site is None else site,
        seed,
        scenario.start_utc,
        commands,
        estimators=estimators,
        frame_every_s=SUMMARY_FRAME_EVERY_S,
    )
    base = summarize(scenario, distance_m, seed, session.sim, reports[0].start_t_s, wall_s)
    last, scored = session.downlinks[-1], session.truths[-1]
    base["commands"] = [
        {
            "command": r.command,
            "status": r.status,
            "reason": r.reason,
            "duration_s": r.end_t_s - r.start_t_s,
            "events": [e.as_dict() for e in [*r.events, *r.scores]],
        }
        for r in reports
    ]
    base["final_aqf"] = last.aqf
    base["final_nate_mode"] = last.nate_mode
    base["attitude_error_deg"] = math.degrees(session.attitude_error_rad())
    base["p_s_est"] = last.p_s_est
    base["p_s_true"] = scored.p_s_true
    base["position_error_m"] = scored.position_error_m
    base["position_error_pct_of_distance"] = (
        100.0 * scored.position_error_m / max(session.sim.totals.distance_truth_m, 1e-9)
    )
    base["estimators"] = {
        name: {
            "position_error_m": e["position_error_m"],
            "position_error_pct_of_distance": 100.0
            * e["position_error_m"]
            / max(session.sim.totals.distance_truth_m, 1e-9),
            "attitude_error_deg": e["attitude_error_deg"],
        }
        for name, e in scored.estimators.items()
    }
    base["imu_integration_s"] = last.imu_integration_s
    base["hga_error_deg"] = scored.hga_error_deg
    base["hga_margin_deg"] = scored.hga_margin_deg
    base["earth_above_horizon"] = scored.earth_up
    return base
