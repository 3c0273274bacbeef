"""The rover as a shadow caster for the Navcam: its boxes and cylinders as arrays.

``sim.sensors.navcam.trace.render_eyes`` tests a ray towards the Sun against the rover's
parts, body frame (x forward, y right, z down): the boxes and cylinders of the one shape
table (``sim.rover.geometry.ROVER_BOXES``, ``ROVER_CYLINDERS``) and the six wheels at zero
suspension angles, inside a bounding sphere that most rays miss.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from sim.rover.geometry import MER_GEOMETRY, ROVER_BOXES, ROVER_CYLINDERS

FloatArray = NDArray[np.float64]

# centre (x, y, z), half sizes
ROVER_BOXES_B = np.array([[*b.centre_b, *(0.5 * s for s in b.size_m)] for b in ROVER_BOXES])


def _rover_cylinders_b() -> FloatArray:
    """Mast, high-gain antenna and the six wheels: centre, unit axis, radius, half length."""
    g = MER_GEOMETRY
    parts = [[*c.centre_b, 0.0, 0.0, 1.0, c.radius_m, 0.5 * c.length_m] for c in ROVER_CYLINDERS]
    for x_m, y_m in g.wheel_xy_b():  # wheels at zero suspension angles
        parts.append(
            [x_m, y_m, g.wheel_centre_z_m, 0.0, 1.0, 0.0, g.wheel_radius_m, 0.5 * g.wheel_width_m]
        )
    return np.array(parts)


ROVER_CYLINDERS_B = _rover_cylinders_b()


def _rover_bound_b() -> FloatArray:
    """A sphere (centre, radius) holding every rover part: box corners, cylinder ends
    widened by their radius."""
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    corners = (ROVER_BOXES_B[:, None, :3] + signs[None] * ROVER_BOXES_B[:, None, 3:]).reshape(-1, 3)
    c = ROVER_CYLINDERS_B
    ends = np.vstack([c[:, :3] + c[:, 7:8] * c[:, 3:6], c[:, :3] - c[:, 7:8] * c[:, 3:6]])
    centre = 0.5 * (np.vstack([corners, ends]).min(axis=0) + np.vstack([corners, ends]).max(axis=0))
    radius = max(
        float(np.linalg.norm(corners - centre, axis=1).max()),
        float((np.linalg.norm(ends - centre, axis=1) + np.tile(c[:, 6], 2)).max()),
    )
    return np.array([*centre, radius])


ROVER_BOUND_B = _rover_bound_b()


@dataclass(frozen=True)
class RoverShadow:
    """The rover's pose for its own shadow (parts: ``ROVER_BOXES_B`` etc.)."""

    p_s: FloatArray
    R_s_b: FloatArray
