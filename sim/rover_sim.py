"""The simulated rover in its world: truth and sensors, a command at a time.

``RoverSim`` owns the terrain of a named site, the Mars clock, the rover's truth state and
its sensors (IMU, wheel and steering encoders). Each motion command produces its truth as
a batch at the 8 Hz control rate (DESIGN.md, "One control cycle") and the sensor samples
for that batch; an idle span is jumped over in one step, with one aggregated IMU sample
that is distributed exactly as the sum of its 8 Hz samples (``sim.imu``).

The flight software is not in the loop yet; ``RoverSim`` records what it would receive
(``ImuSamples``, ``EncoderSamples``) and keeps running figures an operator reads in a
scenario summary.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from datetime import datetime

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from sim import drive
from sim.encoders import EncoderParams, EncoderSamples, MobilityEncoders
from sim.imu import ImuSamples, Ln200Imu, Ln200Params
from sim.local_level import q_ll_b_from_site
from sim.mars_frames import mars_rotation_ll
from sim.marsclock import utc_to_t_s
from sim.rover_geometry import MER_GEOMETRY
from sim.sites import Site, make_terrain, site
from sim.slip import SlipModel
from sim.truth import TruthTrajectory

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Segment:
    """One motion command's truth and what the sensors made of it, sample for sample."""

    truth: TruthTrajectory
    imu: ImuSamples
    encoders: EncoderSamples


@dataclass
class RunningTotals:
    """Figures accumulated over a run (truth and sensors side by side)."""

    cycles_simulated: int = 0
    idle_s_jumped: float = 0.0
    distance_truth_m: float = 0.0
    distance_odometry_m: float = 0.0
    rest_s: float = 0.0
    gyro_rest_angle_b: FloatArray = field(default_factory=lambda: np.zeros(3))
    truth_rest_angle_b: FloatArray = field(default_factory=lambda: np.zeros(3))
    heading_change_rad: float = 0.0
    max_wheel_gap_m: float = 0.0
    unsettled_poses: int = 0


class RoverSim:
    """A rover at a named site, from a UTC start, reproducible from ``seed``.

    ``slip=False`` makes the wheels roll ideally (no slip, creep or sinkage).
    """

    def __init__(
        self,
        site_name: str,
        seed: int,
        start_utc: datetime,
        imu_params: Ln200Params | None = None,
        slip: bool = True,
    ) -> None:
        self.site: Site = site(site_name)
        self.terrain = make_terrain(site_name, seed)
        self.lat_rad = math.radians(self.site.lat_deg)
        self.lon_east_rad = math.radians(self.site.lon_east_deg)
        self.omega_mars_ll = mars_rotation_ll(self.lat_rad)
        rng_imu, rng_encoders, rng_slip = np.random.default_rng(seed).spawn(3)
        self.t_s = utc_to_t_s(start_utc)
        self.imu = Ln200Imu(imu_params or Ln200Params(), rng_imu, t_on_s=self.t_s)
        self.encoders = MobilityEncoders(EncoderParams(), rng_encoders)
        self.slip = (
            SlipModel(self.terrain.soil, rng_slip) if slip else SlipModel.ideal(self.terrain.soil)
        )
        self.state = drive.initial_state(self.terrain, self.t_s, slip_model=self.slip)
        self.totals = RunningTotals()
        self._encoder_counts = self.encoders.read(self.state.as_trajectory()).wheel_counts[0]

    # ---- commands -------------------------------------------------------------------

    def rest(self, duration_s: float) -> ImuSamples:
        """Stay still for ``duration_s``: jump the clock, one aggregated IMU sample."""
        q_ll_b = self.q_ll_b()
        samples = self.imu.measure_interval(duration_s, q_ll_b, self.omega_mars_ll)
        self.totals.rest_s += duration_s
        self.totals.gyro_rest_angle_b += samples.delta_angle_b[0]
        self.totals.truth_rest_angle_b += self._inertial_rest_angle(q_ll_b, duration_s)
        self.t_s += duration_s
        self.state = self.state.at_time(self.t_s)
        self.totals.idle_s_jumped += duration_s
        return samples

    def drive_straight(self, distance_m: float) -> Segment:
        """Drive ``distance_m`` (> 0) straight ahead; returns its truth and sensor samples."""
        traj, self.state = drive.drive_straight(self.terrain, self.state, distance_m, self.slip)
        return self._sense(traj)

    def drive_arc(self, radius_m: float, angle_rad: float) -> Segment:
        """Drive along an arc (see ``sim.drive.drive_arc`` for the signs)."""
        traj, self.state = drive.drive_arc(self.terrain, self.state, radius_m, angle_rad, self.slip)
        return self._sense(traj)

    def turn_in_place(self, angle_rad: float) -> Segment:
        """Turn in place by ``angle_rad`` (positive: clockwise seen from above, to the right)."""
        traj, self.state = drive.turn_in_place(self.terrain, self.state, angle_rad, self.slip)
        return self._sense(traj)

    # ---- truth views ----------------------------------------------------------------

    def q_ll_b(self) -> FloatArray:
        """Truth attitude of the body in the Local-Level frame at the rover, ``[x, y, z, w]``."""
        out: FloatArray = q_ll_b_from_site(
            self.state.q_s_b[None, :], self.state.p_s[None, :], self.lat_rad, self.lon_east_rad
        )[0]
        return out

    # ---- internals ------------------------------------------------------------------

    def _inertial_rest_angle(self, q_ll_b: FloatArray, duration_s: float) -> FloatArray:
        R_b_ll = Rotation.from_quat(q_ll_b).inv()
        out: FloatArray = R_b_ll.apply(self.omega_mars_ll * duration_s)
        return out

    def _sense(self, traj: TruthTrajectory) -> Segment:
        q_ll_b = q_ll_b_from_site(traj.q_s_b, traj.p_s, self.lat_rad, self.lon_east_rad)
        # Quasi-static truth: the rover's own accelerations (~1e-3 m/s^2 at 3.75 cm/s,
        # seed 000 uses the accelerometers only at rest) are left out of the IMU input.
        samples = self.imu.measure(traj.t_s, q_ll_b, self.omega_mars_ll)
        encoders = self.encoders.read(traj)
        counts = encoders.wheel_counts
        wheel_rad = self.encoders.wheel_angle_rad(counts[-1] - self._encoder_counts)
        self._encoder_counts = counts[-1]
        totals = self.totals
        totals.cycles_simulated += len(traj) - 1
        totals.distance_truth_m += float(np.sum(np.linalg.norm(np.diff(traj.p_s, axis=0), axis=1)))
        totals.distance_odometry_m += float(np.mean(wheel_rad)) * MER_GEOMETRY.wheel_radius_m
        yaw = Rotation.from_quat(traj.q_s_b).as_euler("ZYX")[:, 0]
        totals.heading_change_rad += float(np.sum(np.angle(np.exp(1j * np.diff(yaw)))))
        totals.max_wheel_gap_m = max(totals.max_wheel_gap_m, self.state.max_gap_m)
        totals.unsettled_poses += self.state.unsettled_poses
        self.t_s = float(traj.t_s[-1])
        return Segment(traj, samples, encoders)
