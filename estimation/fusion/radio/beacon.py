"""Onboard ephemeris of an orbiting radio beacon: two-body propagation (Jiang, Li et al. 2014, eqs.
5-6).

"The parameters of orbiting radio beacons measured by the DSN are uploaded to the rover in
advance" and, over a pass, perturbations are neglected: ``dr_o/dt = v_o`` (eq. 5),
``dv_o/dt = -μ_M r_o / |r_o|³`` (eq. 6), in a Mars-centred inertial frame (here the
ICRF/J2000 axes centred on Mars). The state is integrated with RK4 (``ekf_core.rk4``) in steps of
at most ``max_step_s`` and rotated to Mars-fixed axes with the onboard IAU rotation
(``estimation.ivp.R_mf_j2000``), where the rover's position lives.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimation.fusion.ekf_core import rk4
from estimation.ivp import R_mf_j2000
from estimation.mars_constants import MARS_GM_M3_S2

FloatArray = NDArray[np.float64]


def two_body_derivative(state: FloatArray) -> FloatArray:
    """Eqs. 5-6 for the stacked state ``[r (m), v (m/s)]`` (6,) in inertial axes."""
    r = state[:3]
    accel = -MARS_GM_M3_S2 * r / float(np.linalg.norm(r)) ** 3  # eq. 6
    return np.concatenate([state[3:], accel])  # eq. 5


class OrbitingBeacon:
    """An uploaded beacon state ``(r_j2000_m, v_j2000_m_s)`` at ``t_s``, propagated forwards.

    ``position_mf_m(t_s)`` moves the held state to ``t_s`` (later than the last call) and
    returns the beacon's Mars-fixed position (m). Raises ``ValueError`` naming bad input.
    """

    def __init__(
        self, r_j2000_m: ArrayLike, v_j2000_m_s: ArrayLike, t_s: float, max_step_s: float = 10.0
    ) -> None:
        r = np.asarray(r_j2000_m, dtype=np.float64)
        v = np.asarray(v_j2000_m_s, dtype=np.float64)
        if r.shape != (3,) or not np.all(np.isfinite(r)) or np.linalg.norm(r) < 1.0e6:
            raise ValueError(f"r_j2000_m: must be a finite (3,) position beyond 1000 km, got {r}")
        if v.shape != (3,) or not np.all(np.isfinite(v)):
            raise ValueError(f"v_j2000_m_s: must be a finite (3,) velocity, got {v}")
        if not math.isfinite(t_s):
            raise ValueError(f"t_s: must be finite, got {t_s!r}")
        if not (math.isfinite(max_step_s) and max_step_s > 0.0):
            raise ValueError(f"max_step_s: must be positive, got {max_step_s!r}")
        self._state = np.concatenate([r, v])
        self._t_s = float(t_s)
        self._max_step_s = float(max_step_s)

    @property
    def t_s(self) -> float:
        """Epoch of the held state, TT seconds since J2000."""
        return self._t_s

    def state_j2000(self) -> FloatArray:
        """The held ``[r (m), v (m/s)]`` (6,), J2000 axes, Mars-centred."""
        return self._state.copy()

    def advance_to(self, t_s: float) -> None:
        """Propagate the held state to ``t_s`` (not earlier than the held epoch)."""
        if not (math.isfinite(t_s) and t_s >= self._t_s - 1e-9):
            raise ValueError(f"t_s: must be finite and not before {self._t_s}, got {t_s!r}")
        span = t_s - self._t_s
        n = max(1, math.ceil(span / self._max_step_s)) if span > 0.0 else 0
        for _ in range(n):
            self._state = rk4(two_body_derivative, self._state, span / n)
        self._t_s = float(t_s)

    def position_mf_m(self, t_s: float) -> FloatArray:
        """The beacon's Mars-fixed position (m) at ``t_s`` (propagates the held state)."""
        self.advance_to(t_s)
        out: FloatArray = R_mf_j2000(t_s) @ self._state[:3]
        return out
