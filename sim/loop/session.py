"""A rover session: the flight software in the loop on the simulated rover, command by command.

docs/DESIGN.md, "One control cycle": ``sim`` advances the truth and makes the measurements, the
sequencer hands the next command to the flight software when the previous one completes,
SAPP's NATE (``estimation.sapp.nate``) steps on the measurements, and a telemetry frame puts the
estimate beside the truth with the derived figures (HGA pointing error and margin, position
and attitude error). ``RoverSession.run`` executes a list of typed commands
(``sequences.commands``) in order; each yields a ``CommandReport``.

How time passes. Motion runs at 8 Hz: a drive's truth and sensor samples are made as a
batch (``sim.loop.rover_sim``) and NATE steps through them one cycle at a time with the encoders.
NATE's 8 Hz modes (Nadir Update and Check, Articulate, the Sungaze gravity window) get every
8 Hz sample. A camera mode waits for its image: the session jumps the clock to the requested
time with one aggregated IMU sample, renders the Pancam frame at the commanded mast pointing
from the truth (``RoverSim.pancam_sun_image``), and steps NATE with both. Gyrocompassing and
Idle waits are jumped over the same way. NATE's clock and the simulator's advance together
(every sample's ``dt``).

Commands are refused, with the reason and nothing changed, when NATE refuses them (wrong
mode, out-of-range parameter, the sun too low) or when the simulator does (a drive outside
its limits). The HGA figures in every frame are those of an HGA pointed at that moment from
the onboard estimate and IVP's Earth (``estimation.sapp.hga_pointing``), scored against the truth
(``sim.rover.hga``): during an HGA pass that is the antenna's real error, and at other times the
error it would have. Earth's direction is computed every ``EARTH_NODE_S`` of simulated time
and interpolated linearly in between (normalised): over a minute its path bends by far
less than a microradian from the chord.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from datetime import datetime
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from estimation.events import Event, Severity
from estimation.ivp import earth_ll
from estimation.sapp.aqf import AttitudeQuality
from estimation.sapp.hga_pointing import point_hga
from estimation.sapp.nate import (
    DriveCommand,
    EncoderSample,
    ImuSample,
    Nate,
    NateMode,
    NateOutput,
    NateParams,
)
from estimation.sapp.pointing_knowledge import PointingKnowledge
from estimation.sapp.sun_modes import SunResult
from estimation.sapp.wheel_odometry import DriveKind, steer_six
from estimation.vo.odometry import VisualOdometry
from sequences import commands as cmd
from sim.errors import InputError
from sim.loop.rover_sim import RoverSim, Segment
from sim.loop.side.kinematic import (
    ESTIMATORS,
    DriveInputs,
    KinematicEkfRunner,
    SideEstimate,
    SideRunner,
)
from sim.loop.side.radio import RadioEkfRunner
from sim.loop.telemetry import TelemetryFrame
from sim.loop.vo_drive import (
    VO_MAST_AZ_RAD,
    VO_MAST_EL_RAD,
    VO_RIG,
    EstimatedPose,
    VoDriveOptions,
    corrected_pose,
    predicted_motion,
    split_drive,
    update_text,
)
from sim.rover.hga import hga_pointing_truth
from sim.rover.truth import CONTROL_DT_S
from sim.sensors.imu import ImuSamples, Ln200Params
from sim.world.local_level import q_ll_b_from_site
from sim.world.mars_frames import earth_ll_truth, elevation_rad, sun_ll_truth
from sim.world.marsclock import lmst_h_from_t_s, sol_number_t_s

FloatArray = NDArray[np.float64]
VoDrive = cmd.DriveStraight | cmd.DriveArc | cmd.TurnInPlace | cmd.DriveTo

EARTH_NODE_S = 60.0  # see the module docstring
HGA_FRAME_S = 60.0  # one frame a minute during an Idle HGA pass
WAIT_CHUNK_S = 600.0  # 8 Hz waits are simulated in chunks of this length


@dataclass
class CommandReport:
    """What a command did: ``status`` is ``completed``, ``refused`` (nothing changed;
    ``reason`` says why) or ``failed`` (it ran and its mode failed; ``reason``)."""

    command: str
    status: str
    start_t_s: float
    end_t_s: float
    reason: str | None = None
    events: list[Event] = field(default_factory=list)
    details: dict[str, Any] = field(default_factory=dict)
    results: list[Any] = field(default_factory=list)


def _name_a_failed_suncheck(details: dict[str, Any], results: list[Any]) -> None:
    """SUNCHECK_SUNGAZE's result names its Suncheck's failure (Ali et al. 2005 sec. 4's
    practice, ``estimation.sapp.nate``): out of tolerance, the command goes on to Sungaze and,
    if Sungaze converges, completes (its purpose, a Fine attitude, is reached; the Suncheck
    only pointed the camera) with ``details["suncheck"]`` saying how far off the estimate
    was; with no sun in the image, it fails with that as its reason."""
    check = results[0] if results else None
    if not isinstance(check, SunResult) or check.success:
        return
    said = f"Suncheck failed: {check.outcome.value}"
    if math.isfinite(check.error_rad):
        said += f" (error {math.degrees(check.error_rad):.2f} deg)"
    if len(results) > 1:
        details["suncheck"] = f"{said}; Sungaze ran on the sun it saw"
    else:
        details["failure"] = f"{said}; Sungaze not run, AQF {details['aqf']}"


class CommandRefusedError(Exception):
    """A command refused before it changed anything."""


class RoverSession:
    """A rover at a site with SAPP in the loop. Arguments as ``RoverSim`` (the rover's
    placement, IMU and slip) plus NATE's parameters, and ``frame_every_s``: keep one
    telemetry frame per that many seconds of 8 Hz data (0: every cycle; frames with events
    or a mode change are always kept); ``vo_options``: the step limits and imaging of
    ``vo=on`` drives (``sim.loop.vo_drive.VoDriveOptions``; MER's by default)."""

    def __init__(
        self,
        site_name: str,
        seed: int,
        start_utc: datetime,
        *,
        imu_params: Ln200Params | None = None,
        slip: bool = True,
        yaw_rad: float = 0.0,
        x_m: float = 0.0,
        y_m: float = 0.0,
        mast_bias_sigma_deg: float = 0.05,
        nate_params: NateParams | None = None,
        frame_every_s: float = 0.0,
        vo_options: VoDriveOptions | None = None,
        estimators: Sequence[str] = ("sapp",),
    ) -> None:
        if not (math.isfinite(frame_every_s) and frame_every_s >= 0.0):
            raise InputError("frame_every_s", "must be finite and non-negative")
        if vo_options is not None and not isinstance(vo_options, VoDriveOptions):
            raise InputError("vo_options", f"must be a VoDriveOptions, got {vo_options!r}")
        self.vo_options = vo_options if vo_options is not None else VoDriveOptions()
        self.sim = RoverSim(
            site_name,
            seed,
            start_utc,
            imu_params=imu_params,
            slip=slip,
            yaw_rad=yaw_rad,
            x_m=x_m,
            y_m=y_m,
            mast_bias_sigma_deg=mast_bias_sigma_deg,
        )
        sim = self.sim
        self.nate = Nate(sim.lat_rad, sim.lon_east_rad, sim.t_s, nate_params)
        self.frames: list[TelemetryFrame] = []
        self.reports: list[CommandReport] = []
        self.frame_every_s = frame_every_s
        self._lon_west_deg = (360.0 - sim.site.lon_east_deg) % 360.0
        self._site_origins_true: list[FloatArray] = [sim.state.p_s.copy()]  # mission frame
        self._command = ""
        self._events: list[Event] = []
        unknown = [e for e in estimators if e not in ESTIMATORS]
        if unknown or "sapp" not in estimators:
            raise InputError(
                "estimators", f"must include sapp, from {', '.join(ESTIMATORS)}; got {estimators!r}"
            )
        self.side: list[SideRunner] = []
        if "kinematic_ekf" in estimators:
            self.side.append(KinematicEkfRunner(sim, seed))
        if "radio_ekf" in estimators:
            self.side.append(RadioEkfRunner(sim, seed, x_m, y_m))
        self._side_now: dict[str, tuple[FloatArray, FloatArray | None]] | None = None
        self._vo: VisualOdometry | None = None  # made at the first vo=on drive
        self._vo_failures_in_row = 0
        self._knowledge = PointingKnowledge()
        self._last_frame_t = -math.inf
        self._last_mode = ""
        self._sky_t0 = math.nan  # interpolation node: Earth (IVP, truth), sun at t0, t0 + node
        self._sky_nodes = np.zeros((3, 2, 3))

    # ---- the sequencer ------------------------------------------------------------

    def run(self, commands: Iterable[cmd.Command]) -> list[CommandReport]:
        """Execute ``commands`` in order (each when the previous completes)."""
        return [self.execute(c) for c in commands]

    def execute(self, command: cmd.Command, label: str | None = None) -> CommandReport:
        """Execute one command to completion and report it. ``label`` replaces the
        command's text in the telemetry frames (``""`` for a wait no operator commanded)."""
        if not isinstance(command, cmd.Command):
            raise InputError("command", f"must be a sequences.commands.Command, got {command!r}")
        self._command = command.describe() if label is None else label
        report = CommandReport(self._command, "completed", self.sim.t_s, self.sim.t_s)
        first_frame = len(self.frames)
        self._results: list[Any] = []
        try:
            details = self._dispatch(command)
        except (CommandRefusedError, ValueError, InputError) as exc:
            report.status, report.reason = "refused", str(exc)
            self._events.append(Event(f"{command.name} refused: {exc}", "command", "error"))
            self._frame_now(force=True)
        else:
            report.details = details
            failure = details.pop("failure", None)
            if failure:
                report.status, report.reason = "failed", str(failure)
        report.end_t_s = self.sim.t_s
        report.results = self._results
        report.events = [e for f in self.frames[first_frame:] for e in f.events]
        self.reports.append(report)
        self._command = ""
        return report

    def _dispatch(self, c: cmd.Command) -> dict[str, Any]:
        nate = self.nate
        if isinstance(c, cmd.DriveStraight):
            return self._move(DriveCommand(DriveKind.STRAIGHT), "straight", (c.distance_m,), c)
        if isinstance(c, cmd.DriveArc):
            arc = (c.radius_m, math.radians(c.angle_deg))
            return self._move(DriveCommand(DriveKind.ARC, c.radius_m), "arc", arc, c)
        if isinstance(c, cmd.TurnInPlace):
            drive = DriveCommand(DriveKind.TURN_IN_PLACE)
            return self._move(drive, "turn", (math.radians(c.angle_deg),), c)
        if isinstance(c, cmd.DriveTo):
            return self._drive_to(c)
        if isinstance(c, cmd.PlantSite):
            index = nate.plant_site()
            self._site_origins_true.append(self.sim.state.p_s.copy())
            self._events.append(Event(f"Site {index} planted", "site"))
            self._frame_now(force=True)
            return {"site_index": index}
        if isinstance(c, cmd.SetParam):
            nate.set_param(c.param, c.value)
            self._events.append(Event(f"parameter {c.param} = {c.value}", "parameter"))
            self._frame_now(force=True)
            return {}
        if isinstance(c, cmd.ArticulateStart):
            nate.articulate()
            self._frame_now(force=True)
            return {}
        if isinstance(c, cmd.ArticulateStop):
            nate.stop()
            self._frame_now(force=True)
            return {}
        if isinstance(c, cmd.Wait):
            self._wait(c.duration_s)
            return {}
        if isinstance(c, cmd.HgaPass):
            return self._hga_pass(c.duration_min * 60.0)
        self._start_acquisition(c)
        details = self._run_until_idle()
        if isinstance(c, cmd.SuncheckSungaze):
            _name_a_failed_suncheck(details, self._results)
        return details

    def _start_acquisition(self, c: cmd.Command) -> None:
        nate = self.nate
        if isinstance(c, cmd.NadirUpdate):
            nate.nadir_update(c.window_s)
        elif isinstance(c, cmd.NadirCheck):
            nate.nadir_check(c.window_s, c.tolerance_deg)
        elif isinstance(c, cmd.Sunfind):
            nate.sunfind()
        elif isinstance(c, cmd.Suncheck):
            nate.suncheck(c.tolerance_deg)
        elif isinstance(c, cmd.Sungaze):
            nate.sungaze(c.use_gravity)
        elif isinstance(c, cmd.GetTiltAttitude):
            nate.get_tilt_attitude()
        elif isinstance(c, cmd.GetCoarseAttitude):
            nate.get_coarse_attitude()
        elif isinstance(c, cmd.GetFineAttitude):
            nate.get_fine_attitude()
        elif isinstance(c, cmd.SuncheckSungaze):
            nate.suncheck_sungaze()
        elif isinstance(c, cmd.Gyrocompass):
            nate.gyrocompass(c.duration_s)
        else:  # pragma: no cover - every command class is dispatched above
            raise CommandRefusedError(f"{c.name}: not implemented by the session")

    # ---- running NATE -------------------------------------------------------------

    def _run_until_idle(self) -> dict[str, Any]:
        """Feed NATE until the acquisition, check or gyrocompass it started has ended."""
        nate, sim = self.nate, self.sim
        aqf_before = nate.aqf
        results: list[Any] = []
        while nate.busy:
            request = nate.camera_request
            hint = nate.wait_hint_s
            if request is not None:
                samples = sim.rest(max(hint, CONTROL_DT_S))  # slew, expose: one cycle at least
                image = sim.pancam_sun_image(request.az_rad, request.el_rad).image
                out = nate.step(_imu(samples, 0), image=image)
                results += [out.completed] if out.completed is not None else []
                self._frame(out, force=True)
            elif hint <= CONTROL_DT_S:
                samples = sim.rest_cycles(1.0)
                for k in range(len(samples)):
                    out = nate.step(_imu(samples, k))
                    results += [out.completed] if out.completed is not None else []
                    self._frame(out, force=out.completed is not None)
            else:
                out = nate.step(_imu(sim.rest(hint), 0))
                results += [out.completed] if out.completed is not None else []
                self._frame(out, force=True)
        details: dict[str, Any] = {"aqf_before": aqf_before.paper_name, "aqf": nate.aqf.paper_name}
        self._results = results
        if results and not results[-1].success:
            details["failure"] = self._last_event() or "the mode failed"
        return details

    def _last_event(self) -> str:
        for frame in reversed(self.frames):
            if frame.events:
                return frame.events[-1].text
        return ""

    def _wait(self, duration_s: float) -> None:
        """Let time pass; Articulate keeps propagating at 8 Hz, Idle is jumped over."""
        nate, sim = self.nate, self.sim
        if nate.busy:
            raise CommandRefusedError(f"WAIT: refused while {nate.mode.value} runs")
        if nate.wait_hint_s > CONTROL_DT_S:  # Idle: one jump
            out = nate.step(_imu(sim.rest(duration_s), 0))
            self._frame(out, force=True)
            return
        remaining = duration_s
        while remaining > 1e-9:
            chunk = min(WAIT_CHUNK_S, remaining)
            samples = sim.rest_cycles(chunk)
            for k in range(len(samples)):
                self._frame(nate.step(_imu(samples, k)))
            remaining -= chunk

    def _hga_pass(self, duration_s: float) -> dict[str, Any]:
        nate, sim = self.nate, self.sim
        if nate.busy:
            raise CommandRefusedError(f"HGA_PASS: refused while {nate.mode.value} runs")
        earth = earth_ll(sim.t_s, sim.lat_rad, sim.lon_east_rad)
        if not point_hga(nate.q_b_ll, earth).earth_above_horizon:
            raise CommandRefusedError(
                "HGA_PASS: Earth is below the horizon (IVP): no link possible"
            )
        if nate.aqf < AttitudeQuality.FINE:
            text = f"HGA pass with AQF {nate.aqf.paper_name}: pointing not assured"
            self._events.append(Event(text, "hga", "warning"))
        first = len(self.frames)
        self._frame_now(force=True)
        end = sim.t_s + duration_s
        while sim.t_s < end - 1e-9:
            step = min(HGA_FRAME_S, end - sim.t_s)
            if nate.wait_hint_s > CONTROL_DT_S:
                self._frame(nate.step(_imu(sim.rest(step), 0)), force=True)
            else:
                samples = sim.rest_cycles(step)
                for k in range(len(samples)):
                    self._frame(nate.step(_imu(samples, k)))
        frames = self.frames[first:]
        errors = [f.hga_error_deg for f in frames if f.earth_up]
        worst = max(errors) if errors else math.nan
        margin = 2.0 - worst
        earth_set = len(errors) != len(frames)
        text = f"HGA pass: worst error {worst:.2f} deg, margin {margin:.2f} deg" + (
            ", Earth set during the pass" if earth_set else ""
        )
        severity: Severity = "error" if margin < 0.0 else "warning" if earth_set else "info"
        self.frames[-1].events.append(Event(text, "hga", severity))
        out: dict[str, Any] = {"hga_worst_error_deg": worst, "hga_min_margin_deg": margin}
        if margin < 0.0:
            out["failure"] = f"HGA margin gone: worst error {worst:.2f} deg > 2 deg"
        return out

    def _drive(self, drive: DriveCommand, kind: str, *args: float) -> dict[str, Any]:
        nate, sim = self.nate, self.sim
        wheel0 = sim.wheel_angle_rad_now()
        if nate.mode is not NateMode.IDLE:  # checked before the rover moves
            raise CommandRefusedError(f"mobility: refused in mode {nate.mode.value}")
        if kind == "straight":  # the simulator refuses bad sizes before anything moves
            seg = sim.drive_straight(args[0])
        elif kind == "arc":
            seg = sim.drive_arc(args[0], args[1])
        else:
            seg = sim.turn_in_place(args[0])
        start = self._mission_estimate()
        nate.mobility(drive, wheel_angle_rad=wheel0)
        outputs = self._step_segment(seg)
        nate.stop()
        side = self._side_drive(seg, kind, args, start, outputs)
        self._segment_frames(seg, outputs, side)
        self._frame_now(force=True)
        distance = float(np.sum(np.linalg.norm(np.diff(seg.truth.p_s, axis=0), axis=1)))
        return {"distance_truth_m": distance}

    def _move(
        self, drive: DriveCommand, kind: str, args: tuple[float, ...], c: VoDrive
    ) -> dict[str, Any]:
        """A drive primitive, stepped with visual odometry when the command says ``vo``."""
        if c.vo:
            return self._drive_vo(drive, kind, args, attitude=bool(c.vo_attitude))
        return self._drive(drive, kind, *args)

    def _drive_vo(
        self, drive: DriveCommand, kind: str, args: tuple[float, ...], attitude: bool
    ) -> dict[str, Any]:
        """A drive in VO steps (``sim.loop.vo_drive``): a Navcam pair before the first step and
        after each, SAPP's pose updated from each converged VO step."""
        nate = self.nate
        if nate.mode is not NateMode.IDLE:  # checked before the rover moves
            raise CommandRefusedError(f"mobility: refused in mode {nate.mode.value}")
        steps = split_drive(kind, args, self._vo_drive_options())
        vo = self._visual_odometry()
        vo.reset()
        before = self._estimate()
        self._vo_step(vo, before, before, 0, len(steps), attitude)  # the first pair
        distance = 0.0
        updates = 0
        for i, step in enumerate(steps, start=1):
            distance += self._drive(drive, kind, *step)["distance_truth_m"]
            after = self._estimate()
            updates += self._vo_step(vo, before, after, i, len(steps), attitude)
            self._wait(cmd.VO_PROCESSING_S)  # the rover stands while VO computes
            self._frame_now(force=True)
            before = self._estimate()
        vo.reset()  # the last pair's images are not needed again (and checkpoints stay small)
        return {
            "distance_truth_m": distance,
            "vo_steps": len(steps),
            "vo_updates": updates,
            "vo_failures": len(steps) - updates,
        }

    def _vo_step(
        self,
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
            pair = self.sim.navcam_pair(
                VO_MAST_AZ_RAD,
                VO_MAST_EL_RAD,
                rig=VO_RIG,
                rover_shadow=self._vo_drive_options().rover_shadow,
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
            self._vo_failed(step)
            text = f"VO step {step}/{steps} failed: {exc}; wheel odometry kept"
            self._events.append(Event(text, "vo", "warning"))
            return 0
        if step == 0:
            return 0  # the first pair: nothing to compare with yet
        if not result.converged or result.motion is None:
            self._vo_failed(step)
            text = f"VO step {step}/{steps} failed: {result.reason}; wheel odometry kept"
            self._events.append(Event(text, "vo", "warning"))
            return 0
        self._vo_failures_in_row = 0
        p_s, q_b_ll = corrected_pose(before, result.motion)
        self.nate.visual_odometry_update(p_s, q_b_ll if attitude else None)
        text = update_text(step, steps, p_s - after.p_s, result.n_inliers, result.n_tracked)
        self._events.append(Event(text, "vo"))
        return 1

    def _vo_failed(self, step: int) -> None:
        """Count a failed VO step (the first pair of a drive is not a step)."""
        if step > 0:
            self._vo_failures_in_row = getattr(self, "_vo_failures_in_row", 0) + 1

    def set_visual_odometry(self, vo: VisualOdometry) -> None:
        """Run ``vo=on`` drives with ``vo`` (a benchmark's wrapper that records each step,
        or other parameters); it must image through ``VO_RIG``."""
        if not isinstance(vo, VisualOdometry) or vo.rig != VO_RIG:
            raise InputError("vo", "must be a VisualOdometry on sim.loop.vo_drive.VO_RIG")
        self._vo = vo

    def _vo_drive_options(self) -> VoDriveOptions:
        options: VoDriveOptions | None = getattr(self, "vo_options", None)
        return options if options is not None else VoDriveOptions()  # an older checkpoint

    def _visual_odometry(self) -> VisualOdometry:
        vo: VisualOdometry | None = getattr(self, "_vo", None)  # None also in a session
        if vo is None:  # checkpointed before VO existed
            vo = self._vo = VisualOdometry(VO_RIG)
        return vo

    def _estimate(self) -> EstimatedPose:
        return EstimatedPose(self.nate.p_s, self.nate.q_b_ll)

    def _drive_to(self, c: cmd.DriveTo) -> dict[str, Any]:
        """DRIVE_TO: turn towards the goal and drive to it, both by NATE's estimate. A
        turn in place slips and creeps, so the aim is taken again after it (twice at
        most) before the straight drive."""
        x_m, y_m = c.x_m, c.y_m
        nate = self.nate
        if nate.mode is not NateMode.IDLE:
            raise CommandRefusedError(f"DRIVE_TO: refused in mode {nate.mode.value}")
        turn, distance = self._aim(x_m, y_m)
        if not 0.01 <= distance <= cmd.MAX_DRIVE_M:
            raise CommandRefusedError(
                f"DRIVE_TO: the goal is {distance:.2f} m from the estimated position "
                f"(0.01-{cmd.MAX_DRIVE_M:g} m)"
            )
        details: dict[str, Any] = {"turn_deg": math.degrees(turn), "distance_m": distance}
        for _ in range(2):
            if abs(turn) <= math.radians(0.5):  # close enough for the straight drive
                break
            self._move(DriveCommand(DriveKind.TURN_IN_PLACE), "turn", (turn,), c)
            turn, distance = self._aim(x_m, y_m)
        if distance >= 0.01:
            out = self._move(DriveCommand(DriveKind.STRAIGHT), "straight", (distance,), c)
            details["distance_truth_m"] = out["distance_truth_m"]
        return details

    def _aim(self, x_m: float, y_m: float) -> tuple[float, float]:
        """Turn (rad, > 0 clockwise) and distance (m) to the goal by the estimate."""
        nate = self.nate
        d_n, d_e = x_m - float(nate.p_s[0]), y_m - float(nate.p_s[1])
        x_ll = Rotation.from_quat(nate.q_b_ll).inv().apply([1.0, 0.0, 0.0])  # body x in LL
        heading = math.atan2(float(x_ll[1]), float(x_ll[0]))
        turn = (math.atan2(d_e, d_n) - heading + math.pi) % (2.0 * math.pi) - math.pi
        return turn, math.hypot(d_n, d_e)

    def _step_segment(self, seg: Segment) -> list[NateOutput]:
        wheel = self.sim.encoders.wheel_angle_rad(seg.encoders.wheel_counts)
        steer = seg.encoders.steer_rad
        outputs = []
        for k in range(len(seg.imu)):
            enc = EncoderSample(wheel[k + 1], steer_six(steer[k + 1]))
            outputs.append(self.nate.step(_imu(seg.imu, k), enc))
        return outputs

    # ---- telemetry ----------------------------------------------------------------

    def _sky(self, t_s: float) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Earth in LL at ``t_s`` from IVP and from the truth, and the true sun in LL
        (module docstring: interpolated between nodes ``EARTH_NODE_S`` apart)."""
        u = (t_s - self._sky_t0) / EARTH_NODE_S
        if not 0.0 <= u <= 1.0:
            sim = self.sim
            self._sky_t0, u = t_s, 0.0
            nodes = np.array([t_s, t_s + EARTH_NODE_S])
            self._sky_nodes = np.stack(
                [
                    earth_ll(nodes, sim.lat_rad, sim.lon_east_rad),
                    earth_ll_truth(nodes, sim.lat_rad, sim.lon_east_rad),
                    sun_ll_truth(nodes, sim.lat_rad, sim.lon_east_rad),
                ]
            )
        v = (1.0 - u) * self._sky_nodes[:, 0] + u * self._sky_nodes[:, 1]
        v /= np.linalg.norm(v, axis=1, keepdims=True)
        return v[0], v[1], v[2]

    def _keep(self, out: NateOutput, force: bool) -> bool:
        return (
            force
            or bool(out.events)
            or bool(self._events)
            or out.mode.value != self._last_mode
            or out.t_s - self._last_frame_t >= self.frame_every_s - 1e-9
        )

    def _frame(self, out: NateOutput, force: bool = False) -> None:
        """A frame for the rover at rest now (truth from the simulator's state)."""
        if not self._keep(out, force):
            return
        sim = self.sim
        state = sim.state
        joints = (state.rocker_rad, state.bogie_rad, state.steer_rad)
        self._append(out, sim.q_ll_b(), state.p_s.copy(), joints)

    def _frame_now(self, force: bool = False) -> None:
        """A frame of the current state without a NATE cycle (after a command)."""
        nate = self.nate
        out = NateOutput(
            q_b_ll=nate.q_b_ll,
            tilt_est_deg=math.nan,
            tilt_accel_deg=math.nan,
            p_s=nate.p_s,
            site_index=nate.sites.current.index,
            aqf=nate.aqf,
            mode=nate.mode,
            imu_integration_s=nate.imu_integration_s,
            gyro_counter_s=nate.gyro_counter_s,
            t_s=nate.t_s,
        )
        self._frame(out, force)

    def _mission_estimate(self) -> tuple[FloatArray, FloatArray]:
        """SAPP's ``(p_mission, q_b_ll)`` now (where a side estimator starts)."""
        nate = self.nate
        p_mission: FloatArray = nate.sites.to_mission(nate.p_s, nate.sites.current.index)
        return p_mission, nate.q_b_ll

    def _side_drive(
        self,
        seg: Segment,
        kind: str,
        args: tuple[float, ...],
        start: tuple[FloatArray, FloatArray],
        outputs: Sequence[NateOutput],
    ) -> dict[str, SideEstimate]:
        """The side estimators through a drive segment (``sim.loop.side.kinematic``); ``start``
        SAPP's pose before it and ``outputs`` its cycles through it."""
        if not self.side:
            return {}
        inputs = DriveInputs(
            kind=kind,
            args=args,
            wheel_rad=self.sim.encoders.wheel_angle_rad(seg.encoders.wheel_counts),
            steer_rad=seg.encoders.steer_rad,
            start=start,
            sapp_q_b_ll=np.array([start[1], *(o.q_b_ll for o in outputs)]),
        )
        out: dict[str, SideEstimate] = {}
        for runner in list(self.side):
            try:
                out[runner.name] = runner.drive(seg, inputs)
            except ValueError as exc:  # InputError and numpy's LinAlgError are ValueErrors
                # The rover has driven and SAPP has its result: a comparison estimator that
                # fails must not turn the drive into a refusal. It stops, and says why.
                self.side.remove(runner)
                self._events.append(Event(f"{runner.name} stopped: {exc}", "estimator", "warning"))
        return out

    def _segment_frames(
        self, seg: Segment, outputs: Sequence[NateOutput], side: dict[str, SideEstimate]
    ) -> None:
        sim = self.sim
        traj = seg.truth
        q_ll_b = q_ll_b_from_site(traj.q_s_b, traj.p_s, sim.lat_rad, sim.lon_east_rad)
        for k, out in enumerate(outputs):
            if self._keep(out, False):
                i = k + 1
                self._side_now = {
                    n: (e.p_mission[i], None if e.q_b_ll is None else e.q_b_ll[i])
                    for n, e in side.items()
                }
                joints = (float(traj.rocker_rad[i]), traj.bogie_rad[i], traj.steer_rad[i])
                self._append(out, q_ll_b[i], traj.p_s[i], joints)
        self._side_now = None

    def _append(
        self,
        out: NateOutput,
        q_ll_b_true: FloatArray,
        p_world: FloatArray,
        joints: tuple[float, FloatArray, FloatArray],
    ) -> None:
        """Append a frame; ``p_world`` is the truth position in the simulator's frame, whose
        offset from the first Site's origin (the start) is the true mission position;
        ``joints`` the true (rocker, bogie (2,), steering (4,)) angles, rad."""
        sim, nate = self.sim, self.nate
        p_mission_true = p_world - self._site_origins_true[0]
        t = out.t_s
        q_b_ll_true = Rotation.from_quat(q_ll_b_true).inv()
        earth_ivp, earth_true, sun_true = self._sky(t)
        hga_command = point_hga(out.q_b_ll, earth_ivp)
        hga = hga_pointing_truth(hga_command, q_b_ll_true.as_quat(), earth_true)
        boresight_ll = q_b_ll_true.inv().apply(hga_command.boresight_b)
        rocker_rad, bogie_rad, steer_rad = joints
        p_mission_est = nate.sites.to_mission(out.p_s, out.site_index)
        origin = self._site_origins_true[min(out.site_index, len(self._site_origins_true) - 1)]
        att_err = (Rotation.from_quat(out.q_b_ll) * q_b_ll_true.inv()).magnitude()
        events = list(out.events) + self._events
        self._events = []
        knowledge: PointingKnowledge | None = getattr(self, "_knowledge", None)
        if knowledge is None:  # a checkpoint from before it: from the flag on
            knowledge = self._knowledge = PointingKnowledge()
        done = out.completed
        sungaze = (
            math.degrees(done.three_sigma_rad)
            if isinstance(done, SunResult) and done.success and done.updated
            else None
        )
        predicted = knowledge.update(out.aqf, out.imu_integration_s, sungaze)
        self.frames.append(
            TelemetryFrame(
                t_s=t,
                sol=int(sol_number_t_s(sim.site.mission, t)),
                lmst_h=float(lmst_h_from_t_s(t, self._lon_west_deg)),
                nate_mode=out.mode.value,
                aqf=out.aqf.paper_name,
                q_b_ll_est=[float(v) for v in out.q_b_ll],
                q_b_ll_true=[float(v) for v in q_b_ll_true.as_quat()],
                p_s_est=[float(v) for v in out.p_s],
                p_s_true=[float(v) for v in p_world - origin],
                site_index=out.site_index,
                p_mission_est=[float(v) for v in p_mission_est],
                p_mission_true=[float(v) for v in p_mission_true],
                imu_integration_s=out.imu_integration_s,
                gyro_counter_s=out.gyro_counter_s,
                tilt_est_deg=out.tilt_est_deg,
                tilt_accel_deg=out.tilt_accel_deg,
                hga_error_deg=hga.error_deg,
                hga_margin_deg=hga.margin_deg,
                earth_up=bool(elevation_rad(earth_true) > 0.0),
                attitude_error_deg=math.degrees(float(att_err)),
                position_error_m=float(np.linalg.norm(p_mission_est - p_mission_true)),
                command=self._command,
                rocker_deg=math.degrees(rocker_rad),
                bogie_deg=[math.degrees(float(v)) for v in bogie_rad],
                steer_deg=[math.degrees(float(v)) for v in steer_rad],
                sun_ll_true=[float(v) for v in sun_true],
                earth_ll_true=[float(v) for v in earth_true],
                hga_boresight_ll_true=[float(v) for v in boresight_ll],
                events=events,
                estimators=self._side_estimates(t, p_mission_true, q_b_ll_true),
                vo_failures_in_row=getattr(self, "_vo_failures_in_row", 0),
                hga_margin_predicted_deg=predicted,
            )
        )
        self._last_frame_t = t
        self._last_mode = out.mode.value

    # ---- truth for benchmarks and tests -------------------------------------------

    def _side_estimates(
        self, t_s: float, p_mission_true: FloatArray, q_b_ll_true: Rotation
    ) -> dict[str, Any]:
        """Each side estimator's pose in this frame and its errors against the truth."""
        out: dict[str, Any] = {}
        for runner in self.side:
            if self._side_now is None:  # at rest, up to this frame's time (the simulator
                runner.rest_until(t_s, self.sim.state.p_s)  # may have run a chunk ahead)
                now = runner.estimate_now()
            else:
                now = self._side_now.get(runner.name)
            if now is None:
                continue  # not started: it starts at the first drive
            p, q = now
            att = None if q is None else (Rotation.from_quat(q) * q_b_ll_true.inv()).magnitude()
            out[runner.name] = {  # position-only estimators have no attitude (None)
                "p_mission": [float(v) for v in p],
                "q_b_ll": None if q is None else [float(v) for v in q],
                "position_error_m": float(np.linalg.norm(p - p_mission_true)),
                "attitude_error_deg": None if att is None else math.degrees(float(att)),
            }
        return out

    @property
    def mission_origin_world(self) -> FloatArray:
        """The mission frame's origin (the first Site's, where the rover started) in the
        simulator's frame (truth; for drawing the terrain in mission coordinates)."""
        return self._site_origins_true[0].copy()

    def attitude_error_rad(self) -> float:
        """Angle between NATE's estimate and the truth now, rad."""
        q_b_ll_true = Rotation.from_quat(self.sim.q_ll_b()).inv()
        return float((Rotation.from_quat(self.nate.q_b_ll) * q_b_ll_true.inv()).magnitude())

    def q_b_ll_true(self) -> FloatArray:
        """The true ``q_b_ll`` now, (4,)."""
        out: FloatArray = Rotation.from_quat(self.sim.q_ll_b()).inv().as_quat()
        return out


def _imu(samples: ImuSamples, k: int) -> ImuSample:
    return ImuSample(samples.delta_angle_b[k], samples.delta_velocity_b[k], float(samples.dt_s[k]))


def run_commands(
    site_name: str, seed: int, start_utc: datetime, commands: Sequence[cmd.Command], **kwargs: Any
) -> tuple[RoverSession, list[CommandReport], float]:
    """A session that runs ``commands``; returns it, the reports and the wall time, s."""
    wall = time.perf_counter()
    session = RoverSession(site_name, seed, start_utc, **kwargs)
    reports = session.run(commands)
    return session, reports, time.perf_counter() - wall
