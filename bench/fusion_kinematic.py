"""Balaram's kinematic EKF on surface eq. 22: the figures of Balaram 2000 sec. 4.1.

Two experiments of the paper, Monte Carlo over seeds (sensor noise, the filter's initial
attitude and position drawn from its own initial covariance):

- a 1 m straight drive (paper: averaged wheel odometry 1.0204 m, 2 % error; the EKF
  1.0036 m, 0.3 %; cross-track error up to 14 mm);
- a 360 deg turn in place (paper Fig. 13: "excellent attitude tracking").

Set-up as the paper's: the Sun fixed along ``[-1, 1, 1]/√3`` in the paper's frame, whose
z is up; our Site frame is North, East, Down and eq. 22's ``(x, y)`` are Site ``(x, y)``
(``sim.terrain``), so the Sun is ``[-1, 1, -1]/√3`` in Site axes (35 deg high in the
South-East). No slip in the rolling direction: the rover rolls ideally (``slip=False``)
and its wheels turn as a compliant controller turns them (``sim.rover.compliant_wheels``), as
in the paper's simulator. Sensors: the heading gyro (the LN-200's z axis), the WASS
(``sim.sensors.sun_sensor``), the wheel and steering encoders (``sim.sensors.encoders``) and the
rocker/bogie sensors (``sim.sensors.joint_encoders``), all at 8 Hz.

Where: Balaram's Rocky-7 straddled eq. 22's two features (a bump at ``(0.5, 0.2)``, a
hollow at ``(0.5, -0.2)``) from the origin; our MER-sized rover (track 1.2 m) would pass
them under its belly, so it starts at ``(1.1, -0.5)`` heading East and its right wheels
cross both. The turn is made at the same place.

Distances: the true distance is the straight-line displacement of the body origin; the
odometry's is the mean wheel rotation times the wheel radius; the EKF's the displacement
of its position estimate. Errors are in % of the true distance. The attitude error is
the angle of ``q̂⁻¹ ⊗ q_true``. NEES: ``eᵀ P⁻¹ e`` of the 6-dim pose error (attitude small
angles in body axes and position in Site axes, the filter's own ``θ`` and ``x`` blocks),
averaged over every 8 Hz sample of every run: a consistent filter gives 6. It is also
given per experiment: on the straight drive the position part is overconfident, because
the wheels' transverse slip on the curved surface is one-directional for the whole metre
while the filter models it as white noise (the paper's 14 mm cross-track error, sec.
4.1.1); on the turn the filter is conservative.

Joint rates reach the filter as the flight software would make them: the rocker/bogie
angles smoothed and differenced (``estimation.fusion.kinematic.encoder_rates``, one sample late,
which the bench absorbs by handing each interval's rates to that interval's update).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from estimation.fusion.kinematic.ekf import KinematicEkf
from estimation.ivp import mars_rotation_ll
from sim.errors import InputError
from sim.loop.rover_sim import RoverSim, Segment
from sim.loop.side.kinematic import commanded_rates, kinematic_ekf_intervals
from sim.rover.compliant_wheels import with_compliant_wheels
from sim.rover.geometry import MER_GEOMETRY
from sim.sensors.encoders import EncoderParams, MobilityEncoders
from sim.sensors.joint_encoders import JointEncoderParams, JointEncoders
from sim.sensors.sun_sensor import SunSensorParams, WassSunSensor

FloatArray = NDArray[np.float64]

START_UTC = datetime(2004, 4, 14, 12, 0, 0, tzinfo=UTC)
SUN_S = np.array([-1.0, 1.0, -1.0]) / math.sqrt(3.0)  # Balaram 2000 sec. 4.1, z flipped to Down
START_X_M, START_Y_M, START_YAW_RAD = 1.1, -0.5, math.pi / 2  # right wheels over both bumps
STRAIGHT_M = 1.0
TURN_RAD = 2.0 * math.pi
POSE_DIM = 6  # NEES over attitude (3) and position (3)


@dataclass(frozen=True)
class RunResult:
    """One run's figures (units in the names); ``nees`` (K,) per 8 Hz sample."""

    distance_true_m: float
    distance_odometry_m: float
    distance_ekf_m: float
    cross_track_max_m: float
    attitude_err_rad: FloatArray
    nees: FloatArray


def _filter_start(
    q_s_b: FloatArray, p_s: FloatArray, rng: np.random.Generator, options: dict[str, Any]
) -> tuple[KinematicEkf, FloatArray]:
    """A filter whose initial error is drawn from its own initial covariance."""
    probe = KinematicEkf(q_s_b, p_s, **options)
    L = probe.layout
    sd = np.sqrt(np.diag(probe.P))
    theta0 = sd[L.THETA] * rng.standard_normal(3)
    # q_true = q_est ⊗ δq(θ): the estimate is the truth turned back by θ.
    q_est = (Rotation.from_quat(q_s_b) * Rotation.from_rotvec(theta0).inv()).as_quat()
    p_est = p_s - sd[L.X] * rng.standard_normal(3)
    return KinematicEkf(q_est, p_est, **options), np.concatenate([theta0, p_s - p_est])


def _pose_error(ekf: KinematicEkf, q_s_b: FloatArray, p_s: FloatArray) -> FloatArray:
    theta = (Rotation.from_quat(ekf.q_s_b).inv() * Rotation.from_quat(q_s_b)).as_rotvec()
    return np.concatenate([theta, p_s - ekf.X[ekf.layout.X]])


def _nees(ekf: KinematicEkf, err: FloatArray) -> float:
    L = ekf.layout
    idx = np.r_[np.arange(L.n)[L.THETA], np.arange(L.n)[L.X]]
    P = ekf.P[np.ix_(idx, idx)]
    return float(err @ np.linalg.solve(P, err))


