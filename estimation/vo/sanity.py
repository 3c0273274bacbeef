"""Sanity constraints on a visual-odometry update (the February 2005 MER flight software).

Cheng, Maimone and Matthies 2005, end of sec. 2: "As of the February 2005 version
of MER flight software, optional constraints can also be placed on the final motion estimate
to provide additional sanity checking. The magnitude of the 3D update vector, its X and Y
Site Frame components, the magnitude of the Roll, Pitch and Yaw updates and the angular
deviation from a purely downslope vector can all be restricted. Any update violating the
active set of constraints is treated as a failure to converge."

The update is what VO changes relative to the wheel-odometry (predicted) motion of the same
step: the position update ``Δp_s = R_s_b0 (p_b1_b0(VO) - p_b1_b0(wheels))`` in the Site frame
and the differences of roll, pitch and yaw of the new attitude ``R_s_b1 = R_s_b0 R_b0_b1``
(z-y-x Euler angles of ``R_s_b``, docs/CONVENTIONS.md: Site is North-East-Down, body
forward-right-down). Downslope is the direction of steepest descent in the plane of the
rover's deck: ``down_s`` minus its component along the body ``z`` axis. Slip carries the
rover downhill, so an honest update points roughly downslope; on nearly level ground the
direction is meaningless and the check is skipped, as it is for updates too small to have a
direction. Every limit is optional (``None``: not active). Flight software: numpy, scipy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from estimation.camera_model import check_rotation_matrix
from estimation.checks import finite_array

FloatArray = NDArray[np.float64]

DOWN_S = np.array([0.0, 0.0, 1.0])  # Site z points down (docs/CONVENTIONS.md)


@dataclass(frozen=True)
class SanityLimits:
    """The active constraints; ``None`` switches one off. Angles in radians, lengths in m.

    ``max_update_m``: ``|Δp_s|``; ``max_update_x_m``/``max_update_y_m``: ``|Δp_s|`` along Site
    x (North) and y (East); ``max_roll_update_rad``, ``max_pitch_update_rad``,
    ``max_yaw_update_rad``: the Euler-angle changes; ``max_downslope_angle_rad``: the angle
    between ``Δp_s`` and downslope, checked only where the tilt is at least
    ``downslope_min_tilt_rad`` and ``|Δp_s|`` at least ``downslope_min_update_m``.
    """

    max_update_m: float | None = 1.0
    max_update_x_m: float | None = 1.0
    max_update_y_m: float | None = 1.0
    max_roll_update_rad: float | None = math.radians(5.0)
    max_pitch_update_rad: float | None = math.radians(5.0)
    max_yaw_update_rad: float | None = math.radians(10.0)
    max_downslope_angle_rad: float | None = None
    downslope_min_tilt_rad: float = math.radians(5.0)
    downslope_min_update_m: float = 0.02

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if value is None:
                continue
            if not (isinstance(value, int | float) and math.isfinite(value) and value >= 0.0):
                raise ValueError(f"{f.name}: must be a non-negative number or None, got {value!r}")


@dataclass(frozen=True)
class Update:
    """A step's VO update relative to wheel odometry: ``dp_s`` (3,) m in Site,
    ``d_roll_rad``, ``d_pitch_rad``, ``d_yaw_rad`` (wrapped to ±π), ``downslope_s`` (3,) the
    unit downslope direction (zero on level ground), ``tilt_rad`` the deck's tilt."""

    dp_s: FloatArray
    d_roll_rad: float
    d_pitch_rad: float
    d_yaw_rad: float
    downslope_s: FloatArray
    tilt_rad: float

    @property
    def downslope_angle_rad(self) -> float:
        """Angle between ``dp_s`` and downslope (NaN if either has no direction)."""
        n = float(np.linalg.norm(self.dp_s))
        if n == 0.0 or not np.any(self.downslope_s):
            return math.nan
        return math.acos(float(np.clip(self.dp_s @ self.downslope_s / n, -1.0, 1.0)))


