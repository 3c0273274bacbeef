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
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from estimation.events import Event
from estimation.ivp import earth_ll
from estimation.sapp.hga_pointing import PointingKnowledge, point_hga
from estimation.sapp.nate import Nate, NateOutput
from estimation.sapp.sun_modes import SunResult
from sim.loop.rover_sim import RoverSim, Segment
from sim.loop.side.estimators import SideEstimators
from sim.loop.side.kinematic import SideEstimate
from sim.loop.telemetry import TelemetryFrame
from sim.rover.hga import hga_pointing_truth
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
        """Whether the cycle ``out`` makes a frame (module docstring)."""
        return (
            force
            or bool(out.events)
            or bool(self.events)
            or out.mode.value != self._last_mode
            or out.t_s - self._last_frame_t >= self.frame_every_s - 1e-9
        )

    def at_rest(self, out: NateOutput, force: bool = False) -> None:
        """A frame for the rover at rest now (truth from the simulator's state)."""
        if not self.keep(out, force):
            return
        state = self.sim.drive_state
        joints = (state.rocker_rad, state.bogie_rad, state.steer_rad)
        self._append(out, self.sim.q_ll_b(), state.p_s.copy(), joints)

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

    def segment(
        self, seg: Segment, outputs: Sequence[NateOutput], side: Mapping[str, SideEstimate]
    ) -> None:
        """The frames of a drive segment, NATE's cycle ``outputs`` through it, with the side
        estimators' estimates ``side``."""
        sim = self.sim
        traj = seg.truth
        q_ll_b = q_ll_b_from_site(traj.q_s_b, traj.p_s, sim.lat_rad, sim.lon_east_rad)
        for k, out in enumerate(outputs):
            if self.keep(out, False):
                i = k + 1
                self.side.at_sample(side, i)
                joints = (float(traj.rocker_rad[i]), traj.bogie_rad[i], traj.steer_rad[i])
                self._append(out, q_ll_b[i], traj.p_s[i], joints)
        self.side.at_sample(None)

    def last_event(self) -> str:
        """The text of the latest event in a frame (``""``: none)."""
        for frame in reversed(self.frames):
            if frame.events:
                return frame.events[-1].text
        return ""

    # ---- building and scoring ---------------------------------------------------------

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
        origins = self.site_origins_true
        p_mission_true = p_world - origins[0]
        t = out.t_s
        q_b_ll_true = Rotation.from_quat(q_ll_b_true).inv()
        earth_ivp, earth_true, sun_true = self._sky(t)
        hga_command = point_hga(out.q_b_ll, earth_ivp)
        hga = hga_pointing_truth(hga_command, q_b_ll_true.as_quat(), earth_true)
        boresight_ll = q_b_ll_true.inv().apply(hga_command.boresight_b)
        rocker_rad, bogie_rad, steer_rad = joints
        p_mission_est = nate.sites.to_mission(out.p_s, out.site_index)
        origin = origins[min(out.site_index, len(origins) - 1)]
        att_err = (Rotation.from_quat(out.q_b_ll) * q_b_ll_true.inv()).magnitude()
        events = list(out.events) + self.events
        self.events = []
        done = out.completed
        sungaze = (
            math.degrees(done.three_sigma_rad)
            if isinstance(done, SunResult) and done.success and done.updated
            else None
        )
        predicted = self.knowledge.update(out.aqf, out.imu_integration_s, sungaze)
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
                command=self.command,
                rocker_deg=math.degrees(rocker_rad),
                bogie_deg=[math.degrees(float(v)) for v in bogie_rad],
                steer_deg=[math.degrees(float(v)) for v in steer_rad],
                sun_ll_true=[float(v) for v in sun_true],
                earth_ll_true=[float(v) for v in earth_true],
                hga_boresight_ll_true=[float(v) for v in boresight_ll],
                events=events,
                estimators=self.side.frame_estimates(t, p_mission_true, q_b_ll_true),
                vo_failures_in_row=self.vo_failures_in_row,
                hga_margin_predicted_deg=predicted,
            )
        )
        self._last_frame_t = t
        self._last_mode = out.mode.value

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
