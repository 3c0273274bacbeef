"""Joint rates from sampled joint angles: "simple smoothing and differencing" (Balaram 2000 sec. 3).

Balaram's filter takes the suspension's joint angles and rates as known inputs. A plain
difference over one control interval amplifies the angle sensors' noise by ``√2 / dt``;
the least-squares slope of a straight line through the four samples around the interval
(two before its middle, two after) cuts that by ``√10 / 2 ≈ 1.6`` more than ``√2``
(``σ / (dt √5)`` instead of ``σ √2 / dt``) at the price of one sample of latency, and is
exact for angles that change linearly. At the ends of a record it falls back to the
plain difference.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]


def interval_rates(angles: ArrayLike, t_s: ArrayLike) -> FloatArray:
    """Rates over each interval ``[t_k, t_k+1]`` (N-1, ...) from angles (N, ...) at ``t_s`` (N,).

    >>> rates = interval_rates([0.0, 1.0, 2.0, 3.0, 4.0], [0.0, 0.5, 1.0, 1.5, 2.0])
    >>> np.round(rates, 12).tolist()  # the slope's dot product may round in the last bit
    [2.0, 2.0, 2.0, 2.0]
    """
    a = np.asarray(angles, dtype=float)
    t = np.asarray(t_s, dtype=float)
    if t.ndim != 1 or a.shape[:1] != t.shape or t.size < 2:
        raise ValueError(f"need angles (N, ...) at N >= 2 instants, got {a.shape} and {t.shape}")
    if not (np.all(np.isfinite(a)) and np.all(np.diff(t) > 0.0)):
        raise ValueError("angles must be finite and t_s strictly increasing")
    dt = np.diff(t).reshape((-1,) + (1,) * (a.ndim - 1))
    out: FloatArray = np.diff(a, axis=0) / dt
    if t.size >= 4:  # the least-squares slope over each window of four, all windows at once
        windows = np.lib.stride_tricks.sliding_window_view(t, 4)
        tt = windows - 0.5 * (windows[:, 1:2] + windows[:, 2:3])
        centred = tt - tt.mean(axis=1, keepdims=True)
        w = centred / np.sum(centred**2, axis=1, keepdims=True)
        a_windows = np.lib.stride_tricks.sliding_window_view(a, 4, axis=0)  # (N-3, ..., 4)
        out[1 : t.size - 2] = np.einsum("kj,k...j->k...", w, a_windows)
    return out
