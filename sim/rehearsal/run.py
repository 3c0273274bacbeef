"""One rehearsal run: the whole loop, flight software and simulated rover, on one sampled world.

``run_once(inputs, run_index, campaign_seed)`` draws a world from what the ground knows
(``sim.rehearsal.world``), a true start around the report (``sim.rehearsal.start``), builds a
``RoverSession`` on them with the flight software loaded from the report, and runs the
sequence as the server's runtime runs it (``server.runtime``): the text parsed by the
sequence language into the same command objects, each step started when its time tag says
(``sequences.timing``, the queue's own arithmetic; the rover idles until then), executed to
completion; a refused or halted step stops the sequence (the steps after it assumed it:
``not_run``), a failed one does not. Each step gives a ``StepOutcome``: its report, the
sampled world's truth (end pose, largest tilt, the keep-out zones entered, the thinned true
path), what the rover would report (its estimate, AQF, IMU time, position 1σ) and, for an
HGA pass, its true and predicted margins.

Deterministic bit for bit from its arguments: every draw comes from
``np.random.SeedSequence([campaign_seed, run_index])`` (the simulator's seed, the world's,
the start's and the priors'), and nothing reads the clock but ``wall_s``. The run reads
nothing but its ``RehearsalInputs``: no session, checkpoint or simulator other than its own.

A bench uses it as it stands: build ``RehearsalInputs`` (``ReportedStart.from_downlink`` on
an execution's last downlink, the ground's map, the sequence), call ``run_once`` for
``run_index`` 0..N-1 with one ``campaign_seed``, and read ``StepOutcome.p_mission_true_m``.
"""

from __future__ import annotations

import itertools
import math
import os
import socket
import time
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from estimation.protection.keepout import KeepOutZone
from sequences import commands as cmd
from sequences import timing
from sequences.language import parse
from sequences.model import TimeTag
from sim.loop.rover_sim import Segment
from sim.loop.session import CommandReport, RoverSession
from sim.rehearsal.inputs import RehearsalInputs
from sim.rehearsal.outcome import RunOutcome, StepOutcome
from sim.rehearsal.start import (
    TrueStart,
    heading_of,
    level_start,
    load_reported,
    sample_start,
)
from sim.rehearsal.world import sampled_world
from sim.world.marsclock import sol_number_t_s, t_s_for_sol_lmst, t_s_to_utc

FloatArray = NDArray[np.float64]

FRAME_EVERY_S = 1.0e9  # frames only where events or modes force them: the run reads its own truth
PATH_SPACING_M = 0.25  # the thinned true path: about four points per metre
_NAN2 = (math.nan, math.nan)


@dataclass(frozen=True)
class RunSeeds:
    """The run's seeds, all from ``SeedSequence([campaign_seed, run_index])``: ``sim`` the
    simulator's (IMU, encoders, slip, cameras, mast bias), ``world`` the site generators'
    (relief, rocks, albedo), and generators for the start and for the world's map error and
    soil."""

    sim: int
    world: int
    start: np.random.Generator
    priors: np.random.Generator

    @classmethod
    def of(cls, campaign_seed: int, run_index: int) -> RunSeeds:
        for name, value in (("campaign_seed", campaign_seed), ("run_index", run_index)):
            if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 0:
                raise ValueError(f"{name}: must be a non-negative integer, got {value!r}")
        children = np.random.SeedSequence([int(campaign_seed), int(run_index)]).spawn(4)

        def as_int(ss: np.random.SeedSequence) -> int:
            return int(ss.generate_state(1, np.uint64)[0]) >> 1  # in [0, 2**63)

        return cls(
            as_int(children[0]),
            as_int(children[1]),
            np.random.default_rng(children[2]),
            np.random.default_rng(children[3]),
        )


@dataclass
class TruthTape:
    """The true traverse as the simulator makes it (``RoverSim.on_segment``): times,
    positions (N, 3) and attitudes ``q_s_b`` (N, 4). A segment made again after a halt (it
    starts no later than what is recorded) replaces what it overlaps."""

    t_s: list[float] = field(default_factory=list)
    p_s: list[FloatArray] = field(default_factory=list)
    q_s_b: list[FloatArray] = field(default_factory=list)

    def add(self, seg: Segment) -> None:
        traj = seg.truth
        t0 = float(traj.t_s[0])
        while self.t_s and self.t_s[-1] >= t0:
            self.t_s.pop(), self.p_s.pop(), self.q_s_b.pop()
        self.t_s.extend(float(t) for t in traj.t_s)
        self.p_s.extend(np.asarray(traj.p_s, dtype=np.float64))
        self.q_s_b.extend(np.asarray(traj.q_s_b, dtype=np.float64))

    def between(self, t0_s: float, t1_s: float) -> tuple[FloatArray, FloatArray]:
        """Positions and attitudes recorded within ``[t0_s, t1_s]``."""
        keep = [k for k, t in enumerate(self.t_s) if t0_s - 1e-9 <= t <= t1_s + 1e-9]
        if not keep:
            return np.zeros((0, 3)), np.zeros((0, 4))
        return np.array([self.p_s[k] for k in keep]), np.array([self.q_s_b[k] for k in keep])

    def forget_before(self, t_s: float) -> None:
        """Drop what was recorded before ``t_s`` (a step that has been scored)."""
        keep = [k for k, t in enumerate(self.t_s) if t >= t_s]
        self.t_s = [self.t_s[k] for k in keep]
        self.p_s = [self.p_s[k] for k in keep]
        self.q_s_b = [self.q_s_b[k] for k in keep]


