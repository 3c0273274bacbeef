"""How well the HGA really points: the onboard command against the truth.

What only a simulator can show (docs/DESIGN.md): the angle between where the flight software
pointed the HGA (``estimation.sapp.hga_pointing``, from its estimate and IVP) and where Earth
really is in the body frame (the truth attitude and the DE421 Earth direction), and the
margin left against MER's 2° (3σ) pointing requirement (Ali et al. 2005, sec. 1).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from estimation.quaternion import quat_rotate
from estimation.sapp.hga_pointing import (
    HGA_POINTING_REQUIREMENT_DEG,
    HgaCommand,
    hga_boresight_b,
    hga_boresights_b,
)

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class HgaPointing:
    """``error_deg``: true pointing error; ``margin_deg``: 2° minus it (negative: lost)."""

    error_deg: float
    margin_deg: float


def hga_pointing_truth(
    command: HgaCommand, q_b_ll_true: ArrayLike, earth_ll_true: ArrayLike
) -> HgaPointing:
    """True pointing error of ``command`` for the true attitude and Earth direction (LL)."""
    earth_b = Rotation.from_quat(np.asarray(q_b_ll_true, dtype=float)).apply(
        np.asarray(earth_ll_true, dtype=float)
    )
    earth_b /= np.linalg.norm(earth_b)
    # Score the gimbal angles themselves, through the forward model, not the intent.
    boresight_b = hga_boresight_b(command.az_rad, command.el_rad)
    cos_angle = float(np.clip(boresight_b @ earth_b, -1.0, 1.0))
    error_deg = math.degrees(math.acos(cos_angle))
    return HgaPointing(error_deg=error_deg, margin_deg=HGA_POINTING_REQUIREMENT_DEG - error_deg)


def hga_errors_deg(
    az_rad: FloatArray, el_rad: FloatArray, q_b_ll_true: FloatArray, earth_ll_true: FloatArray
) -> FloatArray:
    """``hga_pointing_truth``'s error for ``K`` gimbal commands ``(az_rad, el_rad)`` (K,)
    at once, against the true attitudes (K, 4) and Earth directions (K, 3), deg."""
    q = q_b_ll_true / np.linalg.norm(q_b_ll_true, axis=1, keepdims=True)
    earth_b = quat_rotate(q, earth_ll_true)
    earth_b /= np.linalg.norm(earth_b, axis=1, keepdims=True)
    boresight_b = hga_boresights_b(az_rad, el_rad)  # the gimbal angles' forward model
    cos_angle = np.clip(np.sum(boresight_b * earth_b, axis=1), -1.0, 1.0)
    out: FloatArray = np.degrees(np.arccos(cos_angle))
    return out
