"""Wheel odometry of SAPP's Mobility mode: body-frame position change per control cycle.

Flight software: Ali et al. 2005, "Attitude and Position Estimation on the Mars Exploration
Rovers" (Ali et al. 2005), section 2.5, eqs. (5)-(7), and the Site-frame update described there.
It sees only the wheel encoders (rotation of each wheel), the steering potentiometers and the
driving software's command (straight, arc about a centre, turn in place).

Wheel order everywhere: LF, LM, LR, RF, RM, RR. The corner wheels LF, LR, RF, RR steer; the
middle wheels do not (their steering angle is 0). Frames (docs/CONVENTIONS.md): body ``b`` is
x forward, y right, z down; Site ``s`` is North-East-Down.

Signs, checked against the geometry:

- Steering ``σ_i`` is 0 for a wheel pointed straight ahead and increases clockwise seen from
  above (Ali et al. 2005 §2.5), i.e. a positive rotation about body +z (down): the wheel rolls
  along ``d_i = (cos σ_i, sin σ_i)`` in the body XY plane. Arc length ``a_i`` = wheel
  rotation × wheel radius, positive rolling forwards along ``d_i``.
- ``ψ`` is a rotation about body +z (down): positive is clockwise seen from above, a right
  turn, heading (azimuth from North) increasing. Eq. (7) is the first-order motion of the
  body origin O rotated by ``ψ`` about the centre C: ``Δp = ψ ẑ × (O - C) = -ψ ẑ × C``
  ``= (ψ C_y, -ψ C_x)``, the paper's eq. (7). So eq. (7) needs ``ψ`` signed in this sense:
  a rover driving forwards about C = (0, +R) (centre on its right) turns right, ``ψ > 0``,
  and gets ``Δx = ψ R > 0``; about C = (0, -R) it turns left, ``ψ < 0``, and again
  ``Δx = ψ C_y > 0``. Eq. (6) writes ``ψ_i = a_i / |r_i|`` without a sign; here each
  wheel's angle carries the sense in which its rolling direction goes round C:
  ``ψ_i = sgn(d_i · t_i) a_i / |r_i|`` with ``r_i`` from C to wheel i and the unit tangent
  ``t_i = ẑ × r_i / |r_i|``. For a wheel steered tangent to its circle, as the driving
  software commands, ``d_i · t_i = ±1`` exactly. A wheel steered off the tangent (a
  middle wheel if ``C_x ≠ 0``; MER's arc centres lie on the middle-wheel axle) still counts
  as in the paper, ``|a_i| / |r_i|``, not corrected for its scrub.
- Eq. (7) is first order in ``ψ`` per step: the exact displacement is
  ``(R sin ψ, R (1 - cos ψ))`` for C = (0, R). At 8 Hz and 3.75 cm/s, ``ψ`` is small.

The heading change of a step is ``ψ_ave`` (arcs, turns in place) or 0 (straight drives):
Mobility's off-nominal submode (Ali et al. 2005 §2.4.2) propagates attitude from it, a rotation
about body z: ``q_s_b ← q_s_b ⊗ q(ψ ẑ)`` (the rotation is expressed in the body frame, so it
multiplies on the right of ``q_s_b``; it is ``δq^B ⊗ ^Bq^{LL}`` in the paper's order with
``δq^B = q(-ψ ẑ)``).

Site update (Ali et al. 2005 §2.5, first paragraph): each control cycle the attitude is propagated
first, then the body-frame change is "converted to Site frame using the freshly propagated
attitude estimate" (the end-of-step attitude) and added: ``Δp_s = R_s_b Δp_b``.

A dragged wheel (``drag_wheel``, the drive command's: a wheel the drive leaves undriven
and drags, as Spirit's right front wheel from sol 125, Cheng, Maimone and Matthies 2005
sec. 4.2) slides more than it rolls, so its encoder says little of the motion: eqs. (5)
and (6)-(7) then average over the five driven wheels (eq. 5's ``1/6`` becomes ``1/5``, and
the dragged wheel is left out of ``ψ_ave`` like a wheel at the centre). Without one the
arithmetic is the six-wheel one, unchanged.

Bad input raises ``ValueError`` naming the parameter.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimation.geometry import (
    FLIGHT_GEOMETRY,
    N_WHEELS,
    STEERED_INDEX,
    FlightGeometry,
    driven_wheels,
)
from estimation.quaternion import quat_from_rotvec, quat_multiply, quat_rotate

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

DEFAULT_CENTRE_TOL_M = 0.01  # our choice: C "at the center of a wheel" if closer than 1 cm


class DriveKind(enum.Enum):
    """What the driving software commanded for this step (it decides, not SAPP)."""

    STRAIGHT = "straight"  # straight or near-straight: eq. (5)
    ARC = "arc"  # arc about a centre C^B: eqs. (6)-(7)
    TURN_IN_PLACE = "turn_in_place"  # an arc about the body origin: eqs. (6)-(7), Δp = 0


@dataclass(frozen=True)
class OdometryStep:
    """Result of one wheel-odometry step.

    ``delta_p_b``: position change of the body origin in the body frame at the start of the
    step (m), shape (3,), ``Δz = 0``. ``delta_heading_rad``: rotation about body +z (down),
    positive clockwise seen from above (``ψ_ave``; 0 for a straight drive). ``psi_rad``:
    each wheel's signed ``ψ_i`` (eq. 6), NaN where excluded or straight, shape (6,).
    ``used``: the wheels in the average, shape (6,).
    """

    kind: DriveKind
    delta_p_b: FloatArray
    delta_heading_rad: float
    psi_rad: FloatArray
    used: BoolArray


def _vector(name: str, value: ArrayLike, shape: tuple[int, ...]) -> FloatArray:
    try:
        out = np.array(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: must be numeric, shape {shape}") from exc
    if out.shape != shape:
        raise ValueError(f"{name}: must have shape {shape}, got {out.shape}")
    if not np.all(np.isfinite(out)):
        raise ValueError(f"{name}: must be finite")
    return out


def steer_six(steer_corner_rad: ArrayLike) -> FloatArray:
    """Steering of all six wheels (rad, (..., 6)) from the four corner ones (LF, LR, RF, RR;
    (..., 4): one cycle or many).

    >>> steer_six([0.1, -0.1, 0.2, -0.2]).tolist()
    [0.1, 0.0, -0.1, 0.2, 0.0, -0.2]
    """
    try:
        corner = np.asarray(steer_corner_rad, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError("steer_corner_rad: must be numeric, shape (..., 4)") from exc
    if corner.shape[-1:] != (4,):
        raise ValueError(f"steer_corner_rad: must have shape (..., 4), got {corner.shape}")
    if not np.all(np.isfinite(corner)):
        raise ValueError("steer_corner_rad: must be finite")
    out = np.zeros((*corner.shape[:-1], N_WHEELS))
    out[..., list(STEERED_INDEX)] = corner
    return out


def arc_lengths_m(
    wheel_rotation_rad: ArrayLike, geometry: FlightGeometry = FLIGHT_GEOMETRY
) -> FloatArray:
    """Arc length each wheel rolled, ``a_i`` = rotation × wheel radius (§2.5), (6,) in m.

    ``wheel_rotation_rad`` (6,) is this step's encoder change, positive rolling forwards.
    """
    rot = _vector("wheel_rotation_rad", wheel_rotation_rad, (N_WHEELS,))
    out: FloatArray = rot * geometry.wheel_radius_m  # a_i, §2.5
    return out


def arc_centre_b(radius_m: float, geometry: FlightGeometry = FLIGHT_GEOMETRY) -> FloatArray:
    """Arc centre ``C^B = (x_middle, R)`` (m, (2,)) of a commanded arc of radius ``radius_m``.

    MER's arcs turn about a point on the middle wheels' axle line; ``radius_m`` is the
    signed radius of the body origin's path: > 0 centre on the right (right turn, ψ > 0),
    < 0 on the left, 0 a turn in place about the body origin. Same sign as
    ``sim.rover.drive.drive_arc``.

    >>> arc_centre_b(3.0).tolist()
    [0.0, 3.0]
    """
    if not math.isfinite(radius_m):
        raise ValueError("radius_m: must be finite")
    return np.array([geometry.x_middle_m, float(radius_m)])


def is_straight(steer_rad: ArrayLike, tol_rad: float = math.radians(1.0)) -> bool:
    """True if all six wheels roll in parallel within ``tol_rad`` (a straight or crab drive).

    A helper for callers without the command (MER uses the driving software's command).
    ``steer_rad`` (6,) in LF..RR order; wheels parallel means every ``σ_i`` within
    ``tol_rad`` of every other one.

    >>> is_straight(steer_six([0.0, 0.0, 0.0, 0.0])), is_straight(steer_six([0.2, -0.2, 0.2, -0.2]))
    (True, False)
    """
    sigma = _vector("steer_rad", steer_rad, (N_WHEELS,))
    if not (math.isfinite(tol_rad) and tol_rad >= 0.0):
        raise ValueError("tol_rad: must be finite and non-negative")
    # Compare directions on the circle so that σ = ±π are parallel.
    d = np.angle(np.exp(1j * (sigma[:, None] - sigma[None, :])))
    return bool(np.max(np.abs(d)) <= tol_rad)


def straight_step(
    arc_m: ArrayLike, steer_rad: ArrayLike, drag_wheel: str | None = None
) -> FloatArray:
    """Eq. (5): body-frame position change (m, (3,)) of a straight or near-straight drive.

    ``arc_m`` (6,) the arc lengths ``a_i``, ``steer_rad`` (6,) the steering angles ``σ_i``;
    ``drag_wheel`` a dragged wheel left out of the average (module docstring).

    >>> straight_step([0.01] * 6, [0.0] * 6).tolist()
    [0.01, 0.0, 0.0]
    >>> straight_step([0.01, 0.01, 0.01, 0.0, 0.01, 0.01], [0.0] * 6, "rf").tolist()
    [0.01, 0.0, 0.0]
    """
    a = _vector("arc_m", arc_m, (N_WHEELS,))
    sigma = _vector("steer_rad", steer_rad, (N_WHEELS,))
    if drag_wheel is not None:
        on = driven_wheels(drag_wheel)
        dx = float(np.sum(a[on] * np.cos(sigma[on]))) / 5.0  # eq. (5), the driven wheels
        dy = float(np.sum(a[on] * np.sin(sigma[on]))) / 5.0  # eq. (5)
        return np.array([dx, dy, 0.0])
    dx = float(np.sum(a * np.cos(sigma))) / 6.0  # eq. (5)
    dy = float(np.sum(a * np.sin(sigma))) / 6.0  # eq. (5)
    return np.array([dx, dy, 0.0])  # eq. (5): Δz = 0


def arc_step(
    arc_m: ArrayLike,
    steer_rad: ArrayLike,
    centre_b: ArrayLike,
    geometry: FlightGeometry = FLIGHT_GEOMETRY,
    centre_tol_m: float = DEFAULT_CENTRE_TOL_M,
    drag_wheel: str | None = None,
) -> tuple[FloatArray, float, FloatArray, BoolArray]:
    """Eqs. (6)-(7): ``(Δp_b (3,), ψ_ave, ψ_i (6,), used (6,))`` for an arc about ``centre_b``.

    ``centre_b`` is ``C^B = (C_x, C_y)`` in the body XY plane (m). Wheels within
    ``centre_tol_m`` of C are excluded (eq. 6 would divide by ~0); their ``ψ_i`` is NaN,
    and so is a dragged wheel's (``drag_wheel``, module docstring).
    See the module docstring for the signs.
    """
    a = _vector("arc_m", arc_m, (N_WHEELS,))
    sigma = _vector("steer_rad", steer_rad, (N_WHEELS,))
    c = _vector("centre_b", centre_b, (2,))
    if not (math.isfinite(centre_tol_m) and centre_tol_m > 0.0):
        raise ValueError("centre_tol_m: must be finite and positive")
    r = geometry.wheel_xy_b() - c  # r_i, from C to wheel i
    r_norm = np.hypot(r[:, 0], r[:, 1])  # |r_i|
    used: BoolArray = r_norm >= centre_tol_m
    if drag_wheel is not None:
        used &= driven_wheels(drag_wheel)
    if not np.any(used):
        raise ValueError("centre_b: every wheel is at the arc centre")
    tangent = np.stack([-r[:, 1], r[:, 0]], axis=1)  # ẑ × r_i (z down, x × y = z)
    d = np.stack([np.cos(sigma), np.sin(sigma)], axis=1)  # rolling direction of wheel i
    safe = np.where(used, r_norm, 1.0)
    sense = np.sign(np.sum(d * tangent, axis=1))  # sgn(d_i · t_i): sense round C
    psi = np.where(used, sense * a / safe, np.nan)  # eq. (6), signed
    psi_ave = float(np.mean(psi[used]))  # ψ_ave over the wheels not at C
    dp_b = np.array([psi_ave * c[1], -psi_ave * c[0], 0.0])  # eq. (7)
    return dp_b, psi_ave, psi, used


def odometry_step(
    kind: DriveKind,
    wheel_rotation_rad: ArrayLike,
    steer_rad: ArrayLike,
    centre_b: ArrayLike | None = None,
    geometry: FlightGeometry = FLIGHT_GEOMETRY,
    centre_tol_m: float = DEFAULT_CENTRE_TOL_M,
    drag_wheel: str | None = None,
) -> OdometryStep:
    """One control cycle of §2.5 for the commanded ``kind`` of drive.

    ``wheel_rotation_rad`` (6,) encoder changes this step (rad, forwards positive),
    ``steer_rad`` (6,) steering (rad; ``steer_six`` expands the four corner angles),
    ``centre_b`` (2,) the arc centre for ``ARC`` (``arc_centre_b`` from the commanded
    radius); ``TURN_IN_PLACE`` uses the body origin, ``STRAIGHT`` ignores it.
    ``drag_wheel``: the command's dragged wheel, left out (module docstring).

    >>> s = odometry_step(DriveKind.STRAIGHT, [0.1] * 6, [0.0] * 6)
    >>> s.delta_p_b.round(6).tolist(), s.delta_heading_rad
    ([0.013, 0.0, 0.0], 0.0)
    """
    if not isinstance(kind, DriveKind):
        raise ValueError(f"kind: must be a DriveKind, got {kind!r}")
    a = arc_lengths_m(wheel_rotation_rad, geometry)
    used_wheels = driven_wheels(drag_wheel)  # checks drag_wheel
    if kind is DriveKind.STRAIGHT:
        dp_b = straight_step(a, steer_rad, drag_wheel)
        none = np.full(N_WHEELS, np.nan)
        return OdometryStep(kind, dp_b, 0.0, none, used_wheels)
    if kind is DriveKind.TURN_IN_PLACE:
        c = np.zeros(2)
    elif centre_b is None:
        raise ValueError("centre_b: required for an ARC step")
    else:
        c = _vector("centre_b", centre_b, (2,))
    dp_b, psi_ave, psi, used = arc_step(a, steer_rad, c, geometry, centre_tol_m, drag_wheel)
    return OdometryStep(kind, dp_b, psi_ave, psi, used)


def _quat(name: str, q: ArrayLike) -> FloatArray:
    out = _vector(name, q, (4,))
    norm = float(np.linalg.norm(out))
    if abs(norm - 1.0) > 1e-6:
        raise ValueError(f"{name}: must be a unit quaternion, norm {norm:g}")
    return out / norm


def propagate_heading(q_s_b: ArrayLike, delta_heading_rad: float) -> FloatArray:
    """Attitude after turning ``delta_heading_rad`` about body +z (wheel-odometry submode).

    ``q_s_b ⊗ q(ψ ẑ)``: the turn is expressed in the body frame (module docstring).
    ``q_s_b`` is ``[x, y, z, w]``; returns the new ``q_s_b`` (4,).
    """
    q = _quat("q_s_b", q_s_b)
    if not math.isfinite(delta_heading_rad):
        raise ValueError("delta_heading_rad: must be finite")
    return quat_multiply(q, quat_from_rotvec([0.0, 0.0, float(delta_heading_rad)]))


def propagate_position(p_s: ArrayLike, q_s_b: ArrayLike, delta_p_b: ArrayLike) -> FloatArray:
    """Site position after the step: ``p_s + R_s_b Δp_b`` (m, (3,)), Ali et al. 2005 §2.5.

    ``q_s_b`` must be the freshly propagated (end-of-step) attitude, as SAPP does.

    >>> propagate_position([0, 0, 0], [0, 0, np.sin(np.pi / 4), np.cos(np.pi / 4)],
    ...                    [1.0, 0, 0]).round(12).tolist()
    [0.0, 1.0, 0.0]
    """
    p = _vector("p_s", p_s, (3,))
    dp_b = _vector("delta_p_b", delta_p_b, (3,))
    out: FloatArray = p + quat_rotate(_quat("q_s_b", q_s_b), dp_b)  # Δp_s = R_s_b Δp_b, §2.5
    return out


def odometry_deltas(
    kind: DriveKind,
    wheel_rotation_rad: FloatArray,
    steer_rad: FloatArray,
    centre_b: FloatArray | None = None,
    geometry: FlightGeometry = FLIGHT_GEOMETRY,
    centre_tol_m: float = DEFAULT_CENTRE_TOL_M,
    drag_wheel: str | None = None,
) -> tuple[FloatArray, FloatArray]:
    """``odometry_step`` over ``N`` cycles at once: ``(Δp_b (N, 3), ψ_ave (N,))`` from the
    encoder changes ``wheel_rotation_rad`` and steering ``steer_rad`` (N, 6) each, finite
    (the caller has checked them). The same eqs. (5)-(7), row by row, over the driven
    wheels (``drag_wheel``: the command's dragged wheel, left out)."""
    a = wheel_rotation_rad * geometry.wheel_radius_m  # a_i, §2.5
    n = len(a)
    dp_b = np.zeros((n, 3))
    on = driven_wheels(drag_wheel)
    if kind is DriveKind.STRAIGHT and drag_wheel is not None:
        dp_b[:, 0] = np.sum((a * np.cos(steer_rad))[:, on], axis=1) / 5.0  # eq. (5), driven
        dp_b[:, 1] = np.sum((a * np.sin(steer_rad))[:, on], axis=1) / 5.0  # eq. (5)
        return dp_b, np.zeros(n)
    if kind is DriveKind.STRAIGHT:
        dp_b[:, 0] = np.sum(a * np.cos(steer_rad), axis=1) / 6.0  # eq. (5)
        dp_b[:, 1] = np.sum(a * np.sin(steer_rad), axis=1) / 6.0  # eq. (5)
        return dp_b, np.zeros(n)
    if kind is DriveKind.TURN_IN_PLACE:
        c = np.zeros(2)
    elif centre_b is None:
        raise ValueError("centre_b: required for an ARC step")
    else:
        c = np.asarray(centre_b, dtype=np.float64)
    r = geometry.wheel_xy_b() - c  # r_i, from C to wheel i (the same every cycle)
    r_norm = np.hypot(r[:, 0], r[:, 1])
    used = (r_norm >= centre_tol_m) & on
    if not np.any(used):
        raise ValueError("centre_b: every wheel is at the arc centre")
    # sgn(d_i · t_i) with d_i = (cos σ_i, sin σ_i) and t_i = ẑ × r_i = (-r_y, r_x)
    sense = np.sign(np.cos(steer_rad) * -r[:, 1] + np.sin(steer_rad) * r[:, 0])
    psi = (sense * a)[:, used] / r_norm[used]  # eq. (6), signed
    psi_ave = np.mean(psi, axis=1)
    dp_b[:, 0] = psi_ave * c[1]  # eq. (7)
    dp_b[:, 1] = -psi_ave * c[0]
    return dp_b, psi_ave
