"""Argument checks and small vector helpers shared by the flight-software modules.

Flight software cannot import the simulator's ``InputError``; a bad argument raises
``ValueError`` whose message starts with the parameter's name.
"""

from __future__ import annotations

import math
import numbers

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]


def unit_quaternion(q: ArrayLike, name: str = "q_b_ll") -> FloatArray:
    """A finite ``[x, y, z, w]`` of norm 1 (to 1e-6), renormalised; ``ValueError`` otherwise."""
    a = np.asarray(q, dtype=np.float64)
    if a.shape != (4,) or not np.all(np.isfinite(a)):
        raise ValueError(f"{name}: must be a finite (4,) quaternion, got shape {a.shape}")
    norm = float(np.linalg.norm(a))
    if abs(norm - 1.0) > 1e-6:
        raise ValueError(f"{name}: must be a unit quaternion, norm {norm}")
    out: FloatArray = a / norm
    return out


def unit_vector(v: ArrayLike, name: str) -> FloatArray:
    """A finite non-zero 3-vector, normalised; ``ValueError`` naming ``name`` otherwise."""
    a = np.asarray(v, dtype=np.float64)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise ValueError(f"{name}: must be a finite (3,) vector, got shape {a.shape}")
    norm = float(np.linalg.norm(a))
    if norm == 0.0:
        raise ValueError(f"{name}: must be non-zero")
    out: FloatArray = a / norm
    return out


def angle_between_rad(u: FloatArray, v: FloatArray) -> float:
    """Angle between two vectors, accurate at 0 and pi: ``atan2(|u x v|, u . v)``.

    >>> round(angle_between_rad(np.array([1.0, 0, 0]), np.array([0, 2.0, 0])), 12)
    1.570796326795
    """
    return math.atan2(float(np.linalg.norm(np.cross(u, v))), float(np.dot(u, v)))


def is_real_number(value: object) -> bool:
    """A real number that is not a bool (``True`` is not 1 deg)."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def finite_vector(value: ArrayLike, name: str, n: int) -> FloatArray:
    """``value`` as a finite float array of shape ``(n,)``; ``ValueError`` naming ``name``."""
    try:
        out = np.array(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: must be numeric with shape ({n},)") from exc
    if out.shape != (n,) or not np.all(np.isfinite(out)):
        raise ValueError(f"{name}: must be finite with shape ({n},), got {out.shape}")
    return out


def finite_array(value: ArrayLike, name: str, shape: tuple[int, ...]) -> FloatArray:
    """``value`` as a finite float64 array of ``shape`` (not copied when it already is
    one); ``ValueError`` naming ``name`` otherwise."""
    a = np.asarray(value, dtype=np.float64)
    if a.shape != shape or not np.all(np.isfinite(a)):
        raise ValueError(f"{name}: must be finite with shape {shape}, got shape {a.shape}")
    return a
