"""The HGA pointing margin as the rover predicts it from its own attitude knowledge.

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
from typing import Any

from estimation.sapp.aqf import AttitudeQuality
from estimation.sapp.hga_pointing import HGA_POINTING_REQUIREMENT_DEG
from estimation.sapp.nate_io import NateParams

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
