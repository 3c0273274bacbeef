"""Mobility mode over a whole drive segment: NATE's 8 Hz cycles of a drive at once.

Ali et al. 2005, sec. 2.4.2 and 2.5: each Mobility cycle propagates the attitude with the
gyros (``estimation.sapp.gyro_propagation``, sec. 2.4.1's Mars-rotation subtraction), or in
the off-nominal submode from the wheels' heading change, then adds the wheel-odometry step
(eqs. 5-7, ``estimation.sapp.wheel_odometry``, over the driven wheels: a drive command that
drags a wheel leaves it out) turned into the Site frame with the freshly
propagated attitude, ``Δp_s = R_s_b Δp_b``. The gyro counter grows by each cycle's ``dt``
and a Fine flag drops to Coarse once it passes ``fine_to_coarse_s`` (sec. 2.4).

This is what ``Nate.step`` does cycle by cycle in Mobility, computed in the order that
depends on the order, and in arrays for the rest: the odometry steps do not depend on the
attitude, so all of them are computed first, in arrays; the attitude is a recursion, run
on plain floats (no array or object per cycle); the Site positions are then the running
sum of the rotated steps. The inputs are checked once, by ``ImuSeries`` and
``EncoderSeries``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from estimation.quaternion import (
    Quat,
    Vec3,
    q_canonical,
    q_from_rotvec,
    q_multiply,
    q_normalised,
    quat_rotate,
)
from estimation.sapp.gyro_propagation import gyro_cycle
from estimation.sapp.nate_io import DriveCommand, EncoderSeries, ImuSeries
from estimation.sapp.wheel_odometry import DriveKind, arc_centre_b, odometry_deltas

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class MobilityTrack:
    """A segment's Mobility cycles: after cycle ``k``, the estimate ``q_b_ll[k]`` and
    ``p_s[k]``, and the IMU integration time ``imu_integration_s[k]``; ``last_wheel_rad``
    the encoder reference for the next cycle."""

    q_b_ll: FloatArray
    p_s: FloatArray
    imu_integration_s: FloatArray
    last_wheel_rad: FloatArray | None


def mobility_cycles(
    q_b_ll: FloatArray,
    p_s: FloatArray,
    imu_integration_s: float,
    last_wheel_rad: FloatArray | None,
    imu: ImuSeries,
    encoders: EncoderSeries | None,
    drive: DriveCommand,
    use_gyros: bool,
    omega_mars_ll: FloatArray,
) -> MobilityTrack:
    """Mobility through ``imu`` (and ``encoders``, the same cycles) from the estimate
    ``q_b_ll``, ``p_s`` (module docstring). Without ``encoders`` there is no odometry;
    with no ``last_wheel_rad`` the first reading is the reference only."""
    n = len(imu)
    has_step = np.zeros(n, dtype=bool)
    dp_b = np.zeros((n, 3))
    heading = np.zeros(n)
    if encoders is not None:
        wheel = encoders.wheel_angle_rad
        before = np.empty_like(wheel)
        before[1:] = wheel[:-1]
        before[0] = wheel[0] if last_wheel_rad is None else last_wheel_rad
        has_step[:] = True
        has_step[0] = last_wheel_rad is not None
        centre = arc_centre_b(drive.radius_m) if drive.kind is DriveKind.ARC else None
        dp_b, heading = odometry_deltas(
            drive.kind, wheel - before, encoders.steer_rad, centre, drag_wheel=drive.drag_wheel
        )
        last_wheel_rad = wheel[-1].copy()

    # the attitude, cycle by cycle: the gyros (sec. 2.4.1) or the wheels' heading (2.4.2)
    gyros = imu.valid if use_gyros else np.zeros(n, dtype=bool)
    wheels = has_step & (not use_gyros)
    omega = (float(omega_mars_ll[0]), float(omega_mars_ll[1]), float(omega_mars_ll[2]))
    q: Quat = (float(q_b_ll[0]), float(q_b_ll[1]), float(q_b_ll[2]), float(q_b_ll[3]))
    q_out = np.empty((n, 4))
    rows = zip(
        imu.delta_angle_b.tolist(),
        imu.dt_s.tolist(),
        gyros.tolist(),
        wheels.tolist(),
        heading.tolist(),
        strict=True,
    )
    for k, (d_theta_b, dt_s, gyro, wheel_turn, psi) in enumerate(rows):
        if gyro:
            q = q_canonical(gyro_cycle(q_normalised(q), tuple(d_theta_b), dt_s, omega))
        if wheel_turn:  # q_s_b ⊗ q(ψ ẑ) with q_s_b = conj(q_b_ll): wheel_odometry.propagate_heading
            x, y, z, w = q_normalised(q)
            x, y, z, w = q_multiply((-x, -y, -z, w), q_from_rotvec((0.0, 0.0, psi)))
            q = q_canonical((-x, -y, -z, w))
        q_out[k] = q

    # the positions: Δp_s = R_s_b Δp_b with the fresh attitude, R_s_b = R(conj(q_b_ll))
    q_s_b = q_out * np.array([-1.0, -1.0, -1.0, 1.0])
    q_s_b /= np.linalg.norm(q_s_b, axis=1, keepdims=True)
    dp_s = np.where(has_step[:, None], quat_rotate(q_s_b, dp_b), 0.0)
    p_out = np.cumsum(np.vstack([p_s[None, :], dp_s]), axis=0)[1:]  # added in order
    imu_s = imu_integration_s + np.cumsum(np.where(gyros, imu.dt_s, 0.0))
    return MobilityTrack(q_out, p_out, imu_s, last_wheel_rad)


def tilt_of_estimates_deg(q_b_ll: FloatArray) -> FloatArray:
    """``nadir.tilt_of_estimate_rad`` of each row of ``q_b_ll`` (N, 4), in degrees."""
    q = q_b_ll / np.linalg.norm(q_b_ll, axis=1, keepdims=True)
    s = np.minimum(1.0, np.sqrt(q[:, 0] * q[:, 0] + q[:, 1] * q[:, 1]))
    out: FloatArray = np.degrees(2.0 * np.arcsin(s))
    return out


def tilts_from_accelerometers_deg(imu: ImuSeries) -> FloatArray:
    """``nadir.tilt_from_specific_force_rad`` of each cycle's reading, in degrees; NaN
    where the reading is unusable (invalid, not finite or zero), as ``Nate.step`` says."""
    f_b = imu.delta_velocity_b / imu.dt_s[:, None]
    norm = np.linalg.norm(f_b, axis=1)
    usable = imu.valid & np.isfinite(norm) & (norm > 0.0)
    u = f_b[usable] / norm[usable, None]
    out = np.full(len(imu), math.nan)
    out[usable] = np.degrees(np.arctan2(np.hypot(u[:, 0], u[:, 1]), -u[:, 2]))
    return out


def cycle_tilts_deg(
    q_b_ll: Quat, delta_velocity_b: Vec3, dt_s: float, valid: bool
) -> tuple[float, float]:
    """The two tilts of one cycle on plain floats, ``(tilt_est_deg, tilt_accel_deg)``: those
    of ``tilt_of_estimates_deg`` and ``tilts_from_accelerometers_deg``, for ``Nate.step``."""
    x, y, _, _ = q_normalised(q_b_ll)
    tilt_est_deg = math.degrees(2.0 * math.asin(min(1.0, math.sqrt(x * x + y * y))))
    f_x, f_y, f_z = delta_velocity_b
    norm = math.sqrt(f_x * f_x + f_y * f_y + f_z * f_z)
    if not (valid and math.isfinite(norm) and norm > 0.0):
        return tilt_est_deg, math.nan
    u_x, u_y, u_z = f_x / norm, f_y / norm, f_z / norm  # dt cancels from the direction
    return tilt_est_deg, math.degrees(math.atan2(math.hypot(u_x, u_y), -u_z))
