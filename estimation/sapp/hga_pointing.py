"""Pointing the High Gain Antenna at Earth from the onboard attitude (Ali et al. 2005, sec. 1).

MER must point the HGA at Earth to within 2° (3σ); after the other error sources that
leaves 1.5° (3σ) for the attitude estimate (Ali et al. 2005, sec. 1). Onboard, the Earth
direction comes from IVP in Local-Level and is taken into the body frame with the SAPP
estimate, ``earth_b = R_b_ll(q̂) earth_ll``; the HGA's two-axis gimbal then turns to it.

The gimbal uses the same azimuth/elevation convention as the Pancam mast
(``estimation.camera_model``): azimuth clockwise about body Down from body +x, elevation
up from the deck (the body x-y plane). Its elevation travel is a documented assumption
(approximate): from the deck (0°) to straight up (90°); Earth below the deck plane of a
tilted rover is out of reach, and Earth below the horizon cannot be talked to at all.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from estimation.camera_model import mast_az_el_for

FloatArray = NDArray[np.float64]

HGA_POINTING_REQUIREMENT_DEG = 2.0  # Ali et al. 2005 sec. 1: Earth within 2 deg, 3 sigma
HGA_ELEVATION_MIN_RAD = 0.0  # approximate: the dish clears the deck from 0 deg ...
HGA_ELEVATION_MAX_RAD = math.pi / 2  # ... to straight up


@dataclass(frozen=True)
class HgaCommand:
    """Where the flight software points the HGA.

    ``az_rad``, ``el_rad``: gimbal angles, clipped to the travel; ``boresight_b``: the unit
    vector they point along in the body frame (``hga_boresight_b``);
    ``earth_above_horizon``: Earth's elevation in LL is positive (from IVP);
    ``within_gimbal``: the gimbal can reach the boresight.
    """

    boresight_b: FloatArray
    az_rad: float
    el_rad: float
    earth_above_horizon: bool
    within_gimbal: bool


def point_hga(q_b_ll_est: ArrayLike, earth_ll: ArrayLike) -> HgaCommand:
    """Gimbal command towards ``earth_ll`` (unit vector from IVP, LL) with the estimate.

    ``q_b_ll_est`` ``[x, y, z, w]``: SAPP's attitude estimate.
    """
    q = np.asarray(q_b_ll_est, dtype=float)
    e_ll = np.asarray(earth_ll, dtype=float)
    if q.shape != (4,) or not np.all(np.isfinite(q)) or np.linalg.norm(q) < 1e-9:
        raise ValueError(f"q_b_ll_est: must be a finite non-zero [x, y, z, w], got {q!r}")
    if e_ll.shape != (3,) or not np.all(np.isfinite(e_ll)) or np.linalg.norm(e_ll) < 1e-9:
        raise ValueError(f"earth_ll: must be a finite non-zero 3-vector, got {e_ll!r}")
    e_ll = e_ll / np.linalg.norm(e_ll)
    earth_b = Rotation.from_quat(q).apply(e_ll)  # R_b_ll(q̂) earth_ll
    az, el_wanted = mast_az_el_for(earth_b)
    # The gimbal stops at its travel: the dish then points as close as it can.
    el = min(max(el_wanted, HGA_ELEVATION_MIN_RAD), HGA_ELEVATION_MAX_RAD)
    return HgaCommand(
        boresight_b=hga_boresight_b(az, el),
        az_rad=az,
        el_rad=el,
        earth_above_horizon=bool(e_ll[2] < 0.0),  # LL z is Down
        within_gimbal=el == el_wanted,
    )


def hga_boresight_b(az_rad: float, el_rad: float) -> FloatArray:
    """The gimbal's forward model: boresight in the body frame for angles ``(az, el)``.

    ``(cos el cos az, cos el sin az, -sin el)``: the Pancam mast's convention.
    """
    return np.array(
        [
            math.cos(el_rad) * math.cos(az_rad),
            math.cos(el_rad) * math.sin(az_rad),
            -math.sin(el_rad),
        ]
    )