def roll_pitch_yaw(R_s_b: ArrayLike) -> tuple[float, float, float]:
    """Roll, pitch, yaw (rad) of ``R_s_b``: ``R_s_b = Rz(yaw) Ry(pitch) Rx(roll)``.

    >>> [round(math.degrees(a), 9) for a in roll_pitch_yaw(
    ...     Rotation.from_euler("ZYX", [30, 10, -5], degrees=True).as_matrix())]
    [-5.0, 10.0, 30.0]
    """
    R = check_rotation_matrix(R_s_b, "R_s_b")
    yaw, pitch, roll = Rotation.from_matrix(R).as_euler("ZYX")
    return float(roll), float(pitch), float(yaw)


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def update_of(
    R_b0_b1_vo: ArrayLike,
    p_b1_b0_vo: ArrayLike,
    R_b0_b1_wheels: ArrayLike,
    p_b1_b0_wheels: ArrayLike,
    R_s_b0: ArrayLike,
) -> Update:
    """The update VO makes to the wheel-odometry motion of one step (module docstring).

    ``R_b0_b1_*`` take new-body coordinates to previous-body ones; ``p_b1_b0_*`` are the new
    body origin in the previous body frame, m; ``R_s_b0`` the attitude at the previous pair.
    """
    R_s = check_rotation_matrix(R_s_b0, "R_s_b0")
    R_vo = check_rotation_matrix(R_b0_b1_vo, "R_b0_b1_vo")
    R_wheels = check_rotation_matrix(R_b0_b1_wheels, "R_b0_b1_wheels")
    p_vo = finite_array(p_b1_b0_vo, "p_b1_b0_vo", (3,))
    p_wheels = finite_array(p_b1_b0_wheels, "p_b1_b0_wheels", (3,))
    dp_s = R_s @ (p_vo - p_wheels)
    roll_vo, pitch_vo, yaw_vo = roll_pitch_yaw(R_s @ R_vo)
    roll_w, pitch_w, yaw_w = roll_pitch_yaw(R_s @ R_wheels)
    normal_s = R_s[:, 2]  # body z (down through the deck) in Site
    downhill = DOWN_S - (DOWN_S @ normal_s) * normal_s
    size = float(np.linalg.norm(downhill))
    tilt = math.acos(float(np.clip(DOWN_S @ normal_s, -1.0, 1.0)))
    downslope = downhill / size if size > 1e-12 else np.zeros(3)
    return Update(
        dp_s,
        _wrap(roll_vo - roll_w),
        _wrap(pitch_vo - pitch_w),
        _wrap(yaw_vo - yaw_w),
        downslope,
        tilt,
    )


def violation(update: Update, limits: SanityLimits) -> str | None:
    """The first constraint ``update`` violates, as a sentence naming it; ``None`` if sane."""
    size = float(np.linalg.norm(update.dp_s))
    checks = [
        ("update magnitude", size, limits.max_update_m, "m"),
        ("Site X update", abs(float(update.dp_s[0])), limits.max_update_x_m, "m"),
        ("Site Y update", abs(float(update.dp_s[1])), limits.max_update_y_m, "m"),
        ("roll update", abs(update.d_roll_rad), limits.max_roll_update_rad, "rad"),
        ("pitch update", abs(update.d_pitch_rad), limits.max_pitch_update_rad, "rad"),
        ("yaw update", abs(update.d_yaw_rad), limits.max_yaw_update_rad, "rad"),
    ]
    for name, value, limit, unit in checks:
        if limit is not None and value > limit:
            return f"{name} {value:.4g} {unit} exceeds the limit {limit:.4g} {unit}"
    limit = limits.max_downslope_angle_rad
    if (
        limit is not None
        and update.tilt_rad >= limits.downslope_min_tilt_rad
        and size >= limits.downslope_min_update_m
    ):
        angle = update.downslope_angle_rad
        if angle > limit:
            return (
                f"update is {math.degrees(angle):.1f} deg from downslope "
                f"(limit {math.degrees(limit):.1f} deg)"
            )
    return None
