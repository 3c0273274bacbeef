"""Estimators that run beside SAPP in a rover session, on the same drives, so that operators
can compare them (the fusion issue, item 3).

``KinematicEkfRunner`` runs Balaram's kinematic EKF (``estimation.fusion.kinematic.ekf``,
Balaram 2000) on every drive segment, sample for sample at 8 Hz, from the sensors the rover
has: the IMU's gyros (the heading gyro, eqs. 12-13), the wheel and steering encoders and
the rocker/bogie joint encoders (the slip constraints, eqs. 17-20) and a WASS-like sun
sensor (eqs. 15-16, with IVP's sun as the reference), and the drive's commanded rates
(what the driving software commanded: eq. 1's inputs, from the second control cycle when
the drive steers first). At rest the rover does not move and the filter is left as it is.
The rover drives each wheel at its commanded rate, so the filter takes the rolling slip
noise of rate-controlled wheels (``kinematic_ekf.RATE_CONTROLLED_WHEELS``), not the
paper's compliant ones.

It starts from SAPP's estimate at the first drive it sees (it has no attitude acquisition
of its own) and from then on runs on its own. It works in the mission frame (the first
Site: x North, y East, z Down), so Site changes do not concern it. Its noise sensors
(joint encoders, sun sensor) draw from their own generators, seeded from the session's.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from estimation.fusion.kinematic.ekf import RATE_CONTROLLED_WHEELS, KinematicEkf
from estimation.fusion.kinematic.encoder_rates import interval_rates
from estimation.fusion.kinematic.rover_kinematics import steer_per_wheel
from estimation.fusion.kinematic.slip_constraint import JointRates
from estimation.ivp import mars_rotation_ll, sun_ll
from sim.loop.rover_sim import RoverSim, Segment
from sim.rover.drive import DEFAULT_SPEED_M_S, DEFAULT_TURN_RATE_RAD_S
from sim.sensors.joint_encoders import JointEncoderParams, JointEncoders
from sim.sensors.sun_sensor import SunSensorParams, SunSensorSamples, WassSunSensor
from sim.world.mars_frames import sun_ll_truth

FloatArray = NDArray[np.float64]

# A corner steered by more than this stands steered: 10 σ of the steering sensors' 0.05 deg
# (``sim.sensors.encoders``), and the corners of an arc up to ~80 m radius.
STEERED_RAD = math.radians(0.5)


@dataclass(frozen=True)
class SideEstimate:
    """An estimator's pose per sample of a segment: mission-frame positions (N, 3), m, and
    ``q_b_ll`` (N, 4) (``[x, y, z, w]``; LL and mission axes agree to ~1e-5 rad), ``None``
    for an estimator of position only."""

    p_mission: FloatArray
    q_b_ll: FloatArray | None


@dataclass(frozen=True)
class DriveInputs:
    """What a side estimator gets of a drive segment besides the segment itself (its truth,
    for the sensors ``sim/`` models, and its IMU): the command ``kind`` and ``args``
    (``commanded_rates``); the wheel (N, 6) and corner steering (N, 4) encoders as the flight
    software read them, rad; SAPP's ``(p_mission, q_b_ll)`` before the drive (``start``) and
    its attitude ``sapp_q_b_ll`` (N, 4) at each sample."""

    kind: str
    args: tuple[float, ...]
    wheel_rad: FloatArray
    steer_rad: FloatArray
    start: tuple[FloatArray, FloatArray]
    sapp_q_b_ll: FloatArray


class SideRunner(Protocol):
    """An estimator beside SAPP: its name, its pose now (``None`` before it starts), a drive
    segment, and the rover at rest at ``p_s_true`` (truth, for ``sim/``'s sensor models)
    until ``t_s``."""

    name: str

    def estimate_now(self) -> tuple[FloatArray, FloatArray | None] | None: ...

    def drive(self, seg: Segment, inputs: DriveInputs) -> SideEstimate: ...

    def rest_until(self, t_s: float, p_s_true: FloatArray) -> None: ...

    def state(self) -> dict[str, Any]: ...

    def load_state(self, state: Mapping[str, Any]) -> None: ...


def starts_with_steering(kind: str, steer_rad: FloatArray) -> bool:
    """Whether a drive segment begins with a control cycle of steering at rest
    (``sim.loop.rover_sim``): a turn or an arc always does; a straight drive does when its corner
    wheels stood steered before it, which the steering sensors say (``steer_rad`` (N, 4),
    rad, its first sample before the drive). An arc wider than ~80 m leaves its wheels
    within ``STEERED_RAD`` of straight; a straight after it then starts a cycle early."""
    if kind in ("turn", "arc"):
        return True
    return bool(np.max(np.abs(steer_rad[0])) > STEERED_RAD)


def commanded_rates(
    kind: str, args: tuple[float, ...], t_s: FloatArray, steering_cycle: bool | None = None
) -> tuple[FloatArray, FloatArray]:
    """The commanded body velocity (m/s) and rate (rad/s) over each interval of a segment
    (N-1, 3) each: the drive moves at its speed from the first sample until it is done, or
    from the second when the segment begins with a ``steering_cycle``
    (``starts_with_steering``; ``None``: a turn or an arc does, a straight does not, as
    from straight wheels).

    >>> v, w = commanded_rates("straight", (0.075,), np.array([0.0, 1.0, 2.0, 3.0]))
    >>> v[:, 0].round(4).tolist(), float(abs(w).max())
    ([0.0375, 0.0375, 0.0], 0.0)
    >>> v, w = commanded_rates("straight", (0.075,), np.array([0.0, 1.0, 2.0, 3.0]), True)
    >>> v[:, 0].round(4).tolist()
    [0.0, 0.0375, 0.0375]
    """
    if kind not in ("straight", "arc", "turn"):
        raise ValueError(f"kind: must be straight, arc or turn, got {kind!r}")
    start = int(kind != "straight" if steering_cycle is None else steering_cycle)
    v = np.zeros((t_s.size - 1, 3))
    w = np.zeros((t_s.size - 1, 3))

    def profile(amount: float, rate: float) -> FloatArray:
        elapsed = np.clip(t_s - t_s[min(start, t_s.size - 1)], 0.0, None)
        done = np.minimum(elapsed * rate, amount)
        out: FloatArray = np.diff(done) / np.diff(t_s)
        return out

    if kind == "straight":
        v[:, 0] = profile(args[0], DEFAULT_SPEED_M_S)
    elif kind == "arc":
        radius, angle = args
        speed = profile(abs(radius) * angle, DEFAULT_SPEED_M_S)
        v[:, 0] = speed
        w[:, 2] = math.copysign(1.0, radius) * speed / abs(radius)  # > 0 centre on the right
    else:
        (angle,) = args
        w[:, 2] = math.copysign(1.0, angle) * profile(abs(angle), DEFAULT_TURN_RATE_RAD_S)
    return v, w


def kinematic_ekf_intervals(
    ekf: KinematicEkf,
    t_s: FloatArray,
    v_c_b: FloatArray,
    omega_c_b: FloatArray,
    delta_angle_b: FloatArray,
    frame_rate_s: FloatArray,
    gamma_rad: FloatArray,
    steer_rad: FloatArray,
    wheel_rad: FloatArray,
    sun: SunSensorSamples,
    sun_ref_s: FloatArray,
) -> Iterator[int]:
    """Step ``ekf`` through the intervals of a drive, yielding each interval's index ``k``
    once the filter stands at ``t_s[k + 1]``: the command, half the propagation, the gyro
    (eqs. 12-13) and slip (eqs. 17-20) updates at the interval's middle, the other half, and
    the sun sensor (eqs. 15-16) when it sees the sun. Per sample (N,): ``t_s``, ``gamma_rad``
    (N, 3) joint angles, ``steer_rad`` (N, 4) corner steering, ``wheel_rad`` (N, 6),
    ``sun``, ``sun_ref_s`` (N, 3); per interval (N-1,): the commands (N-1, 3) and the IMU's
    ``delta_angle_b`` (N-1, 3); ``frame_rate_s`` the Site frame's rate (Mars rotation)."""
    dt = np.diff(t_s)
    # each interval's inputs for the whole drive at once (the same arithmetic per element)
    gamma_rate = interval_rates(gamma_rad, t_s)
    gamma_mid = 0.5 * (gamma_rad[:-1] + gamma_rad[1:])
    sigma = steer_per_wheel(steer_rad)
    sigma_mid = 0.5 * (sigma[:-1] + sigma[1:])
    sigma_rate = np.diff(sigma, axis=0) / dt[:, None]
    psi_rate = np.diff(wheel_rad, axis=0) / dt[:, None]
    omega_m = np.asarray(delta_angle_b) @ ekf.B_g.T / dt[:, None]
    for k in range(dt.size):
        ekf.set_command(v_c_b[k], omega_c_b[k])
        ekf.propagate(0.5 * dt[k])
        ekf.update_gyro(omega_m[k], frame_rate_s)
        ekf.update_slip(
            JointRates(gamma_mid[k], gamma_rate[k], sigma_mid[k], sigma_rate[k], psi_rate[k])
        )
        ekf.propagate(0.5 * dt[k])
        if sun.valid[k + 1]:
            ekf.update_sun(sun.s_m[k + 1], sun_ref_s[k + 1])
        yield k


class KinematicEkfRunner:
    """Balaram's kinematic EKF beside SAPP (module docstring)."""

    name = "kinematic_ekf"

    def __init__(self, sim: RoverSim, seed: int) -> None:
        rng_joint, rng_sun = np.random.default_rng([seed, 7001]).spawn(2)
        self.joints = JointEncoders(JointEncoderParams(), rng_joint)
        self.sun_sensor = WassSunSensor(SunSensorParams(), rng_sun)
        self.lat_rad, self.lon_east_rad = sim.lat_rad, sim.lon_east_rad
        self.frame_rate_ll = mars_rotation_ll(sim.lat_rad)
        self.ekf: KinematicEkf | None = None

    def estimate_now(self) -> tuple[FloatArray, FloatArray | None] | None:
        """``(p_mission, q_b_ll)`` now, or ``None`` before the first drive."""
        if self.ekf is None:
            return None
        return self._pose()

    def rest_until(self, t_s: float, p_s_true: FloatArray) -> None:
        """At rest the filter is left as it is (module docstring)."""

    def drive(self, seg: Segment, inputs: DriveInputs) -> SideEstimate:
        """Run the filter through ``seg`` (its IMU and sun/joint sensors on its truth) with
        the encoders and commands of ``inputs``; a filter not started yet starts at SAPP's
        ``inputs.start``. Returns the estimate at each sample of the segment (its first =
        before moving)."""
        kind, args, wheel_rad, steer_rad = (
            inputs.kind,
            inputs.args,
            inputs.wheel_rad,
            inputs.steer_rad,
        )
        if self.ekf is None:
            p0, q_b_ll0 = inputs.start
            self.ekf = _new_ekf(Rotation.from_quat(q_b_ll0).inv().as_quat(), p0)
        ekf = self.ekf
        truth = seg.truth
        t = truth.t_s
        joints = self.joints.read(truth)
        q_s_b = truth.q_s_b
        sun_ref = sun_ll(t, self.lat_rad, self.lon_east_rad)  # IVP's: the filter's reference
        sun_true = sun_ll_truth(t, self.lat_rad, self.lon_east_rad)
        sun = self.sun_sensor.measure(t, q_s_b, sun_true)
        gamma = np.column_stack([joints.rocker_rad, joints.bogie_rad])
        v_c, w_c = commanded_rates(kind, args, t, starts_with_steering(kind, steer_rad))
        p = np.empty((t.size, 3))
        q = np.empty((t.size, 4))
        p[0], q[0] = self._pose()
        steps = kinematic_ekf_intervals(
            ekf, t, v_c, w_c, seg.imu.delta_angle_b, self.frame_rate_ll, gamma, steer_rad,
            wheel_rad, sun, sun_ref,
        )  # fmt: skip
        for k in steps:
            p[k + 1], q[k + 1] = self._pose()
        ekf.set_command(np.zeros(3), np.zeros(3))  # at rest until the next drive
        return SideEstimate(p, q)

    def state(self) -> dict[str, Any]:
        """The sensors' generators and the filter (``None`` before the first drive)."""
        return {
            "joints": self.joints.state(),
            "sun_sensor": self.sun_sensor.state(),
            "ekf": None if self.ekf is None else self.ekf.state(),
        }

    def load_state(self, state: Mapping[str, Any]) -> None:
        """Load ``state`` (``state()``) onto a runner built for the same session."""
        self.joints.load_state(state["joints"])
        self.sun_sensor.load_state(state["sun_sensor"])
        self.ekf = None
        if state["ekf"] is not None:
            self.ekf = _new_ekf(np.array([0.0, 0.0, 0.0, 1.0]), np.zeros(3))
            self.ekf.load_state(state["ekf"])

    def _pose(self) -> tuple[FloatArray, FloatArray]:
        assert self.ekf is not None
        est = self.ekf.estimate()
        return est.p_s, est.q_b_s


def _new_ekf(q_s_b0: FloatArray, p0: FloatArray) -> KinematicEkf:
    """The filter at ``(q_s_b0, p0)``: the LN-200 has three axes; the rover drives its
    wheels at their commanded rates."""
    return KinematicEkf(q_s_b0, p0, gyro="3axis", noise=RATE_CONTROLLED_WHEELS)
