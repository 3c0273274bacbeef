"""The onboard position uncertainty: how well the rover knows where it is.

SAPP propagates a position and no uncertainty (Ali et al. 2005 sec. 2.5); a keep-out check
needs one. The model here is the error budget MER's requirement states (the position error
a fraction of the distance driven on wheel odometry, sec. 1) with the heading's share made
explicit, and VO's own covariance where VO measured the motion (Cheng, Maimone and Matthies
2005, eqs. 15-17: the maximum-likelihood motion's covariance):

- On wheel odometry the error of one drive grows *linearly* with the distance ``D`` driven
  since the drive began or since the last VO update: slip and wheel-radius errors are
  systematic over a drive, not independent per cycle. Along track ``f D`` (``f``,
  ``MobilityLimits.odometry_sigma_fraction``, 1σ); across track ``D σ_ψ``, the heading's
  1σ from the attitude knowledge (AQF's 3σ over 3, ``estimation.sapp.hga_pointing``)::

      σ² = σ₀² + (f D)² + (σ_ψ D)²

  with ``σ₀`` the uncertainty at the drive's start (earlier drives are independent of this
  one: their variances add).
- A converged VO step measures the motion since the previous pair with covariance ``C``
  (its position block, in the previous body frame): the new uncertainty is the previous
  pair's plus VO's, ``σ² = σ_prev² + λ_max(C_xy)``, and ``D`` starts again from 0.

``sigma_m`` is the 1σ of the horizontal error along its worst direction (the along-track
error dominates), so the true error is inside ``2σ`` about 95 % of the time if the model
holds. ``tests/estimation/protection/test_position_sigma.py`` checks the propagation against
a Monte Carlo of the same error sources.

>>> u = PositionUncertainty()
>>> u.begin_drive(heading_3sigma_rad=0.0)
>>> round(u.sigma_at(10.0, 0.05), 6)
0.5
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]

MAX_SIGMA_M = 1.0e4  # beyond this the rover does not know where it is at all


class PositionUncertainty:
    """The horizontal position's 1σ, m, through drives and VO updates (module docstring)."""

    def __init__(self) -> None:
        self.sigma_m = 0.0  # now
        self._base_m = 0.0  # at the drive's start or the last VO update
        self._heading_sigma_rad = 0.0
        self._distance_m = 0.0  # on wheel odometry since then

    def state(self) -> dict[str, Any]:
        """Plain data (a checkpoint)."""
        return {
            "sigma_m": self.sigma_m,
            "base_m": self._base_m,
            "heading_sigma_rad": self._heading_sigma_rad,
            "distance_m": self._distance_m,
        }

    def load_state(self, state: Mapping[str, Any]) -> None:
        self.sigma_m = float(state["sigma_m"])
        self._base_m = float(state["base_m"])
        self._heading_sigma_rad = float(state["heading_sigma_rad"])
        self._distance_m = float(state["distance_m"])

    def begin_drive(self, heading_3sigma_rad: float) -> None:
        """A drive starts with the attitude known to ``heading_3sigma_rad``."""
        if not (math.isfinite(heading_3sigma_rad) and heading_3sigma_rad >= 0.0):
            raise ValueError(
                f"heading_3sigma_rad: must be finite and >= 0, got {heading_3sigma_rad}"
            )
        self._base_m = self.sigma_m
        self._heading_sigma_rad = min(heading_3sigma_rad / 3.0, 1.0)  # 1 rad: lost
        self._distance_m = 0.0

    def sigma_at(self, distance_m: float | FloatArray, fraction: float) -> Any:
        """The 1σ after ``distance_m`` more of wheel odometry (scalar or array), m."""
        d = self._distance_m + np.asarray(distance_m, dtype=np.float64)
        grown = np.sqrt(self._base_m**2 + (fraction * d) ** 2 + (self._heading_sigma_rad * d) ** 2)
        out = np.minimum(grown, MAX_SIGMA_M)
        return float(out) if out.ndim == 0 else out

    def drove(self, distance_m: float, fraction: float) -> None:
        """``distance_m`` driven on wheel odometry."""
        if not (math.isfinite(distance_m) and distance_m >= 0.0):
            raise ValueError(f"distance_m: must be finite and >= 0, got {distance_m}")
        self.sigma_m = float(self.sigma_at(distance_m, fraction))
        self._distance_m += distance_m

    def vo_update(self, sigma_before_m: float, covariance: ArrayLike) -> None:
        """A converged VO step from a pair where the uncertainty was ``sigma_before_m``;
        ``covariance`` (6, 6) of ``(θ, δp)`` (``estimation.vo.odometry.VoMotion``)."""
        c = np.asarray(covariance, dtype=np.float64)
        if c.shape != (6, 6) or not np.all(np.isfinite(c)):
            raise ValueError("covariance: must be a finite (6, 6) matrix")
        worst = float(np.max(np.linalg.eigvalsh(0.5 * (c[3:5, 3:5] + c[3:5, 3:5].T))))
        self.sigma_m = min(math.sqrt(max(sigma_before_m, 0.0) ** 2 + max(worst, 0.0)), MAX_SIGMA_M)
        self._base_m = self.sigma_m
        self._distance_m = 0.0
