"""The flight software's one copy of the rover: its dimensions and how fast it drives.

The flight software may not import the simulator, so it keeps its own copy of the rover's
dimensions: nominal MER-like values, the same as the simulated rover's
(``sim.rover.geometry``; approximate MER dimensions, Lindemann and Voorhees 2005; wheel
diameter 26 cm, wheelbase 1.4 m, track 1.2 m, middle wheels under the body origin, the
turn-in-place centre). Wheel odometry (``estimation.sapp.wheel_odometry``, Ali et al. 2005
sec. 2.5) uses the wheel centres in the plane; the kinematic filter
(``estimation.fusion.kinematic.rover_kinematics``, Balaram 2000 sec. 2.2.4) the whole
rocker-bogie. ``tests/estimation/fusion/test_kinematic_ekf_sensors.py`` checks them against the
simulated rover.

The rates the mobility software drives at are the flight software's too (Ali et al. 2005
sec. 2.5: about 3.75 cm/s; sec. 2.4.2: turns at about 2.1 deg/s): the simulator drives at
them and the ground's validator predicts durations with them.

The rover's shape above its wheels (``ROVER_BOXES_B``, ``ROVER_CYLINDERS_B``, the wheels'
width) is the flight copy of ``sim.rover.geometry``'s shape table, for the rover's own shadow
(the ground's pointing advisor, ``server.terrain.advisor``, and the flight VO's shadow mask,
``estimation.vo.shadow_mask``); ``tests/estimation/test_geometry_shapes.py`` keeps the two
equal.

Frames (docs/CONVENTIONS.md): body ``b`` x forward, y right, z down. Wheel order LF, LM, LR,
RF, RM, RR; steered wheels LF, LR, RF, RR. Commands name a wheel in lower case, ``WHEEL_KEYS``
(``drag_wheel=rf``: a wheel not driven and dragged, as Spirit's right front from sol 125,
Cheng, Maimone and Matthies 2005 sec. 4.2).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

N_WHEELS = 6
STEERED_INDEX = (0, 2, 3, 5)  # LF, LR, RF, RR in the wheel order (module docstring)
WHEEL_KEYS = ("lf", "lm", "lr", "rf", "rm", "rr")  # the wheels as commands name them, in order

DRIVE_SPEED_M_S = 0.0375  # Ali et al. 2005 sec. 2.5: MER drives at ~3.75 cm/s
TURN_RATE_DEG_S = 2.1  # Ali et al. 2005 sec. 2.4.2: turns at ~2.1 deg/s
TURN_RATE_RAD_S = math.radians(TURN_RATE_DEG_S)


@dataclass(frozen=True)
class FlightGeometry:
    """Rover dimensions the flight software uses (metres), body frame at zero joint angles.

    Wheel centres at ``x ∈ {x_front, x_middle, x_rear}``, ``y = ∓track/2`` (left negative,
    y is right), ``z = wheel_centre_z_m`` below the body origin; the rocker and bogie
    pivots as ``rover_kinematics.suspension`` uses them.
    """

    wheel_radius_m: float = 0.13  # MER wheel diameter 26 cm (docs/REFERENCES.md)
    wheel_width_m: float = 0.16  # approximate, as sim.rover.geometry
    track_m: float = 1.2  # approximate, as sim.rover.geometry
    x_front_m: float = 0.70  # approximate, as sim.rover.geometry
    x_middle_m: float = 0.0  # as sim.rover.geometry: middle wheels under the origin
    x_rear_m: float = -0.70  # approximate, as sim.rover.geometry
    wheel_centre_z_m: float = 0.17
    rocker_pivot_x_m: float = 0.10
    rocker_pivot_z_m: float = -0.05
    bogie_pivot_x_m: float = -0.35
    bogie_pivot_z_m: float = 0.02

    def __post_init__(self) -> None:
        for name, value in self.__dict__.items():
            if not (isinstance(value, int | float) and math.isfinite(value)):
                raise ValueError(f"{name}: must be finite")
        for name in ("wheel_radius_m", "wheel_width_m", "track_m"):
            if getattr(self, name) <= 0.0:
                raise ValueError(f"{name}: must be positive")
        if not self.x_front_m > self.x_middle_m > self.x_rear_m:
            raise ValueError("x_middle_m: wheels must go front, middle, rear along x")

    def wheel_xy_b(self) -> FloatArray:
        """Wheel centres ``(x, y)`` in the body frame (m), shape (6, 2), LF..RR order.

        >>> FlightGeometry().wheel_xy_b()[0].tolist()
        [0.7, -0.6]
        """
        xs = (self.x_front_m, self.x_middle_m, self.x_rear_m)
        half = 0.5 * self.track_m
        return np.array([[x, -half] for x in xs] + [[x, half] for x in xs])


FLIGHT_GEOMETRY = FlightGeometry()

# The rover's shape above its wheels, body frame (m), as sim.rover.geometry's ROVER_BOXES and
# ROVER_CYLINDERS (approximate MER proportions): boxes as (name, centre, full size along x, y,
# z); cylinders, their axes along body z, as (name, centre, radius, length).
ROVER_BOXES_B: tuple[tuple[str, tuple[float, float, float], tuple[float, float, float]], ...] = (
    ("body", (0.05, 0.0, -0.175), (1.3, 0.9, 0.35)),  # warm electronics box
    ("deck", (0.0, 0.0, -0.37), (1.6, 1.9, 0.03)),  # solar-array deck
    ("pancam", (0.45, -0.30, -1.30), (0.12, 0.3, 0.1)),  # camera bar on the mast head
    ("navcam_left", (0.5, -0.42, -1.24), (0.08, 0.06, 0.06)),  # the Navcams below it
    ("navcam_right", (0.5, -0.18, -1.24), (0.08, 0.06, 0.06)),
    ("minites", (0.35, -0.30, -1.36), (0.16, 0.12, 0.10)),  # the mast head's back
    ("lga_tip", (-0.5, 0.6, -0.9), (0.08, 0.08, 0.08)),  # low-gain antenna's tip
    ("uhf_tip", (-0.6, -0.5, -0.75), (0.06, 0.06, 0.06)),  # UHF antenna's tip
    ("sundial", (0.2, 0.5, -0.5), (0.1, 0.1, 0.2)),  # the Pancam calibration target
    *(
        part
        for side, y in (("left", -0.6), ("right", 0.6))
        for part in (  # the suspension's links at zero joint angles, axis-aligned bars
            (f"rocker_front_{side}", (0.40, y, 0.06), (0.60, 0.05, 0.05)),
            (f"rocker_rear_{side}", (-0.12, y, -0.015), (0.46, 0.05, 0.05)),
            (f"bogie_{side}", (-0.35, y, 0.10), (0.70, 0.05, 0.05)),
            (f"strut_front_{side}", (0.70, y, 0.05), (0.04, 0.04, 0.20)),
            (f"strut_middle_{side}", (0.0, y, 0.10), (0.04, 0.04, 0.12)),
            (f"strut_rear_{side}", (-0.70, y, 0.10), (0.04, 0.04, 0.12)),
        )
    ),
)
ROVER_CYLINDERS_B: tuple[tuple[str, tuple[float, float, float], float, float], ...] = (
    ("mast", (0.45, -0.30, -0.82), 0.04, 0.9),  # stands along -z from the deck
    ("hga", (-0.35, 0.45, -0.50), 0.14, 0.03),  # the high-gain antenna's dish
    ("lga", (-0.5, 0.6, -0.62), 0.012, 0.52),  # low-gain antenna's mast
    ("uhf", (-0.6, -0.5, -0.55), 0.012, 0.36),  # UHF antenna's mast
)


def wheel_index(key: str, name: str = "drag_wheel") -> int:
    """The index in the wheel order of the wheel ``key`` names (``WHEEL_KEYS``);
    ``ValueError`` naming the parameter ``name`` otherwise.

    >>> wheel_index("rf")
    3
    """
    if not isinstance(key, str) or key not in WHEEL_KEYS:
        raise ValueError(f"{name}: must be one of {', '.join(WHEEL_KEYS)}, got {key!r}")
    return WHEEL_KEYS.index(key)


def driven_wheels(drag_wheel: str | None) -> NDArray[np.bool_]:
    """Which wheels are driven (6,) when ``drag_wheel`` (a ``WHEEL_KEYS`` name or None)
    is dragged: all but that one.

    >>> driven_wheels("rf").tolist()
    [True, True, True, False, True, True]
    """
    out = np.ones(N_WHEELS, dtype=bool)
    if drag_wheel is not None:
        out[wheel_index(drag_wheel)] = False
    return out
