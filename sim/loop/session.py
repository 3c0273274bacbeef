"""A rover session: the flight software in the loop on the simulated rover, command by command.

docs/DESIGN.md, "One control cycle": ``sim`` advances the truth and makes the measurements, the
sequencer hands the next command to the flight software when the previous one completes,
SAPP's NATE (``estimation.sapp.nate``) steps on the measurements, and each telemetry frame is
two records: the rover's downlink and, beside it, the truth record that scores it.
``RoverSession`` is the sequencer: it runs a list of typed commands (``sequences.commands``)
in order, each through its handler (``sim.loop.handlers.HANDLERS``), and each yields a
``CommandReport``. The loop it runs them on is ``sim.loop.context``; the frames are built in
``sim.loop.frames`` and scored by ``sim.scoring``; the estimators beside SAPP are
``sim.loop.side``.

Commands are refused, with the reason and nothing changed, when NATE refuses them (wrong
mode, out-of-range parameter, the sun too low) or when the simulator does (a drive outside
its limits).

A session's state (``state()``, plain data) is what a checkpoint keeps: loaded onto a session
built from the same arguments (``load_state``), it runs on as the original would have.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from datetime import datetime
from typing import Any, Unpack

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from estimation.events import Event
from estimation.protection.monitor import MobilityProtection
from estimation.sapp.nate import Nate, NateParams
from estimation.vo.odometry import VisualOdometry
from estimation.vo.params import VoParams
from estimation.vo.stereo_rig import StereoRig
from sequences import commands as cmd
from sim.errors import InputError
from sim.faults.plan import FaultPlan
from sim.loop import vo_drive
from sim.loop.context import CommandRefusedError, LoopContext
from sim.loop.downlink import Downlink, DownlinkDict
from sim.loop.drives import set_vo_rig
from sim.loop.frames import FrameRecorder
from sim.loop.handlers import HANDLERS
from sim.loop.rover_sim import Placement, RoverSim
from sim.loop.side.estimators import SideEstimators
from sim.loop.vo_drive import VoDriveOptions
from sim.scoring.truth import Truth, TruthDict

FloatArray = NDArray[np.float64]
VoFactory = Callable[[RoverSim, StereoRig], VisualOdometry]


@dataclass
class CommandReport:
    """What a command did: ``status`` is ``completed``, ``refused`` (nothing changed;
    ``reason`` says why), ``failed`` (it ran and its mode failed; ``reason``) or ``halted``
    (a mobility fault protection stopped the drive: ``reason``, and ``details["halt"]``
    the check and the values that tripped it, ``estimation.protection.halt``). ``events``
    are the rover's (its downlink's), ``scores`` the truth records' (for scoring only)."""

    command: str
    status: str
    start_t_s: float
    end_t_s: float
    reason: str | None = None
    events: list[Event] = field(default_factory=list)
    scores: list[Event] = field(default_factory=list)
    details: dict[str, Any] = field(default_factory=dict)
    results: list[Any] = field(default_factory=list)


def flight_vo(sim: RoverSim, rig: StereoRig) -> VisualOdometry:
    """The flight software's VO on ``rig``, with the parameters for its width (the default
    of ``visual_odometry``)."""
    return VisualOdometry(rig, VoParams().for_width(rig.camera.width_px))


