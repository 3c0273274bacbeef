"""Classical fourth-order Runge-Kutta step (Jiang, Li et al. 2014, sec. 5: "a four-order Runge-Kutta
algorithm is selected as the numerical solver" of the dynamics, eq. 26).

One step of ``dx/dt = f(t, x)`` from ``t`` to ``t + dt``; its local error is ``O(dt^5)``.

>>> import numpy as np
>>> x1 = rk4_step(lambda t, x: -x, 0.0, np.array([1.0]), 0.1)
>>> round(float(x1[0]), 8), round(float(np.exp(-0.1)), 8)
(0.9048375, 0.90483742)
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
Derivative = Callable[[float, FloatArray], FloatArray]


def rk4_step(f: Derivative, t_s: float, x: FloatArray, dt_s: float) -> FloatArray:
    """``x(t_s + dt_s)`` from ``x(t_s)`` by one RK4 step of ``dx/dt = f(t, x)``.

    ``x`` any shape; ``f`` returns the same shape. ``dt_s`` (s) may be negative (backwards)
    but must be finite; ``ValueError`` naming ``dt_s`` otherwise.
    """
    if not math.isfinite(dt_s):
        raise ValueError(f"dt_s: must be finite, got {dt_s!r}")
    h = dt_s
    k1 = f(t_s, x)
    k2 = f(t_s + 0.5 * h, x + 0.5 * h * k1)
    k3 = f(t_s + 0.5 * h, x + 0.5 * h * k2)
    k4 = f(t_s + h, x + h * k3)
    out: FloatArray = x + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    return out
