"""The flight software's own rocker-bogie geometry and the kinematics its filter needs.

Balaram 2000 builds its slip constraints (eqs. 17-20) on the forward kinematics of
the suspension: wheel centres and axles as functions of the internal angles ``γ`` and the
steering angles ``λ``, and the contact frame ``l_f`` at contact angle ``ξ`` on each wheel's
equator (sec. 2.2.4). The dimensions are the flight software's one copy,
``estimation.geometry.FlightGeometry``.

Frames (docs/CONVENTIONS.md): body ``b`` x forward, y right, z down. A wheel frame ``w`` is
``R_b_w = Ry(link) Rz(σ)``: ``link`` the pitch of the link that carries the wheel (rocker,
or rocker + bogie), ``σ`` the steering angle (positive turns the front to the right; zero
on the middle wheels). In ``w`` the axle is +y, forward +x, down +z. The contact frame is
``R_b_c = R_b_w Ry(ξ)``: its z axis ``d`` points from the centre to the contact point
``c + r d``, its x axis ``t`` is the rolling direction and its y axis the axle, so
``ξ > 0`` puts the contact ahead of the wheel's bottom (a wheel climbing).

Joint angles ``γ = (rocker, bogie_left, bogie_right)``: right-handed about body +y, the
right rocker the negative of the left (the differential), bogies relative to their
rockers. Wheel order LF, LM, LR, RF, RM, RR; steered wheels LF, LR, RF, RR.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimation.geometry import FLIGHT_GEOMETRY, N_WHEELS, STEERED_INDEX, FlightGeometry

FloatArray = NDArray[np.float64]

_SIDES = ((1.0, (0, 1, 2)), (-1.0, (3, 4, 5)))  # (rocker sign, wheel indices) left, right


def _ry(angle: float) -> FloatArray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _rz(angle: float) -> FloatArray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


@dataclass(frozen=True)
class Suspension:
    """Wheel centres and link pitches at one set of joint angles (body frame).

    ``centre_b`` (6, 3) m; ``dcentre_dgamma`` (6, 3, 3), the last axis over ``γ``;
    ``link_rad`` (6,); ``dlink_dgamma`` (6, 3).
    """

    centre_b: FloatArray
    dcentre_dgamma: FloatArray
    link_rad: FloatArray
    dlink_dgamma: FloatArray


def suspension(gamma_rad: ArrayLike, geometry: FlightGeometry = FLIGHT_GEOMETRY) -> Suspension:
    """Forward kinematics of the rocker-bogie at ``γ = (rocker, bogie_l, bogie_r)`` (rad).

    >>> s = suspension([0.0, 0.0, 0.0])
    >>> np.round(s.centre_b[0], 12).tolist(), np.round(s.centre_b[5], 12).tolist()
    ([0.7, -0.6, 0.17], [-0.7, 0.6, 0.17])
    """
    gamma = np.asarray(gamma_rad, dtype=float)
    if gamma.shape != (3,) or not np.isfinite(gamma).all():
        raise ValueError(f"gamma_rad must be 3 finite angles, got {gamma_rad!r}")
    g = geometry
    px, pz = g.rocker_pivot_x_m, g.rocker_pivot_z_m
    zc = g.wheel_centre_z_m
    centre = np.zeros((N_WHEELS, 3))
    dcentre = np.zeros((N_WHEELS, 3, 3))
    link = np.zeros(N_WHEELS)
    dlink = np.zeros((N_WHEELS, 3))
    # On plain floats (a filter step calls this once): Ry(α) turns (x, 0, z) in the x-z
    # plane into (c x + s z, 0, -s x + c z); its derivative at the turned vector is ŷ × v.
    for side, (sign, (i_f, i_m, i_r)) in enumerate(_SIDES):
        rho = sign * float(gamma[0])
        beta = float(gamma[1 + side])
        cr, sr = math.cos(rho), math.sin(rho)
        cb, sb = math.cos(rho + beta), math.sin(rho + beta)
        bx, bz = g.bogie_pivot_x_m - px, g.bogie_pivot_z_m - pz
        bogie = (px + (cr * bx + sr * bz), pz + (-sr * bx + cr * bz))
        fx, fz = g.x_front_m - px, zc - pz
        wheels = [(i_f, px + (cr * fx + sr * fz), pz + (-sr * fx + cr * fz))]
        for i, x in ((i_m, g.x_middle_m), (i_r, g.x_rear_m)):
            wx, wz = x - g.bogie_pivot_x_m, zc - g.bogie_pivot_z_m
            wheels.append((i, bogie[0] + (cb * wx + sb * wz), bogie[1] + (-sb * wx + cb * wz)))
        y = (-0.5 if side == 0 else 0.5) * g.track_m
        for i, x, z in wheels:
            centre[i] = (x, y, z)
            # The whole side turns about the rocker pivot with the rocker (times the
            # differential's sign); the bogie wheels also turn about the bogie pivot.
            dcentre[i, :, 0] = (sign * (z - pz), 0.0, sign * -(x - px))
            link[i] = rho
            dlink[i, 0] = sign
            if i != i_f:
                dcentre[i, :, 1 + side] = (z - bogie[1], 0.0, -(x - bogie[0]))
                link[i] = rho + beta
                dlink[i, 1 + side] = 1.0
    return Suspension(centre, dcentre, link, dlink)


def steer_per_wheel(steer_rad: ArrayLike) -> FloatArray:
    """The four corner steering angles (LF, LR, RF, RR) spread over the six wheels: (4,) to
    (6,), or a series (N, 4) to (N, 6).

    >>> steer_per_wheel([0.1, 0.2, 0.3, 0.4]).tolist()
    [0.1, 0.0, 0.2, 0.3, 0.0, 0.4]
    """
    steer = np.asarray(steer_rad, dtype=float)
    if steer.ndim not in (1, 2) or steer.shape[-1] != 4 or not np.isfinite(steer).all():
        raise ValueError(f"steer_rad must be 4 finite angles (or N rows of 4), got {steer_rad!r}")
    out = np.zeros((*steer.shape[:-1], N_WHEELS))
    out[..., list(STEERED_INDEX)] = steer
    return out


def wheel_rotation_b(link_rad: float, sigma_rad: float) -> FloatArray:
    """``R_b_w = Ry(link) Rz(σ)`` of one wheel frame (3, 3)."""
    out: FloatArray = _ry(link_rad) @ _rz(sigma_rad)
    return out


def contact_rotation_b(link_rad: float, sigma_rad: float, xi_rad: float) -> FloatArray:
    """``R_b_c = Ry(link) Rz(σ) Ry(ξ)`` of one wheel's contact frame (3, 3) (eq. 17's l_f)."""
    out: FloatArray = wheel_rotation_b(link_rad, sigma_rad) @ _ry(xi_rad)
    return out
