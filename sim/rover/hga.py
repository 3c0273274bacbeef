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
from numpy.typing import ArrayLike
from scipy.spatial.transform import Rotation

from estimation.sapp.hga_pointing import HGA_POINTING_REQUIREMENT_DEG, HgaCommand, hga_boresight_b


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
