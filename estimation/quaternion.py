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
