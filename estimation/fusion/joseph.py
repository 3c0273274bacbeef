"""Kalman measurement update in Joseph form (Jiang, Li et al. 2014, eqs. 28-30).

``K = P H^T (H P H^T + R)^-1`` (eq. 28), ``x+ = x + K (y - h(x))`` (eq. 29) and
``P+ = (I - K H) P (I - K H)^T + K R K^T`` (eq. 30). The Joseph form keeps ``P+``
symmetric and positive semi-definite for any gain, which matters when the state mixes
radians of latitude (~1e-6) with metres per second. It equals the textbook
``(I - K H) P`` for the optimal gain.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


def joseph_update(
    x: FloatArray, P: FloatArray, innovation: FloatArray, H: FloatArray, R: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Updated state and covariance; ``x`` (n,), ``P`` (n, n), ``innovation`` (m,) the
    measurement minus its prediction ``y - h(x)``, ``H`` (m, n), ``R`` (m, m).

    Raises ``ValueError`` naming the argument whose shape or values are wrong.
    """
    n, m = x.shape[0], innovation.shape[0]
    if x.ndim != 1 or P.shape != (n, n):
        raise ValueError(f"P: must be ({n}, {n}) for a state of {n}, got {P.shape}")
    if innovation.ndim != 1 or H.shape != (m, n):
        raise ValueError(f"H: must be ({m}, {n}), got {H.shape}")
    if R.shape != (m, m):
        raise ValueError(f"R: must be ({m}, {m}), got {R.shape}")
    for name, a in (("x", x), ("P", P), ("innovation", innovation), ("H", H), ("R", R)):
        if not np.all(np.isfinite(a)):
            raise ValueError(f"{name}: must be finite")
    S = H @ P @ H.T + R
    K = np.linalg.solve(S, H @ P).T  # eq. 28, S symmetric: (S^-1 H P)^T = P H^T S^-1
    x_new: FloatArray = x + K @ innovation  # eq. 29
    I_KH = np.eye(n) - K @ H
    P_new: FloatArray = I_KH @ P @ I_KH.T + K @ R @ K.T  # eq. 30, Joseph form
    return x_new, 0.5 * (P_new + P_new.T)
