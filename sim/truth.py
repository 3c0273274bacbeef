"""Truth state of the simulated rover, sampled at the control rate, as batches of arrays.

The simulator produces truth a segment at a time (one drive primitive, or one idle
interval) as arrays, so the expensive parts (settling the suspension, generating sensor
samples) vectorise over time. The control loop later walks these arrays cycle by cycle.

Frames (CONVENTIONS.md): ``s`` is the Site frame (N, E, Down) of the scenario; ``ll``
the Local-Level frame at the rover; ``b`` the rover body (x forward, y right, z down).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

CONTROL_RATE_HZ = 8.0  # MER's attitude/position loop rate (seed 000)
CONTROL_DT_S = 1.0 / CONTROL_RATE_HZ

WHEEL_NAMES = ("LF", "LM", "LR", "RF", "RM", "RR")  # left/right, front/middle/rear
STEERED_WHEELS = ("LF", "LR", "RF", "RR")  # the four corner wheels carry steering actuators


@dataclass(frozen=True)
class TruthTrajectory:
    """Truth at ``N`` instants ``t_s`` (TT seconds since J2000), all arrays first axis ``N``.

    - ``p_s``: body origin in the Site frame, metres, (N, 3).
    - ``q_s_b``: attitude of the body in the Site frame, ``[x, y, z, w]``, (N, 4);
      ``Rotation.from_quat(q_s_b).apply(v_b) == v_s``.
    - ``rocker_rad``: left rocker angle relative to the body (the differential makes the
      right one its negative), (N,).
    - ``bogie_rad``: left and right bogie angles relative to their rockers, (N, 2).
    - ``wheel_angle_rad``: cumulative rotation of each wheel in ``WHEEL_NAMES`` order, (N, 6).
    - ``steer_rad``: steering angle of each wheel in ``STEERED_WHEELS`` order, (N, 4);
      positive turns the wheel's front to the right (about body +z, Down).
    - ``slip``: longitudinal slip ratio ``1 - v_actual / v_wheel`` (N,); >1 slides back.
    """

    t_s: FloatArray
    p_s: FloatArray
    q_s_b: FloatArray
    rocker_rad: FloatArray
    bogie_rad: FloatArray
    wheel_angle_rad: FloatArray
    steer_rad: FloatArray
    slip: FloatArray

    def __post_init__(self) -> None:
        n = self.t_s.shape[0]
        shapes = {
            "p_s": (n, 3),
            "q_s_b": (n, 4),
            "rocker_rad": (n,),
            "bogie_rad": (n, 2),
            "wheel_angle_rad": (n, 6),
            "steer_rad": (n, 4),
            "slip": (n,),
        }
        for name, shape in shapes.items():
            if getattr(self, name).shape != shape:
                raise ValueError(f"{name} has shape {getattr(self, name).shape}, want {shape}")

    def __len__(self) -> int:
        return int(self.t_s.shape[0])
