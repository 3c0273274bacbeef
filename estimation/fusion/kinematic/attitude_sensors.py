"""Gyro and wide-angle sun sensor measurements of the kinematic EKF (Balaram 2000, eqs. 12-16).

Both are functions of the filter state ``X`` (``kinematic_process``) and the reference
attitude ``q0 = q_s_b`` with the small-angle error on the right (eq. 5):
``R(q) = R(q0)(I + θ×)`` to first order, so ``R(q)ᵀ v = R0ᵀ v + (R0ᵀ v)× θ``.

Gyro (eqs. 12-13): ``ω_m = B_g (ω + R(q)ᵀ Ω_s) + b + n_g`` with ``ω = ω_c + ω_p``. The gyro
senses the inertial rate; the Site frame turns with Mars at ``Ω_s`` (Site axes), which
the flight software knows from its latitude (pass zero to ignore it, as Rocky-7 could).
``B_g = [0 0 1]`` for the heading gyro, ``I`` for a 3-axis unit.

Sun sensor (eqs. 15-16), a Wide Angle Sun Sensor (WASS, 160 deg field of view) whose
fish-eye optics give ``s_m = (2/π) asin(ρ)/ρ [s_x, s_y]``, ``ρ = |[s_x, s_y]|``, where
``s_wass = R_WASS_B R(q)ᵀ s_v`` is the unit sun vector in the sensor frame. The paper
takes the sensor frame to be the rover frame; our body z points down, so the sensor looks
up out of the deck: ``R_WASS_B`` turns the body 180 deg about x (``x_wass = x_b``,
``y_wass = -y_b``, boresight ``z_wass = -z_b``). ``|s_m|`` is the angle off the boresight
over 90 deg, so the elevation is ``π/2 (1 - |s_m|)`` as the paper says.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimation.fusion.kinematic.process import Layout, cross3, skew

FloatArray = NDArray[np.float64]

R_WASS_B = np.diag([1.0, -1.0, -1.0])  # sensor from body: boresight up (see docstring)
WASS_HALF_FOV_RAD = float(np.deg2rad(80.0))  # 160 deg field of view (Balaram 2000 sec. 1.3)
HEADING_GYRO = np.array([[0.0, 0.0, 1.0]])  # B_g of eq. 13
THREE_AXIS_GYRO = np.eye(3)  # B_g = I (eq. 12, full 3-axis gyro)


def gyro_measurement(
    X: FloatArray,
    R0: FloatArray,
    omega_c_b: FloatArray,
    B_g: FloatArray,
    omega_frame_s: FloatArray,
) -> tuple[FloatArray, FloatArray]:
    """``(h(X), H)`` of eq. 12; ``h`` (m,) rad/s in body axes, ``H`` (m, n)."""
    L = Layout(X.shape[0] - 18)
    m = B_g.shape[0]
    if L.n_bias not in (0, m):
        raise ValueError(f"a {m}-axis gyro needs 0 or {m} bias states, the state has {L.n_bias}")
    frame_b0 = R0.T @ omega_frame_s
    frame_b = frame_b0 + cross3(frame_b0, X[L.THETA])
    h = B_g @ (omega_c_b + X[L.OMEGA_P] + frame_b)  # eq. 12
    H = np.zeros((m, L.n))
    H[:, L.THETA] = B_g @ skew(frame_b0)
    H[:, L.OMEGA_P] = B_g
    if L.n_bias:
        h = h + X[L.bias]  # eq. 12: + b
        H[:, L.bias] = np.eye(m)
    return h, H


def _fisheye_gain(rho: float) -> tuple[float, float]:
    """``g(ρ) = (2/π) asin(ρ)/ρ`` of eq. 15 and ``g'(ρ)/ρ`` (series near zero)."""
    if rho < 1e-4:
        return (2.0 / np.pi) * (1.0 + rho**2 / 6.0), (2.0 / np.pi) * (1.0 / 3.0 + 0.3 * rho**2)
    asin = float(np.arcsin(min(rho, 1.0)))
    root = float(np.sqrt(max(1.0 - rho**2, 1e-300)))
    g = (2.0 / np.pi) * asin / rho
    dg_over_rho = (2.0 / np.pi) * (1.0 / (rho**2 * root) - asin / rho**3)
    return g, dg_over_rho


def sun_sensor_model(sun_wass: ArrayLike) -> FloatArray:
    """Eq. 15 without noise: the WASS output (2,) of a unit sun vector in the sensor frame.

    >>> sun_sensor_model([0.0, 0.0, 1.0]).tolist()  # on the boresight
    [0.0, 0.0]
    >>> round(float(np.linalg.norm(sun_sensor_model([1.0, 0.0, 0.0]))), 12)  # horizon
    1.0
    """
    s = np.asarray(sun_wass, dtype=float)
    g, _ = _fisheye_gain(float(np.hypot(s[0], s[1])))
    out: FloatArray = g * s[:2]
    return out


def sun_measurement(
    X: FloatArray, R0: FloatArray, sun_s: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """``(h(X), H)`` of eqs. 15-16 for the Sun along the unit ``sun_s`` (Site frame)."""
    L = Layout(X.shape[0] - 18)
    sun_b0 = R0.T @ sun_s
    sun_b = sun_b0 + cross3(sun_b0, X[L.THETA])  # eq. 16: R(q)ᵀ s_v
    s = R_WASS_B @ sun_b
    rho = float(np.hypot(s[0], s[1]))
    g, dg_over_rho = _fisheye_gain(rho)
    h = g * s[:2]  # eq. 15
    dh_ds = g * np.eye(2) + dg_over_rho * np.outer(s[:2], s[:2])
    H = np.zeros((2, L.n))
    H[:, L.THETA] = dh_ds @ (R_WASS_B @ skew(sun_b0))[:2]
    return h, H


def sun_vector_from_measurement(s_m: ArrayLike) -> FloatArray:
    """The inverse of eq. 15: the unit sun vector in the *body* frame (3,) from ``s_m``.

    The angle off the boresight is ``(π/2)|s_m|`` and the azimuth that of ``s_m``
    (the paper's ``atan(s_m(2), -s_m(1))`` measures it from the sensor's -x).

    >>> np.round(sun_vector_from_measurement([0.0, 0.0]), 12).tolist()  # straight up
    [0.0, 0.0, -1.0]
    """
    m = np.asarray(s_m, dtype=float)
    if m.shape != (2,) or not np.all(np.isfinite(m)):
        raise ValueError(f"s_m must be 2 finite numbers, got {s_m!r}")
    size = float(np.hypot(m[0], m[1]))
    if size > 1.0:
        raise ValueError(f"|s_m| = {size:.3f} is beyond the horizon (must be <= 1)")
    off = 0.5 * np.pi * size
    lateral = m / size * np.sin(off) if size > 0.0 else np.zeros(2)
    out: FloatArray = R_WASS_B.T @ np.array([lateral[0], lateral[1], np.cos(off)])
    return out
