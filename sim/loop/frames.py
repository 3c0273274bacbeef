"""Building and scoring the telemetry frames of a session (``sim.loop.telemetry``).

A frame puts NATE's output beside the truth with the derived figures. The HGA figures are
those of an HGA pointed at that moment from the onboard estimate and IVP's Earth
(``estimation.sapp.hga_pointing``), scored against the truth (``sim.rover.hga``): during an
HGA pass that is the antenna's real error, and at other times the error it would have.
Earth's direction is computed every ``EARTH_NODE_S`` of simulated time and interpolated
linearly in between (normalised): over a minute its path bends by far less than a
microradian from the chord. Position errors are in the mission frame (the first Site's),
whose true origin is where the rover started; the true Site origins are kept as the
operators plant Sites. Frames are thinned to one per ``frame_every_s`` of 8 Hz data, but a
frame with events or a mode change is always kept.

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
from estimation.quaternion import quat_angle_between, quat_conjugate, quat_rotate
from estimation.sapp.hga_pointing import (
    HGA_POINTING_REQUIREMENT_DEG,
    PointingKnowledge,
    point_hga_many,
)
from estimation.sapp.nate import Nate, NateOutput, NateSeries
from estimation.sapp.sun_modes import SunResult
from sim.loop.rover_sim import RoverSim, Segment
from sim.loop.side.estimators import SideEstimators
from sim.loop.side.kinematic import SideEstimate
from sim.loop.telemetry import TelemetryFrame
from sim.rover.hga import hga_errors_deg
from sim.world.local_level import q_ll_b_from_site
from sim.world.mars_frames import earth_ll_truth, elevation_rad, sun_ll_truth
from sim.world.marsclock import lmst_h_from_t_s, sol_number_t_s

FloatArray = NDArray[np.float64]

EARTH_NODE_S = 60.0  # see the module docstring


class FrameRecorder:
    """The frames of a session as it runs (``frames``), with the events waiting for the next
    frame (``events``), the label of the command running (``command``) and the flight
    software's VO status (``vo_failures_in_row``, set by ``sim.loop.drives``)."""

    def __init__(
        self, sim: RoverSim, nate: Nate, side: SideEstimators, frame_every_s: float
    ) -> None:
        self.sim, self.nate, self.side = sim, nate, side
        self.frame_every_s = frame_every_s
        self.frames: list[TelemetryFrame] = []
        self.events: list[Event] = []
        self.command = ""
        self.vo_failures_in_row = 0
        self.knowledge = PointingKnowledge()
        self.site_origins_true: list[FloatArray] = [sim.drive_state.p_s.copy()]
        self._lon_west_deg = (360.0 - sim.site.lon_east_deg) % 360.0
        self._last_frame_t = -math.inf
        self._last_mode = ""
        self._sky_t0 = math.nan  # interpolation node: Earth (IVP, truth), sun at t0, t0 + node
        self._sky_nodes = np.zeros((3, 2, 3))

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
        self._append(
            series,
            kept,
            np.tile(self.sim.q_ll_b(), (n, 1)),
            np.tile(state.p_s, (n, 1)),
            (
                np.full(n, state.rocker_rad),
                np.tile(state.bogie_rad, (n, 1)),
                np.tile(state.steer_rad, (n, 1)),
            ),
            None,
        )

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
            joints = (traj.rocker_rad[rows], traj.bogie_rad[rows], traj.steer_rad[rows])
            self._append(series, kept, q_ll_b, traj.p_s[rows], joints, (side, rows.tolist()))
        self.side.at_sample(None)

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
        for frame in reversed(self.frames):
            if frame.events:
                return frame.events[-1].text
        return ""

    # ---- building and scoring ---------------------------------------------------------

    def _sky(self, t_s: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Earth in LL at each of ``t_s`` (increasing) from IVP and from the truth, and the
        true sun in LL, (K, 3) each (module docstring: interpolated between nodes
        ``EARTH_NODE_S`` apart, a new node pair where a time leaves the last one)."""
        sim = self.sim
        u = np.empty(len(t_s))
        nodes = np.empty((len(t_s), 3, 2, 3))
        for k, t in enumerate(t_s.tolist()):
            u_k = (t - self._sky_t0) / EARTH_NODE_S
            if not 0.0 <= u_k <= 1.0:
                self._sky_t0, u_k = t, 0.0
                at = np.array([t, t + EARTH_NODE_S])
                self._sky_nodes = np.stack(
                    [
                        earth_ll(at, sim.lat_rad, sim.lon_east_rad),
                        earth_ll_truth(at, sim.lat_rad, sim.lon_east_rad),
                        sun_ll_truth(at, sim.lat_rad, sim.lon_east_rad),
                    ]
                )
            u[k], nodes[k] = u_k, self._sky_nodes
        u3 = u[:, None, None]
        v = (1.0 - u3) * nodes[:, :, 0] + u3 * nodes[:, :, 1]
        v /= np.linalg.norm(v, axis=2, keepdims=True)
        return v[:, 0], v[:, 1], v[:, 2]

    def _append(
        self,
        series: NateSeries,
        kept: list[int],
        q_ll_b_true: FloatArray,
        p_world: FloatArray,
        joints: tuple[FloatArray, FloatArray, FloatArray],
        side: tuple[Mapping[str, SideEstimate], list[int]] | None,
    ) -> None:
        """Append the frames of the cycles ``kept`` of ``series``, with the truth of each
        (K rows): ``q_ll_b_true``, ``p_world`` the position in the simulator's frame, whose
        offset from the first Site's origin (the start) is the true mission position, and
        ``joints`` the (rocker (K,), bogie (K, 2), steering (K, 4)) angles, rad; ``side``
        the side estimators' segment estimates and the segment sample of each frame. The
        derived figures are computed for all K frames at once."""
        sim, nate, origins = self.sim, self.nate, self.site_origins_true
        t = series.t_s[kept]
        q_est = series.q_b_ll[kept]
        site_index = [series.site_index[k] for k in kept]
        q_ll_b = q_ll_b_true / np.linalg.norm(q_ll_b_true, axis=1, keepdims=True)
        q_b_ll_true = quat_conjugate(q_ll_b)
        earth_ivp, earth_true, sun_true = self._sky(t)
        hga_az, hga_el, boresight_b = point_hga_many(q_est, earth_ivp)
        hga_error = hga_errors_deg(hga_az, hga_el, q_b_ll_true, earth_true)
        boresight_ll = quat_rotate(q_ll_b, boresight_b)  # R_ll_b: the true body to LL
        att_err_deg = np.degrees(quat_angle_between(q_est, q_b_ll_true))
        p_mission_true = p_world - origins[0]
        p_s_est = series.p_s[kept]
        p_mission_est = np.array(
            [nate.sites.to_mission(p, i) for p, i in zip(p_s_est, site_index, strict=True)]
        )
        last = len(origins) - 1
        p_s_true = p_world - np.array([origins[min(i, last)] for i in site_index])
        position_error = np.linalg.norm(p_mission_est - p_mission_true, axis=1)
        sol = sol_number_t_s(sim.site.mission, t)
        lmst_h = lmst_h_from_t_s(t, self._lon_west_deg)
        earth_up = elevation_rad(earth_true) > 0.0
        rocker_deg, bogie_deg, steer_deg = (np.degrees(a) for a in joints)
        columns = (
            t.tolist(),
            sol.tolist(),
            lmst_h.tolist(),
            q_est.tolist(),
            q_b_ll_true.tolist(),
            p_s_est.tolist(),
            p_s_true.tolist(),
            p_mission_est.tolist(),
            p_mission_true.tolist(),
            hga_error.tolist(),
            earth_up.tolist(),
            att_err_deg.tolist(),
            position_error.tolist(),
            rocker_deg.tolist(),
            bogie_deg.tolist(),
            steer_deg.tolist(),
            sun_true.tolist(),
            earth_true.tolist(),
            boresight_ll.tolist(),
        )
        for j, row in enumerate(zip(*columns, strict=True)):
            (t_j, sol_j, lmst_j, q_est_j, q_true_j, p_est_j, p_true_j, pm_est_j, pm_true_j) = row[
                :9
            ]
            (hga_j, up_j, att_j, pos_j, rocker_j, bogie_j, steer_j, sun_j, earth_j, bore_j) = row[
                9:
            ]
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
            self.frames.append(
                TelemetryFrame(
                    t_s=t_j,
                    sol=sol_j,
                    lmst_h=lmst_j,
                    nate_mode=series.mode[k].value,
                    aqf=aqf.paper_name,
                    q_b_ll_est=q_est_j,
                    q_b_ll_true=q_true_j,
                    p_s_est=p_est_j,
                    p_s_true=p_true_j,
                    site_index=site_index[j],
                    p_mission_est=pm_est_j,
                    p_mission_true=pm_true_j,
                    imu_integration_s=float(series.imu_integration_s[k]),
                    gyro_counter_s=float(series.gyro_counter_s[k]),
                    tilt_est_deg=float(series.tilt_est_deg[k]),
                    tilt_accel_deg=float(series.tilt_accel_deg[k]),
                    hga_error_deg=hga_j,
                    hga_margin_deg=HGA_POINTING_REQUIREMENT_DEG - hga_j,
                    earth_up=up_j,
                    attitude_error_deg=att_j,
                    position_error_m=pos_j,
                    command=self.command,
                    rocker_deg=rocker_j,
                    bogie_deg=bogie_j,
                    steer_deg=steer_j,
                    sun_ll_true=sun_j,
                    earth_ll_true=earth_j,
                    hga_boresight_ll_true=bore_j,
                    events=events,
                    estimators=self.side.frame_estimates(t_j, p_mission_true[j], q_b_ll_true[j]),
                    vo_failures_in_row=self.vo_failures_in_row,
                    hga_margin_predicted_deg=predicted,
                )
            )
            self._last_frame_t = t_j
            self._last_mode = series.mode[k].value

    # ---- checkpoint -----------------------------------------------------------------------

    def state(self) -> dict[str, Any]:
        """What the next frames depend on, as plain data (the frames already made are not
        part of it: a checkpoint is taken between commands, when they have been handed on)."""
        return {
            "events": [e.as_dict() for e in self.events],
            "vo_failures_in_row": self.vo_failures_in_row,
            "knowledge": self.knowledge.state(),
            "site_origins_true": [p.copy() for p in self.site_origins_true],
            "last_frame_t": self._last_frame_t,
            "last_mode": self._last_mode,
            "sky_t0": self._sky_t0,
            "sky_nodes": self._sky_nodes.copy(),
        }

    def load_state(self, state: Mapping[str, Any]) -> None:
        """Load ``state`` (``state()``) onto a recorder built from the same configuration."""
        self.events = [Event(e["text"], e["kind"], e["severity"]) for e in state["events"]]
        self.vo_failures_in_row = int(state["vo_failures_in_row"])
        self.knowledge.load_state(state["knowledge"])
        self.site_origins_true = [np.array(p, dtype=np.float64) for p in state["site_origins_true"]]
        self._last_frame_t = float(state["last_frame_t"])
        self._last_mode = str(state["last_mode"])
        self._sky_t0 = float(state["sky_t0"])
        self._sky_nodes = np.array(state["sky_nodes"], dtype=np.float64)
