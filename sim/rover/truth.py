"""Truth state of the simulated rover, sampled at the control rate, as batches of arrays.

The simulator produces truth a segment at a time (one drive primitive, or one idle
interval) as arrays, so the expensive parts (settling the suspension, generating sensor
samples) vectorise over time. The control loop later walks these arrays cycle by cycle.

Frames (docs/CONVENTIONS.md): ``s`` is the Site frame (N, E, Down) of the scenario; ``ll``
the Local-Level frame at the rover; ``b`` the rover body (x forward, y right, z down).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

FloatArray = NDArray[np.float64]

CONTROL_RATE_HZ = 8.0  # MER's attitude/position loop rate (Ali et al. 2005)
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

    def v_s(self) -> FloatArray:
        """Velocity of the body origin in the Site frame, m/s, (N, 3).

        Central differences inside, one-sided at the ends (second order on the 8 Hz grid).
        """
        if len(self) < 2:
            return np.zeros((len(self), 3))
        out: FloatArray = np.gradient(self.p_s, self.t_s, axis=0)
        return out

    def accel_s_from_rest(self) -> FloatArray:
        """Mean acceleration of the body origin over each interval, Site axes, m/s², (N-1, 3),
        for a trajectory that starts and ends at rest (a drive primitive).

        The velocity at each inner instant is the mean of its two intervals' velocities and
        zero at both ends, so the accelerations integrate to no net velocity change and,
        twice (trapezoidal), to the displacement but for half an interval's travel at each end.
        """
        if len(self) < 2:
            return np.zeros((0, 3))
        dt = np.diff(self.t_s)
        u = np.diff(self.p_s, axis=0) / dt[:, None]  # per interval
        v = np.zeros((len(self), 3))
        v[1:-1] = 0.5 * (u[:-1] + u[1:])
        out: FloatArray = np.diff(v, axis=0) / dt[:, None]
        return out

    def omega_b_s_in_b(self) -> FloatArray:
        """Angular rate of the body relative to the Site frame, in body axes, rad/s, (N-1, 3).

        One value per interval: the rotation vector of ``R_s_b(k)ᵀ R_s_b(k+1)`` over its
        duration, exact for a rotation about a fixed axis within the interval.
        """
        if len(self) < 2:
            return np.zeros((0, 3))
        R = Rotation.from_quat(self.q_s_b)
        out: FloatArray = (R[:-1].inv() * R[1:]).as_rotvec() / np.diff(self.t_s)[:, None]
        return out
