"""MER-like six-wheel rocker-bogie geometry and its forward kinematics.

Frames (docs/CONVENTIONS.md): the rover body frame ``b`` has x forward, y right, z down, its
origin at the bottom of the body, midway between the two middle wheels in x and y.

The suspension is the MER rocker-bogie (Lindemann and Voorhees 2005, "Mars Exploration
Rover mobility assembly design, test and performance"): on each side a *rocker* hinged to
the body carries the front wheel at one end and, at the other, the pivot of a *bogie* that
carries the middle and rear wheels. A differential joins the two rockers through the body,
so the right rocker angle is the negative of the left one. All suspension joints turn
about the body y axis, so every wheel centre keeps its lateral offset ``±track/2``.

Joint angles are right-handed rotations about body +y (right). With z down that lifts the
forward end of a link: a positive left rocker angle raises the left front wheel.
``bogie_rad`` are the bogie angles relative to their rockers, ``[left, right]``.

Steering (the four corner wheels): a rotation of the wheel about the link's z axis through
the wheel centre, positive turning the wheel's front to the right (clockwise seen from
above, as in Ali et al. 2005 section 2.5). We assume the steering axis passes through the wheel
centre, so steering turns the axle but does not move the wheel centre.

The wheel order everywhere is ``WHEEL_NAMES`` of ``sim.rover.truth``: LF, LM, LR, RF, RM, RR.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, fields

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sim.compiled import kernel
from sim.errors import InputError
from sim.rover.truth import STEERED_WHEELS, WHEEL_NAMES

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

# Index of each steered wheel (STEERED_WHEELS order) in WHEEL_NAMES order.
STEERED_INDEX = tuple(WHEEL_NAMES.index(name) for name in STEERED_WHEELS)
LEFT = (0, 1, 2)  # LF, LM, LR
RIGHT = (3, 4, 5)  # RF, RM, RR


@dataclass(frozen=True)
class RoverGeometry:
    """Dimensions of a MER-like rover (metres, radians, kilograms), body-frame positions.

    Positions ``(x, z)`` are in the body frame at zero joint angles (x forward, z down).
    Values marked "approximate" are plausible choices, not flight drawings
    (docs/REFERENCES.md, Hardware: "rocker-bogie link lengths: choose and document").
    """

    wheel_radius_m: float = 0.13  # docs/REFERENCES.md: MER wheel diameter 26 cm
    wheel_width_m: float = 0.16  # approximate, MER wheel width ~16 cm
    track_m: float = 1.2  # approximate: between left and right wheel centres
    x_front_m: float = 0.70  # approximate: wheelbase front-to-rear 1.4 m
    x_middle_m: float = 0.0  # middle wheels under the origin, the turn-in-place centre
    x_rear_m: float = -0.70  # approximate
    # Depth of the wheel centres below the body origin at zero angles: with r = 0.13 m
    # the body bottom clears level ground by 0.30 m (approximate, MER-like clearance).
    wheel_centre_z_m: float = 0.17
    rocker_pivot_x_m: float = 0.10  # approximate: differential pivot, on the body side
    rocker_pivot_z_m: float = -0.05  # approximate: 5 cm above the body bottom
    bogie_pivot_x_m: float = -0.35  # approximate: midway between middle and rear wheels
    bogie_pivot_z_m: float = 0.02  # approximate: 15 cm above the wheel centres
    rocker_limit_rad: float = float(np.deg2rad(35.0))  # approximate joint stop, ±
    bogie_limit_rad: float = float(np.deg2rad(60.0))  # approximate joint stop, ±
    mass_kg: float = 174.0  # docs/REFERENCES.md: ~174 kg

    def __post_init__(self) -> None:
        for f in fields(self):
            if not math.isfinite(getattr(self, f.name)):
                raise InputError(f.name, "must be finite")
        for name in (
            "wheel_radius_m",
            "wheel_width_m",
            "track_m",
            "wheel_centre_z_m",
            "rocker_limit_rad",
            "bogie_limit_rad",
            "mass_kg",
        ):
            if getattr(self, name) <= 0.0:
                raise InputError(name, "must be positive")
        if not self.x_front_m > self.x_middle_m > self.x_rear_m:
            raise InputError("x_middle_m", "wheels must go front, middle, rear along x")

    @property
    def body_height_m(self) -> float:
        """Height of the body origin above level ground with no sinkage (m)."""
        return self.wheel_centre_z_m + self.wheel_radius_m

    def wheel_xy_b(self) -> FloatArray:
        """Wheel-centre ``(x, y)`` in the body frame at zero joint angles, shape (6, 2)."""
        xs = (self.x_front_m, self.x_middle_m, self.x_rear_m)
        half = 0.5 * self.track_m
        return np.array([[x, -half] for x in xs] + [[x, half] for x in xs])

    def plane_fit_b(self) -> FloatArray:
        """The least-squares plane through heights under the six wheels: this (3, 6) matrix
        times the heights gives ``(h0, dh/dx, dh/dy)`` in the heading frame (the
        pseudo-inverse of ``[1, x, y]`` at ``wheel_xy_b``). Computed once per geometry
        (the drive asks for it at every step); read-only."""
        return _plane_fit_b(self)

    def _offsets(self) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
        """Link vectors in (x, z): pivot P, front-P, bogie pivot-P, middle-B, rear-B."""
        p = np.array([self.rocker_pivot_x_m, self.rocker_pivot_z_m])
        b = np.array([self.bogie_pivot_x_m, self.bogie_pivot_z_m])
        zc = self.wheel_centre_z_m
        front = np.array([self.x_front_m, zc]) - p
        middle = np.array([self.x_middle_m, zc]) - b
        rear = np.array([self.x_rear_m, zc]) - b
        return p, front, b - p, middle, rear


@functools.lru_cache(maxsize=8)
def _plane_fit_b(geometry: RoverGeometry) -> FloatArray:
    out: FloatArray = np.linalg.pinv(np.column_stack([np.ones(6), geometry.wheel_xy_b()]))
    out.flags.writeable = False
    return out


@dataclass(frozen=True)
class WheelKinematics:
    """Wheel centres, axles and their joint-angle derivatives, all in the body frame.

    Shapes: ``centre_b``, ``axle_b`` (..., 6, 3); ``link_rad`` (..., 6) is the pitch of the
    link that carries each wheel (rocker for the fronts, rocker + bogie otherwise);
    ``dcentre_dq`` (..., 6, 3, 3) with the last axis over (rocker, bogie_left,
    bogie_right); ``daxle_dq`` likewise. Unit axles point to the wheel's right (body +y at
    zero steering).
    """

    centre_b: FloatArray
    axle_b: FloatArray
    link_rad: FloatArray
    dcentre_dq: FloatArray
    daxle_dq: FloatArray


def wheel_kinematics(
    geometry: RoverGeometry,
    rocker_rad: ArrayLike,
    bogie_rad: ArrayLike,
    steer_rad: ArrayLike | None = None,
) -> WheelKinematics:
    """Forward kinematics of the suspension, vectorised over leading axes.

    ``rocker_rad`` (...,) is the left rocker angle (the right one is its negative),
    ``bogie_rad`` (..., 2) the [left, right] bogie angles relative to their rockers,
    ``steer_rad`` (..., 4) the corner steering angles in ``STEERED_WHEELS`` order (zero
    if omitted). Returns wheel centres and axles in the body frame with their derivatives
    (one compiled pass over the poses, ``_kinematics``: the settling asks at every Newton
    iteration).

    >>> g = RoverGeometry()
    >>> k = wheel_kinematics(g, 0.0, [0.0, 0.0])
    >>> np.allclose(k.centre_b[:, 2], g.wheel_centre_z_m)
    True
    """
    rocker = np.asarray(rocker_rad, dtype=float)
    bogie = np.asarray(bogie_rad, dtype=float)
    lead = np.broadcast_shapes(rocker.shape, bogie.shape[:-1])
    steer = np.zeros(4) if steer_rad is None else np.asarray(steer_rad, dtype=float)
    n = math.prod(lead)
    centre = np.empty((n, 6, 3))
    axle = np.empty((n, 6, 3))
    link = np.empty((n, 6))
    dcentre = np.zeros((n, 6, 3, 3))
    daxle = np.zeros((n, 6, 3, 3))
    _kinematics(
        np.ascontiguousarray(np.broadcast_to(rocker, lead)).reshape(n),
        np.ascontiguousarray(np.broadcast_to(bogie, (*lead, 2))).reshape(n, 2),
        np.ascontiguousarray(np.broadcast_to(steer, (*lead, 4))).reshape(n, 4),
        np.stack(geometry._offsets()),
        0.5 * geometry.track_m,
        _STEERED,
        centre,
        axle,
        link,
        dcentre,
        daxle,
    )
    return WheelKinematics(
        centre.reshape(*lead, 6, 3),
        axle.reshape(*lead, 6, 3),
        link.reshape(*lead, 6),
        dcentre.reshape(*lead, 6, 3, 3),
        daxle.reshape(*lead, 6, 3, 3),
    )


_STEERED = np.array(STEERED_INDEX, dtype=np.int64)


@kernel
def _rot_xz(c: float, s: float, v: FloatArray) -> tuple[float, float]:
    """Rotate the (x, z) link vector ``v`` by the angle of cosine ``c``, sine ``s`` about
    +y: Ry = [[c, 0, s], [0, 1, 0], [-s, 0, c]], so x' = c x + s z and z' = -s x + c z."""
    return c * v[0] + s * v[1], -s * v[0] + c * v[1]


@kernel
def _kinematics(
    rocker: FloatArray,
    bogie: FloatArray,
    steer: FloatArray,
    offsets: FloatArray,
    half_track: float,
    steered: IntArray,
    centre: FloatArray,
    axle: FloatArray,
    link: FloatArray,
    dcentre: FloatArray,
    daxle: FloatArray,
) -> None:
    """``wheel_kinematics`` of ``n`` poses into ``centre``, ``axle`` (n, 6, 3), ``link``
    (n, 6) and the derivatives ``dcentre``, ``daxle`` (n, 6, 3, 3, zeroed by the caller).
    ``offsets`` (5, 2): the link vectors of ``RoverGeometry._offsets``."""
    p, f_off, b_off, m_off, r_off = offsets[0], offsets[1], offsets[2], offsets[3], offsets[4]
    for k in range(rocker.shape[0]):
        for side in range(2):
            rock_sign = 1.0 if side == 0 else -1.0
            rho = rock_sign * rocker[k]  # the differential: right rocker = -left rocker
            beta = bogie[k, side]
            fx, fz = _rot_xz(np.cos(rho), np.sin(rho), f_off)
            bx, bz = _rot_xz(np.cos(rho), np.sin(rho), b_off)
            mx, mz = _rot_xz(np.cos(rho + beta), np.sin(rho + beta), m_off)
            rx, rz = _rot_xz(np.cos(rho + beta), np.sin(rho + beta), r_off)
            y = -half_track if side == 0 else half_track
            i_f = 3 * side  # front, middle, rear: LF, LM, LR or RF, RM, RR
            centre[k, i_f, 0], centre[k, i_f, 1], centre[k, i_f, 2] = p[0] + fx, y, p[1] + fz
            centre[k, i_f + 1, 0] = p[0] + bx + mx
            centre[k, i_f + 1, 1] = y
            centre[k, i_f + 1, 2] = p[1] + bz + mz
            centre[k, i_f + 2, 0] = p[0] + bx + rx
            centre[k, i_f + 2, 1] = y
            centre[k, i_f + 2, 2] = p[1] + bz + rz
            link[k, i_f], link[k, i_f + 1], link[k, i_f + 2] = rho, rho + beta, rho + beta
            for i in range(i_f, i_f + 3):
                cx, cz = centre[k, i, 0], centre[k, i, 2]
                # d centre / d rocker: rotation of the whole side about the rocker pivot,
                # with the chain rule sign of the differential; the generator of Ry takes
                # (x, y, z) to (z, 0, -x).
                dcentre[k, i, 0, 0] = rock_sign * (cz - p[1])
                dcentre[k, i, 1, 0] = rock_sign * 0.0
                dcentre[k, i, 2, 0] = rock_sign * -(cx - p[0])
                if i != i_f:  # d centre / d bogie: about the bogie pivot
                    dcentre[k, i, 0, 1 + side] = cz - (p[1] + bz)
                    dcentre[k, i, 2, 1 + side] = -(cx - (p[0] + bx))
        # axle = Ry(link) Rz(sigma) ŷ, with Rz(sigma) ŷ = (-sin sigma, cos sigma, 0)
        for i in range(6):
            sigma = 0.0
            for j in range(4):
                if steered[j] == i:
                    sigma = steer[k, j]
            side = i // 3
            rock_sign = 1.0 if side == 0 else -1.0
            v = np.array([-np.sin(sigma), 0.0])
            ax_x, ax_z = _rot_xz(np.cos(link[k, i]), np.sin(link[k, i]), v)
            axle[k, i, 0], axle[k, i, 1], axle[k, i, 2] = ax_x, np.cos(sigma), ax_z
            # d axle / d link by the generator of Ry: (z, 0, -x)
            daxle[k, i, 0, 0] = rock_sign * ax_z
            daxle[k, i, 1, 0] = rock_sign * 0.0
            daxle[k, i, 2, 0] = rock_sign * -ax_x
            if i != 3 * side:
                daxle[k, i, 0, 1 + side] = ax_z
                daxle[k, i, 2, 1 + side] = -ax_x


MER_GEOMETRY = RoverGeometry()


@dataclass(frozen=True)
class BoxPart:
    """A box of the rover's shape: its centre and full extent along body x, y, z (m)."""

    name: str
    centre_b: tuple[float, float, float]
    size_m: tuple[float, float, float]


