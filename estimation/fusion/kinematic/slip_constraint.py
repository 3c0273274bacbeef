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

import functools
import math
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import NDArray

from estimation.fusion.kinematic.rover_kinematics import Suspension, suspension
from estimation.geometry import FLIGHT_GEOMETRY, N_WHEELS, FlightGeometry

FloatArray = NDArray[np.float64]
ROWS_PER_WHEEL = 4  # eq. 20: three linear slips and the spin about the normal


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
            if value.shape != (size,) or not np.isfinite(value).all():
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
    n = N_WHEELS * ROWS_PER_WHEEL
    out = SlipJacobians(
        np.zeros(n), np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 6)),
        np.zeros((n, 3)), np.zeros((n, 6)),
    )  # fmt: skip
    _wheels(
        v_b, omega_b, xi_rad, joints.sigma_rad, joints.gamma_rate_rad_s,
        joints.sigma_rate_rad_s, joints.psi_rate_rad_s, s.centre_b, s.dcentre_dgamma,
        s.link_rad, s.dlink_dgamma, geometry.wheel_radius_m, True,
        out.slip, out.d_v, out.d_omega, out.d_xi, out.d_gamma_rate, out.d_psi_rate,
    )  # fmt: skip
    return out


@numba.njit(cache=True, nogil=True)
def _wheels(
    v: FloatArray,
    w: FloatArray,
    xi: FloatArray,
    sigma: FloatArray,
    gamma_rate: FloatArray,
    sigma_rate: FloatArray,
    psi_rate: FloatArray,
    centre: FloatArray,
    dcentre: FloatArray,
    link: FloatArray,
    dlink: FloatArray,
    r: float,
    jacobians: bool,
    slip: FloatArray,
    d_v: FloatArray,
    d_omega: FloatArray,
    d_xi: FloatArray,
    d_gamma_rate: FloatArray,
    d_psi_rate: FloatArray,
) -> None:  # pragma: no cover - compiled (its tests call it through slip_constraint)
    """``slip_constraint``'s wheels written out on scalars, compiled (numba): a filter step
    would otherwise spend its time on array operations over 3-vectors. Fills ``slip`` and,
    with ``jacobians``, the derivatives (the arrays of ``SlipJacobians``, zeros on entry)."""
    for i in range(6):
        # R_b_c = Ry(link) Rz(σ) Ry(ξ) (eq. 18's R, rover_kinematics.contact_rotation_b):
        # the columns of Ry(link) Rz(σ) are (wx, a, wz), wz the link's z axis; then Ry(ξ)
        # turns wx and wz about the axle a into the rolling direction t and the normal d.
        cl, sl = math.cos(link[i]), math.sin(link[i])
        cs, ss = math.cos(sigma[i]), math.sin(sigma[i])
        cx, sx = math.cos(xi[i]), math.sin(xi[i])
        wx0, wx1, wx2 = cl * cs, ss, -sl * cs
        a0, a1, a2 = -cl * ss, cs, sl * ss
        t0, t1, t2 = cx * wx0 - sx * sl, cx * wx1, cx * wx2 - sx * cl
        d0, d1, d2 = sx * wx0 + cx * sl, sx * wx1, sx * wx2 + cx * cl
        # Ω_w = ω + ω_link + σ̇ z_link - ψ̇ a
        omega_link = dlink[i, 0] * gamma_rate[0] + dlink[i, 1] * gamma_rate[1]
        omega_link += dlink[i, 2] * gamma_rate[2]
        ow0 = w[0] + sigma_rate[i] * sl - psi_rate[i] * a0
        ow1 = w[1] + omega_link - psi_rate[i] * a1
        ow2 = w[2] + sigma_rate[i] * cl - psi_rate[i] * a2
        # u = v + ω × c + J_c γ̇ + Ω_w × (r d): the velocity at the contact point
        c0, c1, c2 = centre[i, 0], centre[i, 1], centre[i, 2]
        j0, j1, j2 = 0.0, 0.0, 0.0
        for k in range(3):
            j0 += dcentre[i, 0, k] * gamma_rate[k]
            j1 += dcentre[i, 1, k] * gamma_rate[k]
            j2 += dcentre[i, 2, k] * gamma_rate[k]
        u0 = v[0] + (w[1] * c2 - w[2] * c1) + j0 + r * (ow1 * d2 - ow2 * d1)
        u1 = v[1] + (w[2] * c0 - w[0] * c2) + j1 + r * (ow2 * d0 - ow0 * d2)
        u2 = v[2] + (w[0] * c1 - w[1] * c0) + j2 + r * (ow0 * d1 - ow1 * d0)
        row = 4 * i
        t_u = t0 * u0 + t1 * u1 + t2 * u2
        d_u = d0 * u0 + d1 * u1 + d2 * u2
        slip[row] = t_u  # eq. 20's B^T
        slip[row + 1] = a0 * u0 + a1 * u1 + a2 * u2
        slip[row + 2] = d_u
        slip[row + 3] = d0 * ow0 + d1 * ow1 + d2 * ow2
        if not jacobians:
            continue
        axes = ((t0, t1, t2), (a0, a1, a2), (d0, d1, d2))
        p0, p1, p2 = c0 + r * d0, c1 + r * d1, c2 + r * d2
        for m in range(3):
            n0, n1, n2 = axes[m]
            d_v[row + m, 0], d_v[row + m, 1], d_v[row + m, 2] = n0, n1, n2
            # ∂(n·u)/∂ω = (p × n)ᵀ: u = ω × p + ...
            d_omega[row + m, 0] = p1 * n2 - p2 * n1
            d_omega[row + m, 1] = p2 * n0 - p0 * n2
            d_omega[row + m, 2] = p0 * n1 - p1 * n0
            for j in range(3):
                # ∂u/∂γ̇_j = ∂c/∂γ_j + ∂link/∂γ_j r ŷ × d, with ŷ × d = (d_z, 0, -d_x)
                arm = dlink[i, j] * r
                du0 = dcentre[i, 0, j] + arm * d2
                du1 = dcentre[i, 1, j]
                du2 = dcentre[i, 2, j] - arm * d0
                d_gamma_rate[row + m, j] = n0 * du0 + n1 * du1 + n2 * du2
        d_omega[row + 3, 0], d_omega[row + 3, 1], d_omega[row + 3, 2] = d0, d1, d2
        for j in range(3):
            d_gamma_rate[row + 3, j] = dlink[i, j] * d1
        # ∂/∂ξ: dt/dξ = -d, dd/dξ = t, the axle fixed; ∂u/∂ξ = r Ω_w × t.
        d_xi[row, i] = -d_u
        d_xi[row + 1, i] = r * (ow0 * d0 + ow1 * d1 + ow2 * d2)
        d_xi[row + 2, i] = t_u - r * (ow0 * a0 + ow1 * a1 + ow2 * a2)
        d_xi[row + 3, i] = t0 * ow0 + t1 * ow1 + t2 * ow2
        d_psi_rate[row, i] = -r  # -ψ̇ a × r d = -r ψ̇ t


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
    s = _level_suspension(geometry)
    r = geometry.wheel_radius_m
    zero3, zero6, none = np.zeros(3), np.zeros(N_WHEELS), np.zeros((0, 0))
    slip = np.zeros(N_WHEELS * ROWS_PER_WHEEL)
    args = (s.centre_b, s.dcentre_dgamma, s.link_rad, s.dlink_dgamma, r, False, slip)
    _wheels(v_c_b, omega_c_b, zero6, sigma_rad, zero3, sigma_rate_rad_s, zero6, *args,
            none, none, none, none, none)  # fmt: skip
    rolling = slip[0::ROWS_PER_WHEEL] / r  # the no-slip drive rates
    _wheels(v_c_b, omega_c_b, zero6, sigma_rad, zero3, sigma_rate_rad_s, rolling, *args,
            none, none, none, none, none)  # fmt: skip
    return slip


@functools.lru_cache(maxsize=4)
def _level_suspension(geometry: FlightGeometry) -> Suspension:
    """The suspension at ``γ = 0`` (``deterministic_slip``'s flat ground), computed once."""
    return suspension(np.zeros(3), geometry)
