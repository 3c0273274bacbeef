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

import numpy as np
from numpy.typing import NDArray

from estimation.fusion.kinematic.rover_kinematics import Suspension, suspension
from estimation.geometry import FLIGHT_GEOMETRY, N_WHEELS, FlightGeometry

FloatArray = NDArray[np.float64]
ROWS_PER_WHEEL = 4  # eq. 20: three linear slips and the spin about the normal
_ROWS = np.arange(N_WHEELS * ROWS_PER_WHEEL)
_WHEEL_OF_ROW = _ROWS // ROWS_PER_WHEEL


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
    r = geometry.wheel_radius_m
    rows = _wheels(
        v_b.tolist(), omega_b.tolist(), xi_rad.tolist(), joints.sigma_rad.tolist(),
        joints.gamma_rate_rad_s.tolist(), joints.sigma_rate_rad_s.tolist(),
        joints.psi_rate_rad_s.tolist(), s, r, True,
    )  # fmt: skip
    n = N_WHEELS * ROWS_PER_WHEEL
    slip, d_v, d_omega, d_xi_of_wheel, d_gamma_rate = rows
    d_xi = np.zeros((n, N_WHEELS))
    d_xi[_ROWS, _WHEEL_OF_ROW] = d_xi_of_wheel
    return SlipJacobians(
        np.array(slip), np.array(d_v), np.array(d_omega), d_xi, np.array(d_gamma_rate),
        slip_constraint_d_psi_rate(r),
    )  # fmt: skip


def _wheels(
    v: list[float],
    w: list[float],
    xi: list[float],
    sigma: list[float],
    gamma_rate: list[float],
    sigma_rate: list[float],
    psi_rate: list[float],
    s: Suspension,
    r: float,
    jacobians: bool,
) -> tuple[list[float], list[list[float]], list[list[float]], list[float], list[list[float]]]:
    """``slip_constraint``'s wheels written out on plain floats: a filter step would
    otherwise spend its time on array operations over 3-vectors. Returns the slip (24,)
    and, with ``jacobians``, the rows of ``d_v``, ``d_omega``, ``d_gamma_rate`` (24 of 3
    each) and ``∂t/∂ξ`` of each row's own wheel (24,); empty lists without."""
    g0, g1, g2 = gamma_rate
    slip: list[float] = []
    d_v: list[list[float]] = []
    d_omega: list[list[float]] = []
    d_xi: list[float] = []
    d_gamma_rate: list[list[float]] = []
    centre, dcentre, dlink = s.centre_b.tolist(), s.dcentre_dgamma.tolist(), s.dlink_dgamma.tolist()
    for i, link in enumerate(s.link_rad.tolist()):
        # R_b_c = Ry(link) Rz(σ) Ry(ξ) (eq. 18's R, rover_kinematics.contact_rotation_b):
        # the columns of Ry(link) Rz(σ) are (wx, a, wz), wz the link's z axis; then Ry(ξ)
        # turns wx and wz about the axle a into the rolling direction t and the normal d.
        cl, sl = math.cos(link), math.sin(link)
        cs, ss = math.cos(sigma[i]), math.sin(sigma[i])
        cx, sx = math.cos(xi[i]), math.sin(xi[i])
        wx0, wx1, wx2 = cl * cs, ss, -sl * cs
        a0, a1, a2 = -cl * ss, cs, sl * ss
        t0, t1, t2 = cx * wx0 - sx * sl, cx * wx1, cx * wx2 - sx * cl
        d0, d1, d2 = sx * wx0 + cx * sl, sx * wx1, sx * wx2 + cx * cl
        # Ω_w = ω + ω_link + σ̇ z_link - ψ̇ a
        l0, l1, l2 = dlink[i]
        omega_link = l0 * g0 + l1 * g1 + l2 * g2
        ow0 = w[0] + sigma_rate[i] * sl - psi_rate[i] * a0
        ow1 = w[1] + omega_link - psi_rate[i] * a1
        ow2 = w[2] + sigma_rate[i] * cl - psi_rate[i] * a2
        # u = v + ω × c + J_c γ̇ + Ω_w × (r d): the velocity at the contact point
        c0, c1, c2 = centre[i]
        (j00, j01, j02), (j10, j11, j12), (j20, j21, j22) = dcentre[i]
        u0 = v[0] + (w[1] * c2 - w[2] * c1) + (j00 * g0 + j01 * g1 + j02 * g2)
        u1 = v[1] + (w[2] * c0 - w[0] * c2) + (j10 * g0 + j11 * g1 + j12 * g2)
        u2 = v[2] + (w[0] * c1 - w[1] * c0) + (j20 * g0 + j21 * g1 + j22 * g2)
        u0 += r * (ow1 * d2 - ow2 * d1)
        u1 += r * (ow2 * d0 - ow0 * d2)
        u2 += r * (ow0 * d1 - ow1 * d0)
        t_u = t0 * u0 + t1 * u1 + t2 * u2
        d_u = d0 * u0 + d1 * u1 + d2 * u2
        slip += [t_u, a0 * u0 + a1 * u1 + a2 * u2, d_u, d0 * ow0 + d1 * ow1 + d2 * ow2]
        if not jacobians:
            continue
        p0, p1, p2 = c0 + r * d0, c1 + r * d1, c2 + r * d2
        # ∂u/∂γ̇_j = ∂c/∂γ_j + ∂link/∂γ_j r ŷ × d, with ŷ × d = (d_z, 0, -d_x)
        e00, e01, e02 = j00 + l0 * r * d2, j10, j20 - l0 * r * d0
        e10, e11, e12 = j01 + l1 * r * d2, j11, j21 - l1 * r * d0
        e20, e21, e22 = j02 + l2 * r * d2, j12, j22 - l2 * r * d0
        d_v += [[t0, t1, t2], [a0, a1, a2], [d0, d1, d2], [0.0, 0.0, 0.0]]
        d_omega += [  # ∂(n·u)/∂ω = (p × n)ᵀ for n = t, a, d: u = ω × p + ...
            [p1 * t2 - p2 * t1, p2 * t0 - p0 * t2, p0 * t1 - p1 * t0],
            [p1 * a2 - p2 * a1, p2 * a0 - p0 * a2, p0 * a1 - p1 * a0],
            [p1 * d2 - p2 * d1, p2 * d0 - p0 * d2, p0 * d1 - p1 * d0],
            [d0, d1, d2],
        ]
        d_gamma_rate += [
            [t0 * e00 + t1 * e01 + t2 * e02, t0 * e10 + t1 * e11 + t2 * e12,
             t0 * e20 + t1 * e21 + t2 * e22],
            [a0 * e00 + a1 * e01 + a2 * e02, a0 * e10 + a1 * e11 + a2 * e12,
             a0 * e20 + a1 * e21 + a2 * e22],
            [d0 * e00 + d1 * e01 + d2 * e02, d0 * e10 + d1 * e11 + d2 * e12,
             d0 * e20 + d1 * e21 + d2 * e22],
            [l0 * d1, l1 * d1, l2 * d1],
        ]  # fmt: skip
        # ∂/∂ξ: dt/dξ = -d, dd/dξ = t, the axle fixed; ∂u/∂ξ = r Ω_w × t.
        d_xi += [
            -d_u,
            r * (ow0 * d0 + ow1 * d1 + ow2 * d2),
            t_u - r * (ow0 * a0 + ow1 * a1 + ow2 * a2),
            t0 * ow0 + t1 * ow1 + t2 * ow2,
        ]
    return slip, d_v, d_omega, d_xi, d_gamma_rate