@dataclass(frozen=True)
class CylinderPart:
    """A cylinder of the rover's shape, its axis along body z: centre, radius, length (m)."""

    name: str
    centre_b: tuple[float, float, float]
    radius_m: float
    length_m: float


# The rover's shape above its wheels, body frame (x forward, y right, z down), in boxes and
# cylinders: approximate MER proportions, not flight drawings. The one table from which the
# 3D view draws the rover (server.scene3d.model) and the Navcam casts the rover's own shadow
# (sim.sensors.navcam.rover_shadow); the wheels come from ``RoverGeometry``.
#
# Below the deck the suspension's links (at zero joint angles, as the wheels), above it the
# mast head's cameras and the two small antennas: the details of the rover's own shadow
# (Cheng, Maimone and Matthies 2005 sec. 4.3: on sol 235 the shadow was the most textured
# thing in the Navcams' view). Axis-aligned bars for the slanted links.
ROVER_BOXES: tuple[BoxPart, ...] = (
    BoxPart("body", (0.05, 0.0, -0.175), (1.3, 0.9, 0.35)),  # warm electronics box
    BoxPart("deck", (0.0, 0.0, -0.37), (1.6, 1.9, 0.03)),  # solar-array deck
    BoxPart("pancam", (0.45, -0.30, -1.30), (0.12, 0.3, 0.1)),  # camera bar on the mast head
    BoxPart("navcam_left", (0.5, -0.42, -1.24), (0.08, 0.06, 0.06)),  # the Navcams below it
    BoxPart("navcam_right", (0.5, -0.18, -1.24), (0.08, 0.06, 0.06)),
    BoxPart("minites", (0.35, -0.30, -1.36), (0.16, 0.12, 0.10)),  # the mast head's back
    BoxPart("lga_tip", (-0.5, 0.6, -0.9), (0.08, 0.08, 0.08)),  # low-gain antenna's tip
    BoxPart("uhf_tip", (-0.6, -0.5, -0.75), (0.06, 0.06, 0.06)),  # UHF antenna's tip
    BoxPart("sundial", (0.2, 0.5, -0.5), (0.1, 0.1, 0.2)),  # the Pancam calibration target
    *(
        part
        for side, y in (("left", -0.6), ("right", 0.6))
        for part in (
            BoxPart(f"rocker_front_{side}", (0.40, y, 0.06), (0.60, 0.05, 0.05)),
            BoxPart(f"rocker_rear_{side}", (-0.12, y, -0.015), (0.46, 0.05, 0.05)),
            BoxPart(f"bogie_{side}", (-0.35, y, 0.10), (0.70, 0.05, 0.05)),
            BoxPart(f"strut_front_{side}", (0.70, y, 0.05), (0.04, 0.04, 0.20)),
            BoxPart(f"strut_middle_{side}", (0.0, y, 0.10), (0.04, 0.04, 0.12)),
            BoxPart(f"strut_rear_{side}", (-0.70, y, 0.10), (0.04, 0.04, 0.12)),
        )
    ),
)
ROVER_CYLINDERS: tuple[CylinderPart, ...] = (
    CylinderPart("mast", (0.45, -0.30, -0.82), 0.04, 0.9),  # stands along -z from the deck
    CylinderPart("hga", (-0.35, 0.45, -0.50), 0.14, 0.03),  # the high-gain antenna's dish
    CylinderPart("lga", (-0.5, 0.6, -0.62), 0.012, 0.52),  # low-gain antenna's mast
    CylinderPart("uhf", (-0.6, -0.5, -0.55), 0.012, 0.36),  # UHF antenna's mast
)
MAST_HEAD_B = ROVER_BOXES[2].centre_b  # the Pancam head, about 1.5 m above the ground
HGA_DISH_B = ROVER_CYLINDERS[1].centre_b
