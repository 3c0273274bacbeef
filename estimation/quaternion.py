"""Quaternion algebra in the project's convention (docs/CONVENTIONS.md, "Rotations and
quaternions").

Quaternions are numpy arrays ``[x, y, z, w]`` (scalar last), multiplied with the Hamilton
product, exactly as ``scipy.spatial.transform.Rotation`` stores them, so
``Rotation.from_quat(q_a_b).apply(v_b) == v_a``. With this convention chains read left to
right like matrices: ``q_a_c = quat_multiply(q_a_b, q_b_c)`` matches ``R_a_c = R_a_b @ R_b_c``.
Ali et al. 2005 writes ``δq^B ⊗ ^Bq^{LL}`` for a correction expressed in the body frame (on the
left) and ``^Bq^{LL} ⊗ δq^{LL}`` for one expressed in LL (on the right); both keep that order here.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]


def quat_multiply(q1: ArrayLike, q2: ArrayLike) -> FloatArray:
    """Hamilton product ``q1 ⊗ q2`` of ``[x, y, z, w]`` quaternions; broadcasts over (..., 4).

    >>> quat_multiply([0, 0, 0, 1], [0.0, 0.0, 1.0, 0.0]).tolist()
    [0.0, 0.0, 1.0, 0.0]
    """
    a = np.asarray(q1, dtype=float)
    b = np.asarray(q2, dtype=float)
    x1, y1, z1, w1 = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    x2, y2, z2, w2 = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    out: FloatArray = np.stack(
        [
            w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
            w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
        ],
        axis=-1,
    )
    return out


def quat_conjugate(q: ArrayLike) -> FloatArray:
    """The inverse rotation of a unit quaternion: ``q_b_a`` from ``q_a_b``."""
    out = np.array(q, dtype=float, copy=True)
    out[..., :3] *= -1.0
    return out


def quat_canonical(q: ArrayLike) -> FloatArray:
    """The same rotation with a non-negative scalar part (``q`` and ``-q`` are one rotation)."""
    a = np.asarray(q, dtype=float)
    sign = np.where(a[..., 3:4] < 0.0, -1.0, 1.0)
    out: FloatArray = a * sign
    return out


def quat_from_rotvec(theta: ArrayLike) -> FloatArray:
    """Unit quaternion of the rotation vector ``theta`` (rad, (..., 3)), exact for any size.

    A small-angle error state ``theta`` (Balaram 2000, eqs. 5-7) maps through this to
    ``δq``; which side ``δq`` multiplies is the caller's to state.
    """
    t = np.asarray(theta, dtype=float)
    angle = np.linalg.norm(t, axis=-1, keepdims=True)
    half = 0.5 * angle
    # sin(half)/angle -> 1/2 as angle -> 0; the series keeps it exact near zero.
    small = angle < 1e-8
    safe = np.where(small, 1.0, angle)
    k = np.where(small, 0.5 - angle**2 / 48.0, np.sin(half) / safe)
    out: FloatArray = np.concatenate([t * k, np.cos(half)], axis=-1)
    return out


def quat_rotate(q: ArrayLike, v: ArrayLike) -> FloatArray:
    """``R(q) v`` for unit ``q`` (..., 4) and ``v`` (..., 3), broadcasting: what
    ``Rotation.from_quat(q).apply(v)`` gives, without building a ``Rotation``. With ``t = 2
    q_v × v``: ``v' = v + w t + q_v × t``."""
    a = np.asarray(q, dtype=float)
    b = np.asarray(v, dtype=float)
    x, y, z, w = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    vx, vy, vz = b[..., 0], b[..., 1], b[..., 2]
    tx = 2.0 * (y * vz - z * vy)
    ty = 2.0 * (z * vx - x * vz)
    tz = 2.0 * (x * vy - y * vx)
    out: FloatArray = np.stack(
        [
            vx + w * tx + (y * tz - z * ty),
            vy + w * ty + (z * tx - x * tz),
            vz + w * tz + (x * ty - y * tx),
        ],
        axis=-1,
    )
    return out


def quat_angle_between(q1: ArrayLike, q2: ArrayLike) -> FloatArray:
    """The angle (rad, ``[0, π]``) of the rotation from ``q2`` to ``q1`` (non-zero, (..., 4),
    normalised here as scipy does): ``(Rotation.from_quat(q1) * Rotation.from_quat(q2).inv())
    .magnitude()``."""
    a = np.asarray(q1, dtype=float)
    b = np.asarray(q2, dtype=float)
    a = a / np.linalg.norm(a, axis=-1, keepdims=True)
    b = b / np.linalg.norm(b, axis=-1, keepdims=True)
    d = quat_multiply(a, quat_conjugate(b))
    out: FloatArray = 2.0 * np.arctan2(np.linalg.norm(d[..., :3], axis=-1), np.abs(d[..., 3]))
    return out


# ---- on plain floats: one control cycle's math without array dispatch ------------------------
# ``Quat`` is ``(x, y, z, w)`` and ``Vec3`` ``(x, y, z)``, Python floats. These are the
# per-cycle forms of the functions above (the same formulas), for the 8 Hz paths where
# building arrays would cost more than the arithmetic; their arguments are checked by the
# caller, once, at its boundary.

Quat = tuple[float, float, float, float]
Vec3 = tuple[float, float, float]


def q_multiply(a: Quat, b: Quat) -> Quat:
    """``a ⊗ b`` (``quat_multiply``)."""
    x1, y1, z1, w1 = a
    x2, y2, z2, w2 = b
    return (
        w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
        w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
        w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
        w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
    )


def q_rotate(q: Quat, v: Vec3) -> Vec3:
    """``R(q) v`` (``quat_rotate``)."""
    x, y, z, w = q
    vx, vy, vz = v
    tx = 2.0 * (y * vz - z * vy)
    ty = 2.0 * (z * vx - x * vz)
    tz = 2.0 * (x * vy - y * vx)
    return (
        vx + w * tx + (y * tz - z * ty),
        vy + w * ty + (z * tx - x * tz),
        vz + w * tz + (x * ty - y * tx),
    )


def q_normalised(q: Quat) -> Quat:
    """``q / |q|``."""
    x, y, z, w = q
    norm = math.sqrt(x * x + y * y + z * z + w * w)
    return (x / norm, y / norm, z / norm, w / norm)


def q_canonical(q: Quat) -> Quat:
    """The same rotation with a non-negative scalar part (``quat_canonical``)."""
    return (-q[0], -q[1], -q[2], -q[3]) if q[3] < 0.0 else q


def q_from_rotvec(theta: Vec3) -> Quat:
    """Unit quaternion of the rotation vector ``theta`` (``quat_from_rotvec``)."""
    tx, ty, tz = theta
    angle = math.sqrt(tx * tx + ty * ty + tz * tz)
    k = 0.5 - angle * angle / 48.0 if angle < 1e-8 else math.sin(0.5 * angle) / angle
    return (tx * k, ty * k, tz * k, math.cos(0.5 * angle))
