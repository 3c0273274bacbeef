"""Gyro attitude propagation of SAPP's Articulate and Mobility modes (Ali et al. 2005, sec. 2.4).

The gyros measure the body's rotation relative to inertial space: the rover's rotation
relative to the Local-Level frame plus the rotation of Mars, which carries the LL frame.
SAPP "converts the Mars rotation vector to Rover Body Frame using the current attitude
estimate and then subtracts it from the rotation the gyros measured" (sec. 2.4.1); what is
left, the rotation relative to the surface, propagates the estimate at 8 Hz::

    Δθ_rel^B = Δθ^B - R_b_ll(q̂) ω_mars^LL Δt                      (sec. 2.4.1)
    ^Bq_+^{LL} = δq^B(-Δθ_rel^B) ⊗ ^Bq_-^{LL}                        (as eq. 1's form)

The correction is expressed in the body frame, so it multiplies on the left (docs/CONVENTIONS.md,
and eq. 1 of Ali et al. 2005); its sign is negative because a body that turns by ``φ`` relative to
LL sees the LL frame turn by ``-φ``: ``R_b_ll+ = R(φ)ᵀ R_b_ll``. ``ω_mars^LL`` comes from
the onboard IVP (``estimation.ivp.mars_rotation_ll``). At rest the subtraction cancels the
gyro reading exactly when the estimate is right; an attitude error ``δ`` leaves a residual
rate of about ``|ω| δ``: 0.26 deg/h per degree of error (Mars turns 14.6 deg/h), which is
why a wrong estimate drifts even on perfect gyros.

Subtracting Mars' rotation as a vector, as the paper does, is first order: each step misses
the commutator of the two rotations, so a turn by ``ψ`` gains ``½ ω_perp Δt ψ`` of error
(6.7 µrad for 90° at 8 Hz, with ``ω_perp`` Mars' rate across the turn axis): negligible
beside the gyro drift, and kept for fidelity to the flight code.

The propagation never improves the Attitude Quality Flag; counting the gyro time and the
Fine-to-Coarse downgrade after 15 minutes belong to the NATE state machine.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimation.quaternion import Quat, Vec3, q_multiply, q_normalised, q_rotate

FloatArray = NDArray[np.float64]


def propagate_gyro(
    q_b_ll: ArrayLike,
    delta_angle_b: ArrayLike,
    dt_s: ArrayLike,
    omega_mars_ll: ArrayLike,
) -> FloatArray:
    """Propagate ``q_b_ll`` (4,) through ``N`` gyro samples; returns (N + 1, 4).

    ``delta_angle_b`` (N, 3): the IMU's delta angles (rad, body axes at each interval's
    start); ``dt_s`` (N,) or scalar: the intervals (s); ``omega_mars_ll`` (3,): Mars'
    rotation in LL (rad/s) from IVP. Row 0 of the result is the input estimate.
    """
    q0 = np.asarray(q_b_ll, dtype=float)
    d_theta = np.asarray(delta_angle_b, dtype=float)
    omega = np.asarray(omega_mars_ll, dtype=float)
    if q0.shape != (4,) or not np.all(np.isfinite(q0)) or np.linalg.norm(q0) < 1e-9:
        raise ValueError(f"q_b_ll: must be a finite non-zero [x, y, z, w], got {q0!r}")
    if d_theta.ndim != 2 or d_theta.shape[1] != 3 or not np.all(np.isfinite(d_theta)):
        raise ValueError(f"delta_angle_b: must be finite with shape (N, 3), got {d_theta.shape}")
    n = d_theta.shape[0]
    dt = np.broadcast_to(np.asarray(dt_s, dtype=float), (n,))
    if not (np.all(np.isfinite(dt)) and np.all(dt > 0.0)):
        raise ValueError("dt_s: must be positive and finite")
    if omega.shape != (3,) or not np.all(np.isfinite(omega)):
        raise ValueError(f"omega_mars_ll: must be a finite 3-vector, got {omega!r}")

    out = np.empty((n + 1, 4))
    q = q_normalised((float(q0[0]), float(q0[1]), float(q0[2]), float(q0[3])))
    out[0] = q
    mars_ll = (float(omega[0]), float(omega[1]), float(omega[2]))
    for k, (d_x, d_y, d_z) in enumerate(d_theta.tolist()):
        q = gyro_cycle(q, (d_x, d_y, d_z), float(dt[k]), mars_ll)
        out[k + 1] = q
    return out


def gyro_cycle(q_b_ll: Quat, delta_angle_b: Vec3, dt_s: float, omega_mars_ll: Vec3) -> Quat:
    """One control cycle of ``propagate_gyro`` on plain floats, unchecked (the caller
    checks its inputs once): the unit ``q_b_ll`` after the delta angles ``delta_angle_b``
    over ``dt_s``."""
    # Mars' rotation over the interval, into the body with the current estimate (2.4.1)
    o_x, o_y, o_z = omega_mars_ll
    m_x, m_y, m_z = q_rotate(q_b_ll, (o_x * dt_s, o_y * dt_s, o_z * dt_s))
    d_x, d_y, d_z = delta_angle_b
    phi_x, phi_y, phi_z = d_x - m_x, d_y - m_y, d_z - m_z  # relative to the surface, body axes
    angle = math.sqrt(phi_x * phi_x + phi_y * phi_y + phi_z * phi_z)
    # δq^B = q(-φ): exact for any angle (eq. 1's left-multiplied body correction)
    s = -math.sin(0.5 * angle) / angle if angle > 1e-12 else -0.5
    dq_b = (s * phi_x, s * phi_y, s * phi_z, math.cos(0.5 * angle))
    return q_normalised(q_multiply(dq_b, q_b_ll))  # keep it a unit quaternion