def tilt_deg(q_s_b: FloatArray) -> FloatArray:
    """The tilt (deg) of attitudes ``q_s_b`` (N, 4): the body's z axis against the Site's."""
    z = Rotation.from_quat(q_s_b).apply(np.array([0.0, 0.0, 1.0]))
    out: FloatArray = np.degrees(np.arccos(np.clip(np.atleast_2d(z)[:, 2], -1.0, 1.0)))
    return out


def thinned_path(p_m: FloatArray, spacing_m: float = PATH_SPACING_M) -> FloatArray:
    """The points of a path (N, 2) about ``spacing_m`` apart along it, its ends kept."""
    if len(p_m) <= 2:
        return p_m
    along = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(p_m, axis=0).T))])
    marks = np.floor(along / spacing_m)
    keep = np.flatnonzero(np.diff(marks, prepend=-1.0) > 0)
    keep = np.union1d(keep, [len(p_m) - 1])
    out: FloatArray = p_m[keep]
    return out


def entered(zone: KeepOutZone, origin_m: FloatArray, path_m: FloatArray) -> bool:
    """Whether the true path (N, 2; mission frame) reaches into ``zone`` (its Site's origin
    ``origin_m`` in the mission frame): the body origin's, as the onboard check and the
    ground's path check test a zone."""
    local = path_m - origin_m[:2]
    if zone.is_circle:
        cx, cy = zone.centre_s
        return bool(np.any(np.hypot(local[:, 0] - cx, local[:, 1] - cy) <= zone.radius_m))
    if len(local) == 1:
        return zone.clearance_m((float(local[0, 0]), float(local[0, 1]))) <= 0.0
    pts = [(float(x), float(y)) for x, y in local]
    return any(zone.path_clearance_m(a, b) <= 0.0 for a, b in itertools.pairwise(pts))