def run_once(kind: str, seed: int, **filter_options: Any) -> RunResult:
    """One straight drive (``kind="straight"``) or turn in place (``"turn"``) with the EKF;
    ``filter_options`` go to ``KinematicEkf`` (``noise``, ``process``, ``gyro``, ...)."""
    if kind not in ("straight", "turn"):
        raise InputError("kind", f"must be 'straight' or 'turn', got {kind!r}")
    sim = RoverSim(
        "eq22", seed, START_UTC, slip=False, x_m=START_X_M, y_m=START_Y_M, yaw_rad=START_YAW_RAD
    )
    rng_enc, rng_joint, rng_sun, rng_init = np.random.default_rng([seed, 1001]).spawn(4)
    seg: Segment = (
        sim.drive_straight(STRAIGHT_M) if kind == "straight" else sim.turn_in_place(TURN_RAD)
    )
    truth = with_compliant_wheels(sim.terrain, seg.truth)
    t = truth.t_s
    encoders = MobilityEncoders(EncoderParams(), rng_enc)
    enc = encoders.read(truth)
    wheel = encoders.wheel_angle_rad(enc.wheel_counts - enc.wheel_counts[0])
    joints = JointEncoders(JointEncoderParams(), rng_joint).read(truth)
    sun = WassSunSensor(SunSensorParams(), rng_sun).measure(t, truth.q_s_b, SUN_S)
    gamma = np.column_stack([joints.rocker_rad, joints.bogie_rad])
    frame_s = mars_rotation_ll(sim.lat_rad)  # Site axes are the planting LL axes

    amount = (STRAIGHT_M,) if kind == "straight" else (TURN_RAD,)
    v_c, w_c = commanded_rates(kind, amount, t)  # what the flight software commanded

    ekf, err0 = _filter_start(truth.q_s_b[0], truth.p_s[0], rng_init, filter_options)
    p_est0 = ekf.X[ekf.layout.X].copy()
    att_err, nees = [float(np.linalg.norm(err0[:3]))], [_nees(ekf, err0)]
    cross = 0.0
    heading = truth.p_s[-1, :2] - truth.p_s[0, :2]
    across = np.array([-heading[1], heading[0]]) / max(float(np.linalg.norm(heading)), 1e-12)
    sun_ref = np.broadcast_to(SUN_S, (t.size, 3))
    steps = kinematic_ekf_intervals(
        ekf, t, v_c, w_c, seg.imu.delta_angle_b, frame_s, gamma, enc.steer_rad, wheel, sun,
        sun_ref,
    )  # fmt: skip
    for k in steps:
        err = _pose_error(ekf, truth.q_s_b[k + 1], truth.p_s[k + 1])
        att_err.append(float(np.linalg.norm(err[:3])))
        nees.append(_nees(ekf, err))
        if kind == "straight":
            cross = max(cross, abs(float(across @ err[3:5])))
    p_est = ekf.X[ekf.layout.X]
    return RunResult(
        distance_true_m=float(np.linalg.norm(truth.p_s[-1] - truth.p_s[0])),
        distance_odometry_m=float(np.mean(wheel[-1] - wheel[0])) * MER_GEOMETRY.wheel_radius_m,
        distance_ekf_m=float(np.linalg.norm(p_est - p_est0)),
        cross_track_max_m=cross,
        attitude_err_rad=np.array(att_err),
        nees=np.array(nees),
    )


def bench_fusion_kinematic(n_runs: int = 10, first_seed: int = 1) -> dict[str, Any]:
    """The kinematic EKF's figures over ``n_runs`` seeds of each experiment.

    Returns ``{"metrics": {...}, "targets": {...}}`` (units in the keys; targets as
    ``bench.result``: ``{"le": x}``). Distance errors are the mean of ``|error|`` over the
    runs; the attitude figures are the max and the RMS over every sample of every turn.
    """
    if not (isinstance(n_runs, int) and 1 <= n_runs <= 1000):
        raise InputError("n_runs", "must be an integer in 1..1000")
    seeds = range(first_seed, first_seed + n_runs)
    straight = [run_once("straight", s) for s in seeds]
    turns = [run_once("turn", s) for s in seeds]

    def pct(est: float, true: float) -> float:
        return 100.0 * abs(est - true) / true

    odo = [pct(r.distance_odometry_m, r.distance_true_m) for r in straight]
    ekf = [pct(r.distance_ekf_m, r.distance_true_m) for r in straight]
    att_deg = np.degrees(np.concatenate([r.attitude_err_rad for r in turns]))
    nees = np.concatenate([r.nees for r in straight + turns])
    metrics = {
        "eq22_straight_odometry_err_pct": float(np.mean(odo)),
        "eq22_straight_ekf_err_pct": float(np.mean(ekf)),
        "eq22_straight_ekf_err_pct_max": float(np.max(ekf)),
        "eq22_straight_cross_track_max_mm": 1e3 * max(r.cross_track_max_m for r in straight),
        "eq22_turn_attitude_err_deg_max": float(np.max(att_deg)),
        "eq22_turn_attitude_err_deg_rms": float(np.sqrt(np.mean(att_deg**2))),
        "kinematic_ekf_nees": float(np.mean(nees)),
        "kinematic_ekf_nees_straight": float(np.mean(np.concatenate([r.nees for r in straight]))),
        "kinematic_ekf_nees_turn": float(np.mean(np.concatenate([r.nees for r in turns]))),
        "kinematic_ekf_nees_dim": POSE_DIM,
        "kinematic_ekf_runs": n_runs,
    }
    targets = {"eq22_straight_ekf_err_pct": {"le": 0.3}}
    return {"metrics": metrics, "targets": targets}
