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

The margin the rover predicts (``PointingKnowledge``), from its own attitude knowledge.

NATE carries no attitude covariance; what the flight software knows of its own attitude
is the Attitude Quality Flag (Ali et al. 2005 sec. 2.1), the 3σ of the last Sungaze's QUEST
solution (sec. 2.2.3: it converges to the 1.5° 3σ level) and the IMU integration time
since that Fine attitude (sec. 4). From those, with no truth:

- Fine, or Coarse reached by propagation from Fine (sec. 2.4: the estimate is the same,
  only the flag dropped): 3σ = the Sungaze's 3σ (1.5°, Fine's budget, if the Fine came from
  elsewhere) + ``DRIFT_3SIGMA_DEG_PER_S`` × the IMU time since.
- Coarse from a Sunfind or gyrocompassing: ``COARSE_3SIGMA_DEG`` (8°: a Coarse attitude
  must put the sun in Pancam's field, ``estimation.sapp.nate``).
- TiltOnly or Unknown: the heading is unknown, 180°.

The drift rate is MER's operational experience (sec. 4): after a Sungaze at the 1.5° level
the HGA link stayed solid for about 10,000 s of IMU integration, so the 0.5° left of the
2° requirement (sec. 1) lasts 10,000 s: 0.5° / 10,000 s. The LN-200's specification
(3°/h, sec. 2.4.2) is far above what MER saw. The predicted margin is
``HGA_POINTING_REQUIREMENT_DEG`` minus the 3σ.

>>> k = PointingKnowledge()
>>> k.update(AttitudeQuality.FINE, 0.0, sungaze_3sigma_deg=1.5)
0.5
>>> round(k.update(AttitudeQuality.COARSE, 10_000.0), 6)
0.0
>>> k.update(AttitudeQuality.TILT_ONLY, 10_000.0)
-178.0
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from estimation.camera_model import mast_az_el_for
from estimation.quaternion import quat_rotate
from estimation.sapp.aqf import AttitudeQuality
from estimation.sapp.nate_io import NateParams

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


def point_hga_many(
    q_b_ll_est: FloatArray, earth_ll: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``point_hga`` for ``K`` estimates at once, ``(az_rad (K,), el_rad (K,), boresight_b
    (K, 3))``, from finite non-zero ``q_b_ll_est`` (K, 4) and ``earth_ll`` (K, 3) (checked
    by the caller, once)."""
    q = q_b_ll_est / np.linalg.norm(q_b_ll_est, axis=1, keepdims=True)
    e_ll = earth_ll / np.linalg.norm(earth_ll, axis=1, keepdims=True)
    earth_b = quat_rotate(q, e_ll)  # R_b_ll(q̂) earth_ll
    earth_b /= np.linalg.norm(earth_b, axis=1, keepdims=True)
    horizontal = np.hypot(earth_b[:, 0], earth_b[:, 1])
    el_wanted = np.arctan2(-earth_b[:, 2], horizontal)  # camera_model.mast_az_el_for
    az = np.where(horizontal > 1e-15, np.arctan2(earth_b[:, 1], earth_b[:, 0]), 0.0)
    el = np.clip(el_wanted, HGA_ELEVATION_MIN_RAD, HGA_ELEVATION_MAX_RAD)  # the travel
    return az, el, hga_boresights_b(az, el)


def hga_boresights_b(az_rad: FloatArray, el_rad: FloatArray) -> FloatArray:
    """``hga_boresight_b`` of each ``(az, el)`` pair, (K, 3)."""
    out: FloatArray = np.stack(
        [np.cos(el_rad) * np.cos(az_rad), np.cos(el_rad) * np.sin(az_rad), -np.sin(el_rad)],
        axis=-1,
    )
    return out


# ---- the margin the rover predicts ----------------------------------------------------------

FINE_3SIGMA_DEG = 1.5  # Ali et al. 2005 sec. 1: the attitude's share of the 2 deg, 3 sigma
DRIFT_3SIGMA_DEG_PER_S = 0.5 / 10_000.0  # sec. 4, see the module docstring
# NATE's gyrocompass_coarse_3sigma_rad (Pancam's half field), the 3σ a Coarse flag stands for
COARSE_3SIGMA_DEG = math.degrees(NateParams().gyrocompass_coarse_3sigma_rad)
UNKNOWN_HEADING_3SIGMA_DEG = 180.0


class PointingKnowledge:
    """Follows the flag and the Sungazes, frame by frame (module docstring)."""

    def __init__(self) -> None:
        self._base_deg = UNKNOWN_HEADING_3SIGMA_DEG
        self._base_imu_s = 0.0
        self._propagated = False  # the estimate is a Fine one, propagated since
        self._aqf = AttitudeQuality.UNKNOWN

    def state(self) -> dict[str, Any]:
        """The knowledge as plain data (``estimation.state``)."""
        return {
            "base_deg": self._base_deg,
            "base_imu_s": self._base_imu_s,
            "propagated": self._propagated,
            "aqf": self._aqf.name,
        }

    def load_state(self, state: Mapping[str, Any]) -> None:
        """Load ``state()``'s output onto a fresh ``PointingKnowledge``."""
        self._base_deg = float(state["base_deg"])
        self._base_imu_s = float(state["base_imu_s"])
        self._propagated = bool(state["propagated"])
        self._aqf = AttitudeQuality[state["aqf"]]

    def update(
        self,
        aqf: AttitudeQuality,
        imu_integration_s: float,
        sungaze_3sigma_deg: float | None = None,
    ) -> float:
        """The predicted margin, deg, after a cycle that ended with ``aqf`` and
        ``imu_integration_s``; ``sungaze_3sigma_deg`` the 3σ of a Sungaze that succeeded in
        this cycle, if one did."""
        if sungaze_3sigma_deg is not None and math.isfinite(sungaze_3sigma_deg):
            self._base_deg, self._base_imu_s = sungaze_3sigma_deg, imu_integration_s
            self._propagated = True
        elif aqf != self._aqf:
            if aqf is AttitudeQuality.FINE:  # a Fine attitude from elsewhere (ground)
                self._base_deg, self._base_imu_s = FINE_3SIGMA_DEG, imu_integration_s
                self._propagated = True
            elif not (aqf is AttitudeQuality.COARSE and self._aqf is AttitudeQuality.FINE):
                self._propagated = False  # a new Coarse, or the heading lost
        self._aqf = aqf
        return HGA_POINTING_REQUIREMENT_DEG - self.three_sigma_deg(imu_integration_s)

    def three_sigma_deg(self, imu_integration_s: float) -> float:
        """The attitude's predicted 3σ now, deg."""
        if self._aqf < AttitudeQuality.COARSE:
            return UNKNOWN_HEADING_3SIGMA_DEG
        if not self._propagated:
            return COARSE_3SIGMA_DEG
        grown = max(0.0, imu_integration_s - self._base_imu_s) * DRIFT_3SIGMA_DEG_PER_S
        return min(self._base_deg + grown, UNKNOWN_HEADING_3SIGMA_DEG)
