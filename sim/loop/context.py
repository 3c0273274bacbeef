"""What a command handler works on (``sim.loop.handlers``): the simulated rover, its flight
software, the frame recorder, the side estimators and the VO of ``vo=on`` drives, with the
ways NATE is stepped on the simulator's samples.

How time passes (docs/DESIGN.md, "One control cycle"). Motion runs at 8 Hz: a drive's
truth and sensor samples are made as a batch (``sim.loop.rover_sim``) and NATE steps
through them one cycle at a time with the encoders. NATE's 8 Hz modes (Nadir Update and
Check, Articulate, the Sungaze gravity window) get every 8 Hz sample. A camera mode waits
for its image: the clock jumps to the requested time with one aggregated IMU sample, the
Pancam frame is rendered at the commanded mast pointing from the truth
(``RoverSim.pancam_sun_image``), and NATE steps with both. Gyrocompassing and Idle waits
are jumped over the same way. NATE's clock and the simulator's advance together (every
sample's ``dt``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from estimation.events import Event, Severity
from estimation.protection.monitor import MobilityProtection
from estimation.sapp.nate import EncoderSeries, ImuSample, ImuSeries, Nate, NateSeries
from estimation.sapp.wheel_odometry import steer_six
from estimation.vo.odometry import VisualOdometry
from estimation.vo.stereo_rig import StereoRig
from sim.loop.frames import FrameRecorder
from sim.loop.rover_sim import RoverSim, Segment
from sim.loop.side.estimators import SideEstimators
from sim.loop.vo_drive import EstimatedPose, VoDriveOptions
from sim.rover.truth import CONTROL_DT_S
from sim.sensors.imu import ImuSamples

FloatArray = NDArray[np.float64]

WAIT_CHUNK_S = 600.0  # 8 Hz waits are simulated in chunks of this length


class CommandRefusedError(Exception):
    """A command refused before it changed anything."""


@dataclass
class LoopContext:
    """The rover and its flight software in the loop; ``results`` collects the results of
    the modes the command running completed (``CommandReport.results``); ``make_vo`` makes
    the VO of another rig (``SET_PARAM param=vo.rig``: ``sim.loop.drives.set_vo_rig``)."""

    sim: RoverSim
    nate: Nate
    recorder: FrameRecorder
    side: SideEstimators
    vo: VisualOdometry
    vo_options: VoDriveOptions
    protection: MobilityProtection
    results: list[Any] = field(default_factory=list)
    make_vo: Callable[[StereoRig], VisualOdometry] = VisualOdometry

    def event(self, text: str, kind: str, severity: Severity = "info") -> None:
        """An event for the next frame."""
        self.recorder.events.append(Event(text, kind, severity))

    def estimate(self) -> EstimatedPose:
        """SAPP's pose now in the current Site."""
        return EstimatedPose(self.nate.p_s, self.nate.q_b_ll)

    def mission_estimate(self) -> tuple[FloatArray, FloatArray]:
        """SAPP's ``(p_mission, q_b_ll)`` now (where a side estimator starts)."""
        nate = self.nate
        p_mission: FloatArray = nate.sites.to_mission(nate.p_s, nate.sites.current.index)
        return p_mission, nate.q_b_ll

    def run_until_idle(self) -> dict[str, Any]:
        """Feed NATE until the acquisition, check or gyrocompass it started has ended."""
        nate, sim, frame = self.nate, self.sim, self.recorder.at_rest
        aqf_before = nate.aqf
        results: list[Any] = []
        while nate.busy:
            request = nate.camera_request
            hint = nate.wait_hint_s
            if request is not None:
                samples = sim.rest(max(hint, CONTROL_DT_S))  # slew, expose: one cycle at least
                image = sim.pancam_sun_image(request.az_rad, request.el_rad).image
                out = nate.step(imu_sample(samples, 0), image=image)
                results += [out.completed] if out.completed is not None else []
                frame(out, force=True)
            elif hint <= CONTROL_DT_S:
                series = nate.step_series(imu_series(sim.rest_cycles(1.0)))
                results += [c for c in series.completed if c is not None]
                self.recorder.at_rest_series(series, force_completed=True)
            else:
                out = nate.step(imu_sample(sim.rest(hint), 0))
                results += [out.completed] if out.completed is not None else []
                frame(out, force=True)
        details: dict[str, Any] = {"aqf_before": aqf_before.paper_name, "aqf": nate.aqf.paper_name}
        self.results = results
        if results and not results[-1].success:
            details["failure"] = self.recorder.last_event() or "the mode failed"
        return details

    def report(self) -> None:
        """A frame of the rover now, or, when this moment has its frame already (the
        previous command's last: sim.loop.frames), at the next control cycle, at rest."""
        if self.recorder.reported(self.nate.t_s) and not self.nate.busy:
            self.wait(CONTROL_DT_S)
        else:
            self.recorder.now(force=True)

    def wait(self, duration_s: float, report_waiting_first: bool = True) -> None:
        """Let time pass; Articulate keeps propagating at 8 Hz, Idle is jumped over.
        ``report_waiting_first``: events waiting for a frame are reported at the next cycle;
        ``False`` within a command whose events are known only at the wait's end (VO's
        result, computed while the rover stands), so that one jump reports them."""
        nate, sim, frame = self.nate, self.sim, self.recorder.at_rest
        if nate.busy:
            raise CommandRefusedError(f"WAIT: refused while {nate.mode.value} runs")
        if nate.wait_hint_s > CONTROL_DT_S:  # Idle: one jump
            if report_waiting_first and self.recorder.events and duration_s > CONTROL_DT_S:
                # events waiting for a frame (a command that took no time: sim.loop.frames)
                # are reported at the next cycle, not at the end of the jump
                frame(nate.step(imu_sample(sim.rest(CONTROL_DT_S), 0)))
                duration_s -= CONTROL_DT_S
            out = nate.step(imu_sample(sim.rest(duration_s), 0))
            frame(out, force=True)
            return
        remaining = duration_s
        while remaining > 1e-9:
            chunk = min(WAIT_CHUNK_S, remaining)
            self.recorder.at_rest_series(nate.step_series(imu_series(sim.rest_cycles(chunk))))
            remaining -= chunk

    def step_segment(self, seg: Segment) -> NateSeries:
        """NATE through a drive segment with the encoders, its cycles at once."""
        wheel = self.sim.encoders.wheel_angle_rad(seg.encoders.wheel_counts)
        steer = steer_six(seg.encoders.steer_rad)
        return self.nate.step_series(imu_series(seg.imu), EncoderSeries(wheel[1:], steer[1:]))


def imu_sample(samples: ImuSamples, k: int) -> ImuSample:
    """Sample ``k`` of ``samples`` as NATE takes it."""
    return ImuSample(samples.delta_angle_b[k], samples.delta_velocity_b[k], float(samples.dt_s[k]))


def imu_series(samples: ImuSamples) -> ImuSeries:
    """``samples`` as NATE takes many cycles at once."""
    return ImuSeries(samples.delta_angle_b, samples.delta_velocity_b, samples.dt_s)
