"""Jiang, Li et al. 2014's scenario on our simulator: a 1000 s drive during a relay pass, with its
sensors.

Jiang, Li et al. 2014 sec. 5: the rover drives a random 2-D trajectory for 1000 s, sampled at 1 s.
Here ``RoverSim`` drives a random chain of straight legs and arcs on Meridiani Planum
(flat plains, as the paper's 2-D model assumes; MER speed 3.75 cm/s, with slip), timed so
the relay orbiter (``sim.sensors.orbiter``) culminates above 45° mid-drive.

The IMU is ``sim.sensors.imu``'s model with the *paper's* settings rather than the LN-200's
(Jiang, Li et al. 2014 sec. 5, "according to the parameters of the MER IMU"): accelerometer bias
3e-3 m/s² and gyro bias 5e-6 rad/s (drawn per axis with those 1σ: the paper gives
fixed values, a Monte Carlo needs draws of that size), white noise of variance 5e-8
(m/s²)² and 9e-8 (rad/s)² per 1 s sample (the LN-200's are 2.2x and 0.1x those), no bias
instability. Unlike ``RoverSim``'s own quasi-static IMU, this one senses the rover's
accelerations (eq. 2 integrates them). The onboard attitude for eq. 1 is the gyros'
propagation (``estimation.sapp.gyro_propagation``) from the true attitude at the start, as
after SAPP's fine attitude with no heading error (the paper assumes attitude known).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation, Slerp

from estimation.fusion.radio.ekf import RadioEkfTuning
from estimation.fusion.radio.models import radii_of_curvature_m
from estimation.ivp import mars_rotation_ll
from estimation.sapp.gyro_propagation import propagate_gyro
from sim.loop.rover_sim import RoverSim
from sim.rover.truth import CONTROL_DT_S
from sim.sensors.imu import (
    DEG_PER_H_TO_RAD_S,
    DEG_PER_SQRT_H_TO_RAD_PER_SQRT_S,
    STANDARD_GRAVITY_M_S2,
    Ln200Imu,
    Ln200Params,
)
from sim.sensors.orbiter import RelayOrbiter
from sim.world.local_level import q_ll_b_from_site
from sim.world.mars_frames import mf_from_site_m, site_mf_m
from sim.world.marsclock import t_s_to_utc

FloatArray = NDArray[np.float64]

SITE = "meridiani"
DURATION_S = 1000.0  # Jiang, Li et al. 2014 sec. 5
STEP_S = 1.0
PAPER_IMU = Ln200Params(
    gyro_bias_turn_on_deg_per_h=5.0e-6 / DEG_PER_H_TO_RAD_S,  # 5e-6 rad/s
    gyro_arw_deg_per_sqrt_h=math.sqrt(9.0e-8) / DEG_PER_SQRT_H_TO_RAD_PER_SQRT_S,
    gyro_bias_instability_deg_per_h=0.0,
    accel_bias_turn_on_ug=3.0e-3 / STANDARD_GRAVITY_M_S2 * 1e6,  # 3e-3 m/s^2
    accel_noise_ug_per_sqrt_hz=math.sqrt(5.0e-8) / STANDARD_GRAVITY_M_S2 * 1e6,
)


@dataclass(frozen=True)
class RadioScenario:
    """One seed's drive and sensors on the 1 s filter grid (``K + 1`` instants).

    Truth: ``t_s`` (K+1,), ``p_s`` (K+1, 3) body origin in the Site frame, ``v_ne`` (K+1, 2).
    Onboard: ``specific_force_b`` (K, 3) mean accelerometer reading over each step in body
    axes at its start, ``euler_rad`` (K+1, 3) the gyro-propagated attitude,
    ``yaw_rate_rad_s`` (K,) heading rate over each step. ``R_s_b`` (K+1, 3, 3) truth attitude.
    """

    seed: int
    t_s: FloatArray
    p_s: FloatArray
    v_ne: FloatArray
    R_s_b: FloatArray
    specific_force_b: FloatArray
    euler_rad: FloatArray
    yaw_rate_rad_s: FloatArray
    clearance_m: float
    orbiter: RelayOrbiter
    site_lat_rad: float
    site_lon_east_rad: float

    def rover_mf_m(self) -> FloatArray:
        """Truth Mars-fixed positions (m) of the body origin, (K+1, 3)."""
        return mf_from_site_m(self.p_s, self.site_lat_rad, self.site_lon_east_rad)


# The filter's Q matched to this scenario's errors rather than the paper's (white-noise
# stand-ins for the correlated ones, ``bench.fusion_radio``; the NEES checks it).
SCENARIO_TUNING = RadioEkfTuning(q_position_m2_per_s=1.0e-3, q_velocity_m2_s2_per_s=1.0e-2)


def metres_per_radian(lat_rad: float) -> tuple[float, float]:
    """Metres per radian of latitude and of East longitude at ``lat_rad`` on the ellipsoid:
    how a Site frame's North/East map to the filter's state near its origin."""
    M, N, _, _ = radii_of_curvature_m(lat_rad)
    return M, N * math.cos(lat_rad)


SITE_LAT_RAD = math.radians(-1.95)  # Opportunity's landing site (sim.world.sites)
SITE_LON_EAST_RAD = math.radians(354.47)


def drive_starts_t_s(orbiter: RelayOrbiter, count: int) -> FloatArray:
    """Starts (TT s) of ``count`` drives, each 500 s before a culmination above 45° at the
    site, the first ones after the orbit's epoch."""
    site = site_mf_m(SITE_LAT_RAD, SITE_LON_EAST_RAD)
    epoch = orbiter.orbit.epoch_t_s
    peaks = orbiter.passes(
        epoch, 40.0 * 86_400.0, site, SITE_LAT_RAD, SITE_LON_EAST_RAD, 45.0, step_s=20.0
    )
    if peaks.size < count:
        raise ValueError(f"count: only {peaks.size} passes above 45 deg in 40 days")
    out: FloatArray = peaks[:count] - 0.5 * DURATION_S
    return out