@functools.lru_cache(maxsize=4)
def slip_constraint_d_psi_rate(r: float) -> FloatArray:
    """``∂t/∂ψ̇`` (24, 6) of wheels of radius ``r``: ``-ψ̇ a × r d = -r ψ̇ t`` in each wheel's
    rolling row, whatever the wheel's pose (read-only; ``SlipJacobians.d_psi_rate``)."""
    out = np.zeros((N_WHEELS * ROWS_PER_WHEEL, N_WHEELS))
    out[_ROWS[::ROWS_PER_WHEEL], np.arange(N_WHEELS)] = -r
    out.setflags(write=False)
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
    s = _level_suspension(geometry)
    r = geometry.wheel_radius_m
    v, w = v_c_b.tolist(), omega_c_b.tolist()
    sigma, sigma_rate = sigma_rad.tolist(), sigma_rate_rad_s.tolist()
    zero3, zero6 = [0.0] * 3, [0.0] * N_WHEELS
    slip = np.array(_wheels(v, w, zero6, sigma, zero3, sigma_rate, zero6, s, r, False)[0])
    # Rolling at ψ̇ = t·u / r takes the rolling slip to zero; ψ̇ moves u along t only
    # (``-ψ̇ a × r d = -r ψ̇ t``) and Ω_w along the axle, so the other rows keep their values.
    slip[0::ROWS_PER_WHEEL] = 0.0
    return slip


@functools.lru_cache(maxsize=4)
def _level_suspension(geometry: FlightGeometry) -> Suspension:
    """The suspension at ``γ = 0`` (``deterministic_slip``'s flat ground), computed once."""
    return suspension(np.zeros(3), geometry)