class Rehearsal:
    """One run in progress (``run_once``): the session on its sampled world and its tape."""

    def __init__(self, inputs: RehearsalInputs, seeds: RunSeeds) -> None:
        start, priors = inputs.start, inputs.priors
        centre = (float(start.p_mission_est[0]), float(start.p_mission_est[1]))
        world = sampled_world(
            start.site, inputs.ground_map, priors, centre, seeds.world, seeds.priors
        )
        self.true_start: TrueStart = sample_start(start, priors, seeds.start)
        terrain = level_start(world, self.true_start, start).terrain()
        self.soil = terrain.soil
        self.session = RoverSession(
            start.site,
            seeds.sim,
            t_s_to_utc(start.t_s),
            frame_every_s=FRAME_EVERY_S,
            vo_rig=start.vo_rig,
            terrain=terrain,
            start_t_s=start.t_s,
            x_m=self.true_start.p_mission_m[0],
            y_m=self.true_start.p_mission_m[1],
            yaw_rad=self.true_start.yaw_rad,
            mast_bias_sigma_deg=priors.mast_bias_sigma_deg,
        )
        load_reported(self.session, start)
        self.tape = TruthTape()
        self.session.sim.on_segment = self.tape.add
        self.mission = start.mission
        self.last_done_t_s = start.t_s

    def start_time(self, tag: TimeTag) -> float:
        mission = self.mission
        return timing.start_time(
            tag,
            self.session.sim.t_s,
            self.last_done_t_s,
            lambda t: int(sol_number_t_s(mission, t)),
            lambda sol, lmst_h: t_s_for_sol_lmst(mission, sol, lmst_h),
        )

    def step(self, line: int, command: cmd.Command, tag: TimeTag) -> StepOutcome:
        """Wait for the step's time, run it, score it."""
        session = self.session
        target = self.start_time(tag)
        if target > session.sim.t_s + 1e-6:  # the runtime's idle until the step is due
            session.execute(cmd.Wait(target - session.sim.t_s), label="")
        state = session.sim.drive_state
        p0, q0 = state.p_s.copy(), state.q_s_b.copy()
        first_frame = len(session.downlinks)
        report = session.execute(command, label=command.describe())
        self.last_done_t_s = report.end_t_s
        outcome = self.score(line, command, report, p0, q0, first_frame)
        del session.reports[:], session.downlinks[:], session.truths[:]
        session.take_images()
        self.tape.forget_before(report.end_t_s)
        return outcome

    def score(
        self,
        line: int,
        command: cmd.Command,
        report: CommandReport,
        p0: FloatArray,
        q0: FloatArray,
        first_frame: int,
    ) -> StepOutcome:
        session, nate = self.session, self.session.nate
        state = session.sim.drive_state
        p_tape, q_tape = self.tape.between(report.start_t_s, report.end_t_s)
        p_all = np.vstack([p0[None, :], p_tape, state.p_s[None, :]])
        q_all = np.vstack([q0[None, :], q_tape, state.q_s_b[None, :]])
        path = p_all[:, :2]
        zones: list[str] = []
        for name, zone in sorted(session.loop.protection.zones.items()):
            if zone.site_index < len(nate.sites):
                origin = nate.sites.site(zone.site_index).origin_mission_m
                if entered(zone, origin, path):
                    zones.append(name)
        p_est = nate.sites.to_mission(nate.p_s, nate.sites.current.index)
        hga_true = hga_predicted = math.nan
        if isinstance(command, cmd.HgaPass) and report.status != "refused":
            hga_true = float(report.details.get("hga_min_margin_deg", math.nan))
            predicted = [
                d.hga_margin_predicted_deg
                for d in session.downlinks[first_frame:]
                if math.isfinite(d.hga_margin_predicted_deg)
            ]
            hga_predicted = float(min(predicted)) if predicted else math.nan
        reason = report.reason
        if report.status == "halted":  # the check's name: the risk table groups halts by it
            reason = str(report.details.get("halt", {}).get("check", reason))
        yaw_true = Rotation.from_quat(state.q_s_b).as_euler("ZYX")[0]
        return StepOutcome(
            line=line,
            command=command.describe(),
            status=report.status,
            reason=reason,
            start_t_s=float(report.start_t_s),
            end_t_s=float(report.end_t_s),
            p_mission_true_m=(float(state.p_s[0]), float(state.p_s[1])),
            p_mission_est_m=(float(p_est[0]), float(p_est[1])),
            heading_true_rad=float(yaw_true),
            heading_est_rad=heading_of(nate.q_b_ll),
            max_tilt_true_deg=float(np.max(tilt_deg(q_all))),
            aqf=nate.aqf.paper_name,
            imu_integration_s=float(nate.imu_integration_s),
            position_sigma_m=float(session.loop.protection.uncertainty.sigma_m),
            hga_margin_deg=hga_true,
            hga_margin_predicted_deg=hga_predicted,
            keepouts_entered=tuple(zones),
            path_true_m=tuple((float(n), float(e)) for n, e in thinned_path(path)),
        )


def not_run(line: int, command: cmd.Command) -> StepOutcome:
    """A step an earlier step's refusal or halt kept from running."""
    nan = math.nan
    return StepOutcome(
        line,
        command.describe(),
        "not_run",
        None,
        nan,
        nan,
        _NAN2,
        _NAN2,
        nan,
        nan,
        nan,
        "",
        nan,
        nan,
    )


def run_once(inputs: RehearsalInputs, run_index: int, campaign_seed: int) -> RunOutcome:
    """One run of ``inputs.sequence_text`` on the world ``run_index`` of the campaign
    ``campaign_seed`` (module docstring). ``SequenceError`` if the text does not parse."""
    if not isinstance(inputs, RehearsalInputs):
        raise ValueError(f"inputs: must be a RehearsalInputs, got {type(inputs).__name__}")
    wall = time.perf_counter()
    sequence = parse(inputs.sequence_text)
    seeds = RunSeeds.of(campaign_seed, run_index)
    run = Rehearsal(inputs, seeds)
    steps: list[StepOutcome] = []
    stopped = False
    for step in sequence.steps:
        if stopped:
            steps.append(not_run(step.line, step.command))
            continue
        outcome = run.step(step.line, step.command, step.time_tag)
        steps.append(outcome)
        stopped = outcome.status in ("refused", "halted")
    start = run.true_start
    return RunOutcome(
        run_index=int(run_index),
        seed=int(campaign_seed),
        steps=tuple(steps),
        wall_s=time.perf_counter() - wall,
        worker=f"{socket.gethostname()}:{os.getpid()}",
        extra={
            "start_true_m": list(start.p_mission_m),
            "start_yaw_true_rad": start.yaw_rad,
            "friction_deg": run.soil.friction_angle_deg,
            "cohesion_kpa": run.soil.cohesion_kpa,
        },
    )
