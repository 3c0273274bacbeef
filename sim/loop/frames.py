"""Building the telemetry frames of a session: the rover's downlink and, beside it, the truth.

Each kept control cycle makes two records at the same ``t_s``: the ``Downlink``
(``sim.loop.downlink``: NATE's output, the encoders' readings, the HGA pointing the rover
would command now from its estimate and IVP's Earth, the margin it predicts, the side
estimators' poses) and the ``Truth`` (``sim.scoring.truth``), which the scorer
(``sim.scoring.scorer``) makes from the world's truth at those cycles and the downlink.
IVP's Earth is interpolated between nodes a minute apart (``sim.loop.sky``). Frames are
thinned to one per ``frame_every_s`` of 8 Hz data, but a frame with events or a mode change is
always kept.

One frame per moment: a rover's frames have strictly increasing ``t_s``. A command that
takes no time (PLANT_SITE, SET_PARAM, ARTICULATE_START/STOP, a refusal) comes at the moment
the previous command's last frame reported, and that frame has been handed on (the runtime
plays out and stores each command's frames when the command completes), so it makes no
second frame of that moment: its events wait for the next frame, which they force (the
next 8 Hz cycle: ``LoopContext.wait`` steps one before jumping), and its mode counts as
reported. PLANT_SITE and SET_PARAM, whose change the operator waits to see, take that cycle
themselves (``LoopContext.report``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

from estimation.events import Event
from estimation.ivp import earth_ll
from estimation.protection.monitor import MobilityProtection
from estimation.sapp.hga_pointing import PointingKnowledge, hga_boresights_b, point_hga_many
from estimation.sapp.nate import Nate, NateOutput, NateSeries
from estimation.sapp.sun_modes import SunResult
from sim.loop.downlink import Downlink
from sim.loop.images import ImageDict
from sim.loop.rover_sim import RoverSim, Segment
from sim.loop.side.estimators import SideEstimators
from sim.loop.side.kinematic import SideEstimate
from sim.loop.sky import SkyNodes
from sim.scoring.scorer import DownlinkFigures, Scorer, SidePose, WorldTruth
from sim.scoring.truth import Truth
from sim.world.local_level import q_ll_b_from_site
from sim.world.marsclock import lmst_h_from_t_s, sol_number_t_s

FloatArray = NDArray[np.float64]


class FrameRecorder:
    """The frames of a session as it runs: the rover's ``downlinks`` and, record for record,
    the scorer's ``truths``; the events waiting for the next frame (``events``), the label
    of the command running (``command``) and the flight software's VO status
    (``vo_failures_in_row``, set by ``sim.loop.drives``)."""

    def __init__(
        self, sim: RoverSim, nate: Nate, side: SideEstimators, frame_every_s: float
    ) -> None:
        self.sim, self.nate, self.side = sim, nate, side
        self.frame_every_s = frame_every_s
        self.downlinks: list[Downlink] = []
        self.truths: list[Truth] = []
        self.images: list[ImageDict] = []  # the pairs the rover sends (sim.loop.imaging)
        self.events: list[Event] = []
        # truth events waiting for the next frame's truth record (a fault applied: sim.faults)
        self.truth_events: list[Event] = []
        self.command = ""
        self.vo_failures_in_row = 0
        # mobility fault protection, for its figures (set by the session), and the position
        # uncertainty at each cycle of the drive segment being recorded (set by sim.loop.drives)
        self.protection: MobilityProtection | None = None
        self.segment_sigma_m: FloatArray | None = None
        self.knowledge = PointingKnowledge()
        self.scorer = Scorer(sim.lat_rad, sim.lon_east_rad, sim.drive_state.p_s)
        self._lon_west_deg = (360.0 - sim.site.lon_east_deg) % 360.0
        self._last_frame_t = -math.inf
        self._last_mode = ""
        self._earth_ivp = SkyNodes([lambda t: earth_ll(t, sim.lat_rad, sim.lon_east_rad)])

    # ---- when a frame is made ---------------------------------------------------------

    def keep(self, out: NateOutput, force: bool) -> bool:
        """Whether the cycle ``out`` makes a frame (module docstring: never a second frame of
        a moment, even when forced)."""
        if self.reported(out.t_s):
            self._last_mode = out.mode.value
            return False
        return (
            force
            or bool(out.events)
            or bool(self.events)
            or out.mode.value != self._last_mode
            or out.t_s - self._last_frame_t >= self.frame_every_s - 1e-9
        )

    def at_rest(self, out: NateOutput, force: bool = False) -> None:
        """A frame for the rover at rest now (truth from the simulator's state)."""
        if self.keep(out, force):
            self._rest_frames(NateSeries.of_outputs([out]), [0])

    def at_rest_series(self, series: NateSeries, force_completed: bool = False) -> None:
        """The frames of NATE's cycles ``series`` with the rover at rest (an 8 Hz wait);
        ``force_completed``: a cycle that completed a mode always makes one."""
        self._rest_frames(series, self._kept(series, force_completed))

    def _rest_frames(self, series: NateSeries, kept: list[int]) -> None:
        if not kept:
            return
        state, n = self.sim.drive_state, len(kept)
        world = WorldTruth(
            q_ll_b=np.tile(self.sim.q_ll_b(), (n, 1)),
            p_world=np.tile(state.p_s, (n, 1)),
            rocker_rad=np.full(n, state.rocker_rad),
            bogie_rad=np.tile(state.bogie_rad, (n, 1)),
            steer_rad=np.tile(state.steer_rad, (n, 1)),
        )
        self._append(series, kept, world, np.tile(self.sim.steer_reading_rad, (n, 1)), None)

    def now(self, force: bool = False) -> None:
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
        self.at_rest(out, force)

    def segment(self, seg: Segment, series: NateSeries, side: Mapping[str, SideEstimate]) -> None:
        """The frames of a drive segment, NATE's cycles ``series`` through it, with the side
        estimators' estimates ``side``: built for the kept cycles only, in arrays."""
        kept = self._kept(series, False)
        if kept:
            traj, rows = seg.truth, np.array(kept) + 1  # truth row 0 is the segment's start
            sim = self.sim
            q_ll_b = q_ll_b_from_site(
                traj.q_s_b[rows], traj.p_s[rows], sim.lat_rad, sim.lon_east_rad
            )
            world = WorldTruth(
                q_ll_b=q_ll_b,
                p_world=traj.p_s[rows],
                rocker_rad=traj.rocker_rad[rows],
                bogie_rad=traj.bogie_rad[rows],
                steer_rad=traj.steer_rad[rows],
            )
            steer_read = seg.encoders.steer_rad[rows]
            self._append(series, kept, world, steer_read, (side, rows.tolist()))
        self.side.at_sample(None)

    def _sigma_m(self, k: int) -> float:
        """The onboard position uncertainty at cycle ``k`` of the series being recorded."""
        if self.segment_sigma_m is not None:
            return float(self.segment_sigma_m[k])
        return math.nan if self.protection is None else self.protection.uncertainty.sigma_m

    def _fault(self) -> str:
        fault = None if self.protection is None else self.protection.fault
        return "" if fault is None else fault.reason

    def _kept(self, series: NateSeries, force_completed: bool) -> list[int]:
        """The cycles of ``series`` that make frames (``keep``, cycle by cycle)."""
        kept: list[int] = []
        last_t, last_mode, pending = self._last_frame_t, self._last_mode, bool(self.events)
        every_s = self.frame_every_s - 1e-9
        for k, t in enumerate(series.t_s.tolist()):
            mode = series.mode[k].value
            if (
                pending
                or series.events[k]
                or mode != last_mode
                or t - last_t >= every_s
                or (force_completed and series.completed[k] is not None)
            ):
                kept.append(k)
                last_t, last_mode, pending = t, mode, False
        return kept

    def reported(self, t_s: float) -> bool:
        """Whether a frame of the moment ``t_s`` has been made (module docstring)."""
        return t_s <= self._last_frame_t

    def last_event(self) -> str:
        """The text of the latest event in a frame (``""``: none)."""
        for frame in reversed(self.downlinks):
            if frame.events:
                return frame.events[-1].text
        return ""

    # ---- building ----------------------------------------------------------------------

    def _append(
        self,
        series: NateSeries,
        kept: list[int],
        world: WorldTruth,
        steer_read_rad: FloatArray,
        side: tuple[Mapping[str, SideEstimate], list[int]] | None,
    ) -> None:
        """Append the downlink and truth records of the cycles ``kept`` of ``series`` (K
        rows): ``world`` the truth at those cycles, ``steer_read_rad`` (K, 4) the steering
        sensors' readings, ``side`` the side estimators' segment estimates and the segment
        sample of each frame. The figures are computed for all K frames at once."""
        sim, nate = self.sim, self.nate
        t = series.t_s[kept]
        q_est = series.q_b_ll[kept]
        site_index = [series.site_index[k] for k in kept]
        (earth_ivp,) = self._earth_ivp.at(t)
        hga_az, hga_el, boresight_b = point_hga_many(q_est, earth_ivp)
        p_s_est = series.p_s[kept]
        p_mission_est = np.array(
            [nate.sites.to_mission(p, i) for p, i in zip(p_s_est, site_index, strict=True)]
        )
        sol = sol_number_t_s(sim.site.mission, t)
        lmst_h = lmst_h_from_t_s(t, self._lon_west_deg)
        rocker_read, bogie_read = sim.joint_encoders.read_angles(world.rocker_rad, world.bogie_rad)
        columns = (
            t.tolist(),
            sol.tolist(),
            lmst_h.tolist(),
            q_est.tolist(),
            p_s_est.tolist(),
            p_mission_est.tolist(),
            np.degrees(rocker_read).tolist(),
            np.degrees(bogie_read).tolist(),
            np.degrees(steer_read_rad).tolist(),
            np.degrees(hga_az).tolist(),
            np.degrees(hga_el).tolist(),
        )
        side_poses: list[dict[str, SidePose]] = []
        for j, row in enumerate(zip(*columns, strict=True)):
            t_j, sol_j, lmst_j, q_est_j, p_est_j, pm_est_j, rocker_j, bogie_j = row[:8]
            steer_j, az_j, el_j = row[8:]
            k = kept[j]
            events = list(series.events[k]) + self.events
            self.events = []
            done = series.completed[k]
            sungaze = (
                math.degrees(done.three_sigma_rad)
                if isinstance(done, SunResult) and done.success and done.updated
                else None
            )
            aqf = series.aqf[k]
            predicted = self.knowledge.update(aqf, float(series.imu_integration_s[k]), sungaze)
            if side is not None:
                self.side.at_sample(side[0], side[1][j])
            poses = self.side.frame_poses(t_j)
            side_poses.append(poses)
            self.downlinks.append(
                Downlink(
                    t_s=t_j,
                    sol=sol_j,
                    lmst_h=lmst_j,
                    nate_mode=series.mode[k].value,
                    aqf=aqf.paper_name,
                    q_b_ll_est=q_est_j,
                    p_s_est=p_est_j,
                    site_index=site_index[j],
                    p_mission_est=pm_est_j,
                    imu_integration_s=float(series.imu_integration_s[k]),
                    gyro_counter_s=float(series.gyro_counter_s[k]),
                    tilt_est_deg=float(series.tilt_est_deg[k]),
                    tilt_accel_deg=float(series.tilt_accel_deg[k]),
                    command=self.command,
                    rocker_enc_deg=rocker_j,
                    bogie_enc_deg=bogie_j,
                    steer_enc_deg=steer_j,
                    hga_azimuth_deg=az_j,
                    hga_elevation_deg=el_j,
                    events=events,
                    estimators={
                        name: {
                            "p_mission": [float(v) for v in p],
                            "q_b_ll": None if q is None else [float(v) for v in q],
                        }
                        for name, (p, q) in poses.items()
                    },
                    vo_failures_in_row=self.vo_failures_in_row,
                    hga_margin_predicted_deg=predicted,
                    position_sigma_m=self._sigma_m(k),
                    mobility_fault=self._fault(),
                )
            )
            self._last_frame_t = t_j
            self._last_mode = series.mode[k].value
        stuck = sim.condition.hga_stuck_rad  # the true gimbal angles, a fault (sim.faults)
        if stuck is not None:
            hga_az, hga_el = np.full(len(t), stuck[0]), np.full(len(t), stuck[1])
            boresight_b = hga_boresights_b(hga_az, hga_el)
        figures = DownlinkFigures(
            t_s=t,
            q_b_ll_est=q_est,
            p_mission_est=p_mission_est,
            site_index=site_index,
            hga_az_rad=hga_az,
            hga_el_rad=hga_el,
            hga_boresight_b=boresight_b,
            side=side_poses,
        )
        truths = self.scorer.score(figures, world)
        if self.truth_events:
            truths[0].events.extend(self.truth_events)
            self.truth_events = []
        self.truths.extend(truths)

    # ---- checkpoint -----------------------------------------------------------------------

    def state(self) -> dict[str, Any]:
        """What the next frames depend on, as plain data (the frames already made are not
        part of it: a checkpoint is taken between commands, when they have been handed on)."""
        return {
            "events": [e.as_dict() for e in self.events],
            "truth_events": [e.as_dict() for e in self.truth_events],
            "vo_failures_in_row": self.vo_failures_in_row,
            "knowledge": self.knowledge.state(),
            "scorer": self.scorer.state(),
            "last_frame_t": self._last_frame_t,
            "last_mode": self._last_mode,
            "earth_ivp": self._earth_ivp.state(),
        }

    def load_state(self, state: Mapping[str, Any]) -> None:
        """Load ``state`` (``state()``) onto a recorder built from the same configuration."""
        self.events = [Event(e["text"], e["kind"], e["severity"]) for e in state["events"]]
        waiting = state.get("truth_events", [])  # none in a checkpoint from before faults
        self.truth_events = [Event(e["text"], e["kind"], e["severity"]) for e in waiting]
        self.vo_failures_in_row = int(state["vo_failures_in_row"])
        self.knowledge.load_state(state["knowledge"])
        self.scorer.load_state(state["scorer"])
        self._last_frame_t = float(state["last_frame_t"])
        self._last_mode = str(state["last_mode"])
        self._earth_ivp.load_state(state["earth_ivp"])