class RoverSession:
    """A rover at a site with SAPP in the loop. Arguments as ``RoverSim`` (the site, seed and
    start, and as keywords the rover's placement, IMU and slip: ``Placement``) plus NATE's
    parameters, and ``frame_every_s``: keep one telemetry frame per that many seconds of
    8 Hz data (0: every cycle; frames with events or a mode change are always kept);
    ``vo_options``: the step limits and imaging of ``vo=on`` drives
    (``sim.loop.vo_drive.VoDriveOptions``; MER's by default); ``vo_rig``: the width of
    their Navcam pairs, 256 (MER's, ``VO_RIG``) or 1024 px (``sim.loop.vo_drive.VO_RIGS``;
    ``SET_PARAM param=vo.rig`` changes it, and a checkpoint keeps it); ``visual_odometry``:
    makes the VO of those drives from the simulator and the rig (a benchmark's wrapper
    that records each step; it must image through the rig it is given; made again when
    the rig changes); ``estimators``: the estimators that run, SAPP and those beside it
    (``sim.loop.side``)."""

    def __init__(
        self,
        site_name: str,
        seed: int,
        start_utc: datetime,
        *,
        nate_params: NateParams | None = None,
        frame_every_s: float = 0.0,
        vo_options: VoDriveOptions | None = None,
        vo_rig: int = 256,
        visual_odometry: VoFactory = flight_vo,
        estimators: Sequence[str] = ("sapp",),
        **placement: Unpack[Placement],
    ) -> None:
        if not (math.isfinite(frame_every_s) and frame_every_s >= 0.0):
            raise InputError("frame_every_s", "must be finite and non-negative")
        if vo_options is not None and not isinstance(vo_options, VoDriveOptions):
            raise InputError("vo_options", f"must be a VoDriveOptions, got {vo_options!r}")
        rig = vo_drive.vo_rig(vo_rig)  # InputError naming vo_rig unless 256 or 1024
        sim = RoverSim(site_name, seed, start_utc, **placement)

        def make_vo(rig: StereoRig) -> VisualOdometry:
            vo = visual_odometry(sim, rig)
            if not isinstance(vo, VisualOdometry) or vo.rig != rig:
                raise InputError("visual_odometry", "must make a VisualOdometry on the rig given")
            return vo

        vo = make_vo(rig)
        nate = Nate(sim.lat_rad, sim.lon_east_rad, sim.t_s, nate_params)
        side = SideEstimators(sim, seed, *sim.start_xy_m, estimators)
        self.loop = LoopContext(
            sim=sim,
            nate=nate,
            recorder=FrameRecorder(sim, nate, side, frame_every_s),
            side=side,
            vo=vo,
            vo_options=vo_options if vo_options is not None else VoDriveOptions(),
            protection=MobilityProtection(sim.lon_east_rad),
            make_vo=make_vo,
        )
        self.loop.recorder.protection = self.loop.protection
        self.reports: list[CommandReport] = []
        self.faults = FaultPlan()  # the conductor's faults, applied as commands start

    # ---- the parts, for the runtime, benchmarks and tests -------------------------------

    @property
    def sim(self) -> RoverSim:
        """The simulated rover (truth and sensors)."""
        return self.loop.sim

    @property
    def nate(self) -> Nate:
        """The flight software's attitude and position estimator."""
        return self.loop.nate

    @property
    def side(self) -> SideEstimators:
        """The estimators beside SAPP."""
        return self.loop.side

    @property
    def downlinks(self) -> list[Downlink]:
        """The rover's frames made so far (a consumer may clear the list once it has them,
        with ``truths``)."""
        return self.loop.recorder.downlinks

    @property
    def truths(self) -> list[Truth]:
        """The truth record of each of ``downlinks`` (the same length, the same times):
        for scoring, never for the ground."""
        return self.loop.recorder.truths

    def take_frames(self) -> list[tuple[DownlinkDict, TruthDict]]:
        """The frames made so far as (downlink, truth) dict pairs, handed over: the lists
        are emptied (a checkpoint stays small)."""
        pairs = [
            (d.as_dict(), t.as_dict()) for d, t in zip(self.downlinks, self.truths, strict=True)
        ]
        del self.downlinks[:], self.truths[:]
        return pairs

    @property
    def vo(self) -> VisualOdometry:
        """The VO of ``vo=on`` drives."""
        return self.loop.vo

    # ---- the sequencer --------------------------------------------------------------------

    def run(self, commands: Iterable[cmd.Command]) -> list[CommandReport]:
        """Execute ``commands`` in order (each when the previous completes)."""
        return [self.execute(c) for c in commands]

    def execute(self, command: cmd.Command, label: str | None = None) -> CommandReport:
        """Execute one command to completion and report it. ``label`` replaces the
        command's text in the telemetry frames (``""`` for a wait no operator commanded)."""
        if not isinstance(command, cmd.Command):
            raise InputError("command", f"must be a sequences.commands.Command, got {command!r}")
        handler = HANDLERS.get(type(command))
        if handler is None:  # a command added to the dictionary without its handler
            raise InputError("command", f"{command.name} has no handler in sim.loop.handlers")
        loop, recorder = self.loop, self.loop.recorder
        self.faults.apply_due(loop)  # the faults due by now (sim.faults.plan)
        recorder.command = command.describe() if label is None else label
        report = CommandReport(recorder.command, "completed", loop.sim.t_s, loop.sim.t_s)
        first_frame, waited = len(recorder.downlinks), len(recorder.events)
        loop.results = []
        try:
            details = handler(loop, command)
        except (CommandRefusedError, ValueError, InputError) as exc:
            report.status, report.reason = "refused", str(exc)
            loop.event(f"{command.name} refused: {exc}", "command", "error")
            recorder.now(force=True)
        else:
            report.details = details
            failure = details.pop("failure", None)
            if failure:
                report.status, report.reason = "failed", str(failure)
            halt = details.get("halt")
            if halt is not None:
                report.status, report.reason = "halted", str(halt["reason"])
        report.end_t_s = loop.sim.t_s
        report.results = loop.results
        # with the events still waiting for a frame (a command that took no time comes at a
        # moment already reported: sim.loop.frames)
        made = len(recorder.downlinks) > first_frame
        waiting = list(recorder.events) if made else recorder.events[waited:]
        report.events = [e for f in recorder.downlinks[first_frame:] for e in f.events] + waiting
        report.scores = [e for f in recorder.truths[first_frame:] for e in f.events]
        self.reports.append(report)
        recorder.command = ""
        return report

    # ---- checkpoint -------------------------------------------------------------------------

    def state(self) -> dict[str, Any]:
        """The session's state between commands, as plain data: the simulator, NATE, the
        frame recorder, the side estimators, the VO and its rig's width (the frames and
        reports already made are not part of it)."""
        loop = self.loop
        return {
            "sim": loop.sim.state(),
            "nate": loop.nate.state(),
            "recorder": loop.recorder.state(),
            "side": loop.side.state(),
            "vo": loop.vo.state(),
            "vo_rig": loop.vo.rig.camera.width_px,
            "protection": loop.protection.state(),
            "faults": self.faults.state(),
        }

    def load_state(self, state: Mapping[str, Any]) -> None:
        """Load ``state`` (``state()``) onto a session built from the same arguments."""
        loop = self.loop
        loop.sim.load_state(state["sim"])
        loop.nate.load_state(state["nate"])
        loop.recorder.load_state(state["recorder"])
        loop.side.load_state(state["side"])
        set_vo_rig(loop, state.get("vo_rig", 256))  # 256 before the rig could change
        loop.vo.load_state(state["vo"])
        if "protection" in state:  # a checkpoint from before fault protection: its defaults
            loop.protection.load_state(state["protection"])
        self.faults.load_state(state.get("faults", []))  # none before faults existed

    # ---- truth for the 3D view, benchmarks and tests -----------------------------------

    @property
    def mission_origin_world(self) -> FloatArray:
        """The mission frame's origin (the first Site's, where the rover started) in the
        simulator's frame (truth; for drawing the terrain in mission coordinates)."""
        return self.loop.recorder.scorer.site_origins_true[0].copy()

    def attitude_error_rad(self) -> float:
        """Angle between NATE's estimate and the truth now, rad."""
        q_b_ll_true = Rotation.from_quat(self.sim.q_ll_b()).inv()
        return float((Rotation.from_quat(self.nate.q_b_ll) * q_b_ll_true.inv()).magnitude())

    def q_b_ll_true(self) -> FloatArray:
        """The true ``q_b_ll`` now, (4,)."""
        out: FloatArray = Rotation.from_quat(self.sim.q_ll_b()).inv().as_quat()
        return out


def run_commands(
    site_name: str, seed: int, start_utc: datetime, commands: Sequence[cmd.Command], **kwargs: Any
) -> tuple[RoverSession, list[CommandReport], float]:
    """A session that runs ``commands``; returns it, the reports and the wall time, s."""
    wall = time.perf_counter()
    session = RoverSession(site_name, seed, start_utc, **kwargs)
    reports = session.run(commands)
    return session, reports, time.perf_counter() - wall
