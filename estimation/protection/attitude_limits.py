"""Tilt and suspension limits: the reactive checks on the vehicle's attitude and shape.

MER's mobility flight software stopped a drive when the vehicle tilted past a limit or a
suspension angle left its range (Biesiadecki and Maimone 2006 sec. 3, "reactive" checks).
Onboard, roll and pitch come from the accelerometers: at rest or driving slowly they
measure the specific force ``f_b ≈ -g_b`` (body x forward, y right, z down), so with
``f_b = (f_x, f_y, f_z)``::

    pitch = atan2(f_x, sqrt(f_y² + f_z²))     (nose up positive)
    roll  = atan2(-f_y, -f_z)                 (right side down positive)

the standard strapdown levelling relations (Titterton and Weston 2004). The
accelerations of driving (starts, stops, rocks) are short and small against gravity; a
1 s moving average of the 8 Hz samples (``TILT_WINDOW_CYCLES``) keeps them from tripping
the check. The rocker and bogie angles are their encoders' readings.

>>> g = 3.711
>>> roll, pitch = roll_pitch_rad(np.array([[g * math.sin(0.1), 0.0, -g * math.cos(0.1)]]))
>>> abs(round(float(roll[0]), 9)), round(float(pitch[0]), 9)  # nose up 0.1 rad
(0.0, 0.1)
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

TILT_WINDOW_CYCLES = 8  # 1 s of 8 Hz samples


def roll_pitch_rad(f_b: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Roll and pitch (rad), (N,) each, from specific forces ``f_b`` (N, 3), m/s²."""
    f = np.atleast_2d(np.asarray(f_b, dtype=np.float64))
    if f.shape[1:] != (3,):
        raise ValueError(f"f_b: must have shape (N, 3), got {f.shape}")
    pitch = np.arctan2(f[:, 0], np.hypot(f[:, 1], f[:, 2]))
    roll = np.arctan2(-f[:, 1], -f[:, 2])
    return roll, pitch


def smoothed_specific_force(delta_velocity_b: FloatArray, dt_s: FloatArray) -> FloatArray:
    """The specific force of each cycle, averaged over the cycle and the ones before it in
    a ``TILT_WINDOW_CYCLES`` window (N, 3), m/s², from the IMU's velocity increments."""
    dv = np.asarray(delta_velocity_b, dtype=np.float64)
    dt = np.asarray(dt_s, dtype=np.float64)
    if dv.ndim != 2 or dv.shape[1] != 3 or dt.shape != (len(dv),):
        raise ValueError("delta_velocity_b (N, 3) and dt_s (N,) must match")
    if np.any(~np.isfinite(dt)) or np.any(dt <= 0.0):
        raise ValueError("dt_s: must be positive and finite")
    c_dv = np.vstack([np.zeros(3), np.cumsum(dv, axis=0)])
    c_dt = np.concatenate([[0.0], np.cumsum(dt)])
    hi = np.arange(1, len(dv) + 1)
    lo = np.maximum(0, hi - TILT_WINDOW_CYCLES)
    out: FloatArray = (c_dv[hi] - c_dv[lo]) / (c_dt[hi] - c_dt[lo])[:, None]
    return out


def first_over(values: FloatArray, limit: float) -> int | None:
    """Index of the first ``|values|`` above ``limit`` (``None`` if none)."""
    over = np.flatnonzero(np.abs(np.asarray(values, dtype=np.float64)) > limit)
    return int(over[0]) if over.size else None


def tilt_rad(roll_rad: float, pitch_rad: float) -> float:
    """The total tilt of the body's z axis from the vertical, rad."""
    return math.acos(max(-1.0, min(1.0, math.cos(roll_rad) * math.cos(pitch_rad))))