def _truth_drive(
    sim: RoverSim, rng: np.random.Generator
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Random legs and arcs until the drive lasts ``DURATION_S``: (t, p_s, q_s_b) samples."""
    t0 = sim.t_s
    ts, ps, qs = [np.array([t0])], [sim.drive_state.p_s[None, :]], [sim.drive_state.q_s_b[None, :]]
    while ts[-1][-1] < t0 + DURATION_S + 1.0:
        if rng.random() < 0.4:
            seg = sim.drive_straight(float(rng.uniform(2.0, 6.0)))
        else:
            radius = float(rng.choice([-1.0, 1.0]) * rng.uniform(3.0, 12.0))
            seg = sim.drive_arc(radius, float(rng.uniform(0.2, 1.2)))
        keep = seg.truth.t_s > ts[-1][-1] + 1e-6
        ts.append(seg.truth.t_s[keep])
        ps.append(seg.truth.p_s[keep])
        qs.append(seg.truth.q_s_b[keep])
    return np.concatenate(ts), np.concatenate(ps), np.concatenate(qs)


def build_scenario(seed: int, orbiter: RelayOrbiter, t0_s: float) -> RadioScenario:
    """Drive from ``t0_s`` (TT s), IMU and onboard attitude for ``seed`` (deterministic)."""
    lat0, lon0, t0 = SITE_LAT_RAD, SITE_LON_EAST_RAD, t0_s
    rng_drive, rng_imu = np.random.default_rng([seed, 4]).spawn(2)
    sim = RoverSim(SITE, seed, t_s_to_utc(t0), yaw_rad=float(rng_drive.uniform(0, 2 * np.pi)))
    t_raw, p_raw, q_raw = _truth_drive(sim, rng_drive)

    per_step = round(STEP_S / CONTROL_DT_S)
    t8 = t_raw[0] + CONTROL_DT_S * np.arange(round(DURATION_S / CONTROL_DT_S) + 1)
    p8 = np.stack([np.interp(t8, t_raw, p_raw[:, i]) for i in range(3)], axis=-1)
    q8 = Slerp(t_raw, Rotation.from_quat(q_raw))(t8).as_quat()
    v8 = np.gradient(p8, t8, axis=0)
    accel = np.diff(v8, axis=0) / CONTROL_DT_S  # mean acceleration over each 8 Hz interval

    omega_ll = mars_rotation_ll(lat0)
    q_ll_b = q_ll_b_from_site(q8, p8, lat0, lon0)
    imu = Ln200Imu(PAPER_IMU, rng_imu, t_on_s=float(t8[0]))
    samples = imu.measure(t8, q_ll_b, omega_ll, accel_ll=accel)
    q_b_ll0 = Rotation.from_quat(q_ll_b[0]).inv().as_quat()
    q_b_ll_est = propagate_gyro(q_b_ll0, samples.delta_angle_b, samples.dt_s, omega_ll)
    R_ll_b_est = Rotation.from_quat(q_b_ll_est).inv().as_matrix()  # (8N+1, 3, 3)

    # Mean specific force over each 1 s step, in body axes at the step's start
    dv_ll = np.einsum("kij,kj->ki", R_ll_b_est[:-1], samples.delta_velocity_b)
    dv_ll_steps = dv_ll.reshape(-1, per_step, 3).sum(axis=1) / STEP_S
    starts = R_ll_b_est[::per_step]
    force_b = np.einsum("kji,kj->ki", starts[:-1], dv_ll_steps)
    euler = Rotation.from_matrix(starts).as_euler("ZYX")[:, ::-1]  # (roll, pitch, yaw)
    yaw_rate = np.angle(np.exp(1j * np.diff(euler[:, 2]))) / STEP_S

    terrain = sim.terrain
    clearance = float(-p8[0, 2] - terrain.height_m(p8[0, 0], p8[0, 1]))
    return RadioScenario(
        seed=seed,
        t_s=t8[::per_step],
        p_s=p8[::per_step],
        v_ne=v8[::per_step, :2],
        R_s_b=Rotation.from_quat(q8[::per_step]).as_matrix(),
        specific_force_b=force_b,
        euler_rad=euler,
        yaw_rate_rad_s=yaw_rate,
        clearance_m=clearance,
        orbiter=orbiter,
        site_lat_rad=lat0,
        site_lon_east_rad=lon0,
    )
