"""The simulated rover in its world: truth and sensors, a command at a time.

``RoverSim`` owns the terrain of a named site, the Mars clock, the rover's truth state and
its sensors (IMU, wheel and steering encoders). Each motion command produces its truth as
a batch at the 8 Hz control rate (docs/DESIGN.md, "One control cycle") and the sensor samples
for that batch; an idle span is jumped over in one step, with one aggregated IMU sample
that is distributed exactly as the sum of its 8 Hz samples (``sim.sensors.imu``).

``RoverSim`` gives what the flight software receives (``ImuSamples``, ``EncoderSamples``,
Pancam sun images at a commanded mast pointing) and keeps running figures an operator
reads in a scenario summary; ``sim.loop.session`` puts the flight software in the loop.

The Pancam mast points where it is commanded plus a fixed per-rover bias in azimuth and
elevation (``mast_bias_sigma_deg``, 1σ per axis, default 0.05 deg: approximate, a
calibrated pan/tilt actuator's absolute knowledge), which the flight software does not
know: it enters every sun vector as an unmodelled systematic error.

A drive may drag a wheel (``sim.rover.drag``): the one its command names (``drag_wheel``,
the flight software knows it), and the one whose motor the test conductor has failed
(``failed_wheel``, a fault injected at run time that the flight software is not told of:
every drive then drags it while the flight software still averages the wheels the command
told it). Wheels are named as ``estimation.geometry.WHEEL_KEYS``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, fields
from datetime import datetime
from typing import TYPE_CHECKING, Any, TypedDict

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from estimation.geometry import WHEEL_KEYS
from sim.errors import InputError
from sim.faults.condition import FaultCondition, NavcamFailedError
from sim.rover import drive
from sim.rover.drag import Drag
from sim.rover.geometry import MER_GEOMETRY
from sim.rover.patch_slip import PatchSlipModel
from sim.rover.slip import SlipModel
from sim.rover.truth import CONTROL_DT_S, TruthTrajectory
from sim.sensors.encoders import EncoderParams, EncoderSamples, MobilityEncoders
from sim.sensors.imu import ImuSamples, Ln200Imu, Ln200Params
from sim.sensors.joint_encoders import JointEncoderParams, JointEncoders
from sim.sensors.pancam import SunImage, render_sun_image
from sim.world.local_level import q_ll_b_from_site
from sim.world.mars_frames import earth_ll_truth, mars_rotation_ll, sun_ll_truth
from sim.world.marsclock import utc_to_t_s
from sim.world.places import place_patches
from sim.world.sites import Site, make_terrain, site
from sim.world.soil_patches import SoilMap, SoilPatch
from sim.world.terrain import Soil, Terrain

if TYPE_CHECKING:  # sim.sensors.navcam.camera (numba) is imported when a pair is first rendered
    from sim.sensors.navcam.camera import NavcamPair

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


class Placement(TypedDict, total=False):
    """``RoverSim``'s keyword arguments after the site, seed and start (their defaults are
    ``RoverSim``'s): what a ``RoverSession`` passes on without restating them."""

    imu_params: Ln200Params | None
    slip: bool
    yaw_rad: float
    x_m: float
    y_m: float
    mast_bias_sigma_deg: float
    terrain: Terrain | None
    start_t_s: float | None


