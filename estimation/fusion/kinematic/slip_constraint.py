"""Balaram's kinematic slip constraint (Balaram 2000, eqs. 17-20), one contact angle per wheel.

For each wheel the forward kinematics from the body to the contact frame ``l_f``
(``rover_kinematics``) gives the twist of the wheel at its contact point relative to the
ground, in the contact frame (eq. 17 with the adjoint of eqs. 18-19); the pure-rolling
``B`` of eq. 20 keeps its three linear components and its spin about the contact normal::

    u   = v + ω × c + J_c γ̇ + Ω_w × (r d)     velocity of the wheel material at the contact
    Ω_w = ω + ω_link + σ̇ z_link - ψ̇ a          angular velocity of the wheel
    t_i = [t·u, a·u, d·u, d·Ω_w]               rolling, lateral, normal slip; turning slip

with ``v = v_c + v_p``, ``ω = ω_c + ω_p`` (body axes), the wheel centre ``c(γ)`` and its
Jacobian ``J_c`` in the joint angles, ``ω_link`` the link's pitch rate about body y from
``γ̇``, ``σ̇`` the steering rate about the link's z, ``ψ̇`` the wheel's drive rate (positive
rolling forwards: ``-ψ̇`` about the axle ``a``), and the contact frame ``(t, a, d)`` at
contact angle ``ξ``. The ``-R^T p×`` of eq. 18 is the ``ω × (r d)`` moment arm here:
``u`` is the velocity at the contact point ``p = c + r d``.

The filter treats ``t_m = t_i + n_i`` as a measurement whose value is the deterministic
slip (sec. 2.3.4): zero for straight driving; on a turn the slip of the commanded motion
on flat ground (``deterministic_slip``): the spin of every wheel about the vertical at the
yaw rate, and the lateral slip of unsteered wheels off the turn axis. The joint angles
and rates come from the encoders and enter as known inputs (sec. 3).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from estimation.fusion.kinematic.process import skew
from estimation.fusion.kinematic.rover_kinematics import (
    Suspension,
    contact_rotation_b,
    suspension,
)
from estimation.geometry import FLIGHT_GEOMETRY, N_WHEELS, FlightGeometry

FloatArray = NDArray[np.float64]
ROWS_PER_WHEEL = 4  # eq. 20: three linear slips and the spin about the normal
_Y = np.array([0.0, 1.0, 0.0])


def _cross(a: FloatArray, b: FloatArray) -> FloatArray:
    """``a × b`` of two 3-vectors (``np.cross`` costs ten times more on single vectors)."""
    return np.array(
        [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
    )


@dataclass(frozen=True)
class JointRates:
    """What the mobility encoders give the filter over one interval (body frame, SI).

    ``gamma_rad`` (3,) rocker and bogie angles, ``gamma_rate_rad_s`` (3,) their rates;
    ``sigma_rad`` (6,) and ``sigma_rate_rad_s`` (6,) steering per wheel (zero on the
    middle wheels); ``psi_rate_rad_s`` (6,) drive rates, positive rolling forwards.
    """

    gamma_rad: FloatArray
    gamma_rate_rad_s: FloatArray
    sigma_rad: FloatArray
    sigma_rate_rad_s: FloatArray
    psi_rate_rad_s: FloatArray

    def __post_init__(self) -> None:
        for name, size in (
            ("gamma_rad", 3),
            ("gamma_rate_rad_s", 3),
            ("sigma_rad", N_WHEELS),
            ("sigma_rate_rad_s", N_WHEELS),
            ("psi_rate_rad_s", N_WHEELS),
        ):
            value = getattr(self, name)
            if value.shape != (size,) or not np.all(np.isfinite(value)):
                raise ValueError(f"{name} must be {size} finite numbers, got {value!r}")


@dataclass(frozen=True)
class SlipJacobians:
    """The slip vector (24,) and its derivatives: in ``v`` (24, 3), ``ω`` (24, 3),
    ``ξ`` (24, 6), and in the encoder inputs ``γ̇`` (24, 3) and ``ψ̇`` (24, 6)."""

    slip: FloatArray
    d_v: FloatArray
    d_omega: FloatArray
    d_xi: FloatArray
    d_gamma_rate: FloatArray
    d_psi_rate: FloatArray


def slip_constraint(
    v_b: FloatArray,
    omega_b: FloatArray,
    xi_rad: FloatArray,
    joints: JointRates,
    geometry: FlightGeometry = FLIGHT_GEOMETRY,
    susp: Suspension | None = None,
) -> SlipJacobians:
    """Eq. 17 for all six wheels, stacked wheel by wheel as ``[t·u, a·u, d·u, d·Ω_w]``."""
    s = suspension(joints.gamma_rad, geometry) if susp is None else susp
    r = geometry.wheel_radius_m
    n = N_WHEELS * ROWS_PER_WHEEL
    out = SlipJacobians(
        np.zeros(n), np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 6)),
        np.zeros((n, 3)), np.zeros((n, 6)),
    )  # fmt: skip
    for i in range(N_WHEELS):
        rows = slice(ROWS_PER_WHEEL * i, ROWS_PER_WHEEL * (i + 1))
        C = contact_rotation_b(s.link_rad[i], joints.sigma_rad[i], xi_rad[i])  # eq. 18's R
        t, a, d = C[:, 0], C[:, 1], C[:, 2]
        c = s.centre_b[i]
        link_z = np.array([np.sin(s.link_rad[i]), 0.0, np.cos(s.link_rad[i])])
        omega_link = (s.dlink_dgamma[i] @ joints.gamma_rate_rad_s) * _Y
        omega_w = omega_b + omega_link + joints.sigma_rate_rad_s[i] * link_z
        omega_w = omega_w - joints.psi_rate_rad_s[i] * a
        u = v_b + _cross(omega_b, c) + s.dcentre_dgamma[i] @ joints.gamma_rate_rad_s
        u = u + r * _cross(omega_w, d)  # eqs. 17-19: velocity at the contact point
        out.slip[rows] = [t @ u, a @ u, d @ u, d @ omega_w]  # eq. 20's B^T
        out.d_v[rows, :] = np.stack([t, a, d, np.zeros(3)])
        p_cross = skew(c + r * d)  # ∂(n·u)/∂ω = (p × n)ᵀ: u = ω × p + ...
        out.d_omega[rows, :] = np.stack([p_cross @ t, p_cross @ a, p_cross @ d, d])
        # ∂/∂ξ: dt/dξ = -d, dd/dξ = t, the axle fixed; ∂u/∂ξ = r Ω_w × t.
        out.d_xi[rows, i] = [-(d @ u), r * (omega_w @ d), t @ u - r * (omega_w @ a), t @ omega_w]
        for j in range(3):
            du = s.dcentre_dgamma[i][:, j] + s.dlink_dgamma[i, j] * r * _cross(_Y, d)
            out.d_gamma_rate[rows, j] = [t @ du, a @ du, d @ du, s.dlink_dgamma[i, j] * d[1]]
        out.d_psi_rate[ROWS_PER_WHEEL * i, i] = -r  # -ψ̇ a × r d = -r ψ̇ t
    return out


def deterministic_slip(
    v_c_b: FloatArray,
    omega_c_b: FloatArray,
    sigma_rad: FloatArray,
    sigma_rate_rad_s: FloatArray,
    geometry: FlightGeometry = FLIGHT_GEOMETRY,
) -> FloatArray:
    """The nominal slip ``t_m`` (24,) of the commanded motion on flat ground (sec. 2.3.4).

    Joint angles and contact angles zero, each wheel rolling at the rate that leaves it no
    rolling slip: what remains is the turning slip about the normal and the lateral slip of
    wheels not steered to the turn centre. Zero for a straight drive.

    >>> t = deterministic_slip(np.zeros(3), np.array([0.0, 0.0, 0.04]), np.zeros(6), np.zeros(6))
    >>> np.round(t[3::4], 12).tolist()  # every wheel spins about the vertical at the yaw rate
    [0.04, 0.04, 0.04, 0.04, 0.04, 0.04]
    """
    zero3, zero6 = np.zeros(3), np.zeros(N_WHEELS)
    joints = JointRates(zero3, zero3, sigma_rad, sigma_rate_rad_s, zero6)
    still = slip_constraint(v_c_b, omega_c_b, zero6, joints, geometry).slip
    rolling = still[0::ROWS_PER_WHEEL] / geometry.wheel_radius_m  # the no-slip drive rates
    joints = JointRates(zero3, zero3, sigma_rad, sigma_rate_rad_s, rolling)
    return slip_constraint(v_c_b, omega_c_b, zero6, joints, geometry).slip