class RoverSim:
    """A rover at a named site, from a UTC start, reproducible from ``seed``.

    ``slip=False`` makes the wheels roll ideally (no slip, creep or sinkage). ``terrain``
    replaces the site's own (``make_terrain(site_name, seed)``), its soil with it: a
    rehearsal's sampled world (``sim.rehearsal.world``); ``start_t_s`` (TT s) replaces
    ``start_utc`` as the start, exactly (a rehearsal starts at a report's time).
    """

    def __init__(
        self,
        site_name: str,
        seed: int,
        start_utc: datetime,
        imu_params: Ln200Params | None = None,
        slip: bool = True,
        yaw_rad: float = 0.0,
        x_m: float = 0.0,
        y_m: float = 0.0,
        mast_bias_sigma_deg: float = 0.05,
        terrain: Terrain | None = None,
        start_t_s: float | None = None,
    ) -> None:
        self.site: Site = site(site_name)
        self.start_xy_m = (x_m, y_m)  # where the rover was placed (the radio EKF starts there)
        self.terrain = make_terrain(site_name, seed) if terrain is None else terrain
        self.lat_rad = math.radians(self.site.lat_deg)
        self.lon_east_rad = math.radians(self.site.lon_east_deg)
        self.omega_mars_ll = mars_rotation_ll(self.lat_rad)
        rng_imu, rng_encoders, rng_slip, rng_cam = np.random.default_rng(seed).spawn(4)
        if start_t_s is not None and not math.isfinite(start_t_s):
            raise InputError("start_t_s", f"must be finite, got {start_t_s!r}")
        self.t_s = utc_to_t_s(start_utc) if start_t_s is None else float(start_t_s)
        self.imu = Ln200Imu(imu_params or Ln200Params(), rng_imu, t_on_s=self.t_s)
        self.encoders = MobilityEncoders(EncoderParams(), rng_encoders)
        # The soil under the rover: the terrain's, with the place's patches and those a
        # test conductor lays while the rover runs (``add_soil_patch``).
        self.soil_map = SoilMap(self.terrain.soil, place_patches(site_name))
        self.slip: SlipModel = (
            PatchSlipModel(self.terrain.soil, rng_slip, soil_map=self.soil_map)
            if slip
            else SlipModel.ideal(self.terrain.soil)
        )
        self.drive_state = drive.initial_state(
            self.terrain, self.t_s, x_m=x_m, y_m=y_m, yaw_rad=yaw_rad, slip_model=self.slip
        )
        if not (math.isfinite(mast_bias_sigma_deg) and 0.0 <= mast_bias_sigma_deg <= 5.0):
            raise InputError("mast_bias_sigma_deg", "must be in [0, 5] deg")
        self.mast_bias_rad = np.radians(mast_bias_sigma_deg) * rng_cam.standard_normal(2)
        self._rng_cam = rng_cam
        self.totals = RunningTotals()
        self._q_ll_b_of_pose: tuple[bytes, FloatArray] = (b"", np.zeros(4))  # see q_ll_b
        first = self.encoders.read(self.drive_state.as_trajectory())
        self._encoder_counts = first.wheel_counts[0]
        # The steering sensors' latest reading (what the downlink reports at rest) and the
        # suspension's encoders, on a noise stream of their own so that adding them changed
        # no other draw.
        self.steer_reading_rad: FloatArray = first.steer_rad[0].copy()
        rng_joints = np.random.default_rng([seed, 7010])
        self.joint_encoders = JointEncoders(JointEncoderParams(), rng_joints)
        # The same sensors as mobility fault protection reads them every 8 Hz cycle of a
        # drive: a stream of their own, so that the frames' readings drew nothing new.
        rng_suspension = np.random.default_rng([seed, 7011])
        self.suspension_encoders = JointEncoders(JointEncoderParams(), rng_suspension)
        self._failed_wheel: str | None = None
        self.condition = FaultCondition()  # healthy until a fault is applied (sim.faults)
        # told of every motion segment's truth as it is made (a rehearsal's record of its
        # true traverse, sim.rehearsal.run); a halted drive's segment is made again, cut
        self.on_segment: Callable[[Segment], None] | None = None

    @property
    def failed_wheel(self) -> str | None:
        """The wheel whose motor has failed (``WHEEL_KEYS``), dragged on every drive; None:
        all motors work. The test conductor sets it; the flight software is not told."""
        return self._failed_wheel

    @failed_wheel.setter
    def failed_wheel(self, key: str | None) -> None:
        if key is not None and (not isinstance(key, str) or key not in WHEEL_KEYS):
            raise InputError("failed_wheel", f"must be one of {', '.join(WHEEL_KEYS)} or None")
        self._failed_wheel = key

    # ---- checkpoint ---------------------------------------------------------------------

    def state(self) -> dict[str, Any]:
        """What changes as the rover runs, as plain data: the clock, the truth at rest, the
        sensors (biases, generators), the slip model and the running totals. The terrain,
        site and mast bias follow from the configuration and are not part of it."""
        return {
            "t_s": self.t_s,
            "drive_state": drive_state_dict(self.drive_state),
            "imu": self.imu.state(),
            "encoders": self.encoders.state(),
            "encoder_counts": np.asarray(self._encoder_counts).copy(),
            "steer_reading_rad": self.steer_reading_rad.copy(),
            "joint_encoders": self.joint_encoders.state(),
            "suspension_encoders": self.suspension_encoders.state(),
            "slip": self.slip.state(),
            "soil_patches": self.soil_map.state(),
            "rng_cam": self._rng_cam.bit_generator.state,
            "mast_bias_rad": self.mast_bias_rad.copy(),
            "totals": {f.name: _plain(getattr(self.totals, f.name)) for f in fields(RunningTotals)},
            "failed_wheel": self._failed_wheel,
            "condition": self.condition.state(),
        }

    def load_state(self, state: Mapping[str, Any]) -> None:
        """Load ``state`` (``state()``) onto a simulator built from the same arguments."""
        self.t_s = float(state["t_s"])
        self.drive_state = drive_state_from_dict(state["drive_state"])
        self.imu.load_state(state["imu"])
        self.encoders.load_state(state["encoders"])
        self._encoder_counts = np.array(state["encoder_counts"], dtype=np.int64)
        self.steer_reading_rad = np.array(state["steer_reading_rad"], dtype=np.float64)
        self.joint_encoders.load_state(state["joint_encoders"])
        if "suspension_encoders" in state:  # a checkpoint from before fault protection
            self.suspension_encoders.load_state(state["suspension_encoders"])
        self.slip.load_state(state["slip"])
        if "soil_patches" in state:  # checkpoints from before soil patches have none
            self.soil_map.load_state(state["soil_patches"])
        self._rng_cam.bit_generator.state = state["rng_cam"]
        self.mast_bias_rad = np.array(state["mast_bias_rad"], dtype=np.float64)
        self.totals = RunningTotals(**_arrays(state["totals"]))
        self.failed_wheel = state.get("failed_wheel")  # absent before wheel drag
        self.condition = FaultCondition()  # a checkpoint from before faults: healthy
        if "condition" in state:
            self.condition.load_state(state["condition"])

    # ---- soil patches ---------------------------------------------------------------

    def add_soil_patch(self, name: str, patch: SoilPatch) -> None:
        """Lay ``patch`` (a soil on a region of the Site frame) on top of the ground as
        ``name``, replacing a patch of that name: a sand trap a test conductor injects while
        the rover runs. It applies from the next drive on (the rover at rest keeps the
        sinkage it settled with until it moves); with ``slip=False`` the wheels roll
        ideally on any soil."""
        self.soil_map.add(name, patch)

    def remove_soil_patch(self, name: str) -> SoilPatch:
        """Lift the soil patch ``name``; InputError('name', ...) if there is none."""
        return self.soil_map.remove(name)

    def soil_at(self, x_m: float, y_m: float) -> Soil:
        """The soil at Site ``(x_m, y_m)`` (m): the topmost patch there, else the terrain's."""
        return self.soil_map.soil_at(x_m, y_m)

    # ---- commands -------------------------------------------------------------------

    def rest(self, duration_s: float) -> ImuSamples:
        """Stay still for ``duration_s``: jump the clock, one aggregated IMU sample."""
        q_ll_b = self.q_ll_b()
        samples = self.imu.measure_interval(duration_s, q_ll_b, self.omega_mars_ll)
        self.totals.rest_s += duration_s
        self.totals.gyro_rest_angle_b += samples.delta_angle_b[0]
        self.totals.truth_rest_angle_b += self._inertial_rest_angle(q_ll_b, duration_s)
        self.t_s += duration_s
        self.drive_state = self.drive_state.at_time(self.t_s)
        self.totals.idle_s_jumped += duration_s
        return samples

    def drive_straight(
        self, distance_m: float, max_cycles: int | None = None, drag_wheel: str | None = None
    ) -> Segment:
        """Drive ``distance_m`` (> 0) straight ahead; returns its truth and sensor samples.
        ``max_cycles``: the drive halted after that many of its control cycles (``_drive``);
        ``drag_wheel``: the wheel the command leaves undriven (module docstring)."""
        steer = bool(np.any(self.drive_state.steer_rad != 0.0))
        drag = self.drag(drag_wheel)
        return self._drive(
            lambda start, n: drive.drive_straight(
                self.terrain, start, distance_m, self.slip, max_cycles=n, drag=drag
            ),
            steer,
            max_cycles,
        )

    def drive_arc(
        self,
        radius_m: float,
        angle_rad: float,
        max_cycles: int | None = None,
        drag_wheel: str | None = None,
    ) -> Segment:
        """Drive along an arc (see ``sim.rover.drive.drive_arc`` for the signs)."""
        drag = self.drag(drag_wheel)
        return self._drive(
            lambda start, n: drive.drive_arc(
                self.terrain, start, radius_m, angle_rad, self.slip, max_cycles=n, drag=drag
            ),
            True,
            max_cycles,
        )

    def turn_in_place(
        self, angle_rad: float, max_cycles: int | None = None, drag_wheel: str | None = None
    ) -> Segment:
        """Turn in place by ``angle_rad`` (positive: clockwise seen from above, to the right)."""
        drag = self.drag(drag_wheel)
        return self._drive(
            lambda start, n: drive.turn_in_place(
                self.terrain, start, angle_rad, self.slip, max_cycles=n, drag=drag
            ),
            True,
            max_cycles,
        )

    def drag(self, drag_wheel: str | None = None) -> Drag | None:
        """The wheels a drive drags: the command's ``drag_wheel`` and the failed motor's."""
        return Drag.of(drag_wheel, self._failed_wheel)

    def _drive(
        self,
        primitive: Callable[
            [drive.DriveState, int | None], tuple[TruthTrajectory, drive.DriveState]
        ],
        steers: bool,
        max_cycles: int | None = None,
    ) -> Segment:
        """Run a drive primitive. Steering the corner wheels at rest moves their contact
        points and so the body's attitude: when the wheels steer, one control cycle of
        steering comes first, from the pose at rest to the primitive's first (steered)
        pose, so that the IMU and the truth see the change.

        ``max_cycles``: fault protection halted the drive after that many control cycles
        of the segment (the steering cycle counted): loaded back to the state before the
        drive, the simulator makes the same segment cut there (``sim.rover.drive.cut_cycles``).
        """
        before = self.drive_state
        start = before.at_time(before.t_s + CONTROL_DT_S) if steers else before
        n = None if max_cycles is None else max(1, drive.cut_cycles(max_cycles) - int(steers))
        traj, self.drive_state = primitive(start, n)
        if steers:
            traj = _prepend(before.as_trajectory(), traj)
        return self._sense(traj)

    def rest_cycles(self, duration_s: float) -> ImuSamples:
        """Stay still for ``duration_s`` with every 8 Hz IMU sample (the last may be short),
        for the modes that average the accelerometers sample by sample."""
        if not (math.isfinite(duration_s) and duration_s > 0.0):
            raise InputError("duration_s", "must be positive and finite")
        n = max(1, math.ceil(duration_s / CONTROL_DT_S - 1e-9))
        t = self.t_s + np.minimum(np.arange(n + 1) * CONTROL_DT_S, duration_s)
        q_ll_b = self.q_ll_b()
        samples = self.imu.measure(t, np.tile(q_ll_b, (n + 1, 1)), self.omega_mars_ll)
        self.totals.rest_s += duration_s
        self.totals.gyro_rest_angle_b += samples.delta_angle_b.sum(axis=0)
        self.totals.truth_rest_angle_b += self._inertial_rest_angle(q_ll_b, duration_s)
        self.t_s = float(t[-1])
        self.drive_state = self.drive_state.at_time(self.t_s)
        return samples

    def pancam_sun_image(self, az_rad: float, el_rad: float) -> SunImage:
        """A Pancam solar-filter frame now, the mast commanded to ``(az_rad, el_rad)``. Dust
        (``condition.pancam_tau``, a fault) dims and blurs it along the slant path: the
        optical depth over the cosine of the sun's zenith angle (at least 0.05)."""
        sun_ll = self.sun_ll()
        sun_b = Rotation.from_quat(self.q_ll_b()).inv().apply(sun_ll)
        az_true = az_rad + float(self.mast_bias_rad[0])
        el_true = el_rad + float(self.mast_bias_rad[1])
        tau = self.condition.pancam_tau
        if tau > 0.0:  # LL z is Down: the sun's zenith cosine is -sun_ll[2]
            slant = tau / max(-float(sun_ll[2]), 0.05)
            return render_sun_image(sun_b, az_true, el_true, self._rng_cam, dust_slant_tau=slant)
        return render_sun_image(sun_b, az_true, el_true, self._rng_cam)

    def navcam_pair(
        self, az_rad: float = 0.0, el_rad: float | None = None, **options: Any
    ) -> NavcamPair:
        """A Navcam stereo pair now (``sim.sensors.navcam.camera.render_navcam_pair``) from the
        truth pose and the true Sun, the mast commanded to ``(az_rad, el_rad)`` (default elevation:
        the renderer's, 35 deg down). The Navcams share the Pancam mast head, so the mast's
        pointing bias applies to them too; ``pair.az_rad``, ``pair.el_rad`` are the true
        pointing. ``options`` go to the renderer (``rig``, ``shadows``, ``rover_shadow``,
        ``noise``, ...); the noise draws from the simulator's camera generator unless an
        ``rng`` is given. The Sun's LL direction is used as Site axes (they differ by the
        rover's distance over the Mars radius, ~1e-5 rad here). Failed Navcams (a fault,
        ``condition.navcam_failed``) give no pair: ``NavcamFailedError`` (an ``InputError``).
        """
        if self.condition.navcam_failed:
            raise NavcamFailedError()
        from sim.sensors.navcam.camera import DEFAULT_EL_RAD, render_navcam_pair

        el_cmd = DEFAULT_EL_RAD if el_rad is None else el_rad
        if not math.isfinite(az_rad):
            raise InputError("az_rad", f"must be finite, got {az_rad}")
        if not (math.isfinite(el_cmd) and abs(el_cmd) <= 0.5 * math.pi):
            raise InputError("el_rad", f"must be in [-pi/2, pi/2], got {el_cmd}")
        az_true = az_rad + float(self.mast_bias_rad[0])
        el_true = min(max(el_cmd + float(self.mast_bias_rad[1]), -0.5 * math.pi), 0.5 * math.pi)
        kwargs: dict[str, Any] = {"rng": self._rng_cam, **options}
        return render_navcam_pair(
            self.terrain,
            self.drive_state.p_s,
            self.drive_state.q_s_b,
            self.sun_ll(),
            az_rad=az_true,
            el_rad=el_true,
            **kwargs,
        )

    def suspension_readings(self, seg: Segment) -> tuple[FloatArray, FloatArray]:
        """The rocker (N,) and bogie (N, 2) encoders' readings, rad, at each cycle of
        ``seg`` after its start (what mobility fault protection reads)."""
        traj = seg.truth
        return self.suspension_encoders.read_angles(traj.rocker_rad[1:], traj.bogie_rad[1:])

    def wheel_angle_rad_now(self) -> FloatArray:
        """The wheel encoders' angles now (6,), rad since power-on, as the flight
        software reads them (quantised)."""
        out: FloatArray = self.encoders.wheel_angle_rad(np.asarray(self._encoder_counts))
        return out

    # ---- truth views ----------------------------------------------------------------

    def sun_ll(self) -> FloatArray:
        """Truth apparent sun direction in LL now, unit (3,)."""
        out: FloatArray = sun_ll_truth(self.t_s, self.lat_rad, self.lon_east_rad)
        return out

    def earth_ll(self) -> FloatArray:
        """Truth apparent Earth direction in LL now, unit (3,)."""
        out: FloatArray = earth_ll_truth(self.t_s, self.lat_rad, self.lon_east_rad)
        return out

    def q_ll_b(self) -> FloatArray:
        """Truth attitude of the body in the Local-Level frame at the rover, ``[x, y, z, w]``.
        It depends on the pose alone, so a rover at rest (the camera modes' many images)
        computes it once per pose."""
        state = self.drive_state
        pose = state.q_s_b.tobytes() + state.p_s.tobytes()
        if self._q_ll_b_of_pose[0] != pose:
            q = q_ll_b_from_site(
                state.q_s_b[None, :], state.p_s[None, :], self.lat_rad, self.lon_east_rad
            )
            self._q_ll_b_of_pose = (pose, q[0])
        return self._q_ll_b_of_pose[1].copy()

    # ---- internals ------------------------------------------------------------------

    def _inertial_rest_angle(self, q_ll_b: FloatArray, duration_s: float) -> FloatArray:
        R_b_ll = Rotation.from_quat(q_ll_b).inv()
        out: FloatArray = R_b_ll.apply(self.omega_mars_ll * duration_s)
        return out

    def _sense(self, traj: TruthTrajectory) -> Segment:
        q_ll_b = q_ll_b_from_site(traj.q_s_b, traj.p_s, self.lat_rad, self.lon_east_rad)
        # The accelerometers sense the rover's own accelerations too (starting and stopping,
        # climbing over rocks): Ali et al. 2005 uses them only at rest, but the radio EKF (Jiang, Li
        # et al. 2014, eq. 2) integrates them. Site and LL axes differ by ~1e-5 rad here: ignored.
        accel = traj.accel_s_from_rest()
        samples = self.imu.measure(traj.t_s, q_ll_b, self.omega_mars_ll, accel_ll=accel)
        encoders = self.encoders.read(traj)
        counts = encoders.wheel_counts
        wheel_rad = self.encoders.wheel_angle_rad(counts[-1] - self._encoder_counts)
        self._encoder_counts = counts[-1]
        self.steer_reading_rad = encoders.steer_rad[-1].copy()
        totals = self.totals
        totals.cycles_simulated += len(traj) - 1
        totals.distance_truth_m += float(np.sum(np.linalg.norm(np.diff(traj.p_s, axis=0), axis=1)))
        totals.distance_odometry_m += float(np.mean(wheel_rad)) * MER_GEOMETRY.wheel_radius_m
        yaw = Rotation.from_quat(traj.q_s_b).as_euler("ZYX")[:, 0]
        totals.heading_change_rad += float(np.sum(np.angle(np.exp(1j * np.diff(yaw)))))
        totals.max_wheel_gap_m = max(totals.max_wheel_gap_m, self.drive_state.max_gap_m)
        totals.unsettled_poses += self.drive_state.unsettled_poses
        self.t_s = float(traj.t_s[-1])
        seg = Segment(traj, samples, encoders)
        if self.on_segment is not None:
            self.on_segment(seg)
        return seg


def _plain(value: Any) -> Any:
    return value.copy() if isinstance(value, np.ndarray) else value


def drive_state_dict(state: drive.DriveState) -> dict[str, Any]:
    """A ``DriveState`` as plain data (its fields; arrays copied)."""
    return {f.name: _plain(getattr(state, f.name)) for f in fields(drive.DriveState)}


def drive_state_from_dict(state: Mapping[str, Any]) -> drive.DriveState:
    """The ``DriveState`` of ``drive_state_dict``."""
    return drive.DriveState(**_arrays(state))


def _arrays(state: Mapping[str, Any]) -> dict[str, Any]:
    """``state`` with its lists and arrays as float arrays (a dataclass's fields)."""
    return {
        k: np.array(v, dtype=np.float64) if isinstance(v, list | np.ndarray) else v
        for k, v in state.items()
    }


def _prepend(first: TruthTrajectory, rest: TruthTrajectory) -> TruthTrajectory:
    """One trajectory: the sample(s) of ``first`` then those of ``rest``."""
    return TruthTrajectory(
        **{
            f.name: np.concatenate([getattr(first, f.name), getattr(rest, f.name)])
            for f in fields(TruthTrajectory)
        }
    )
