"""The rover's own shadow, predicted on board: which VO features lie in it (or at its edge).

Cheng, Maimone and Matthies 2005, sec. 4.3: on Opportunity's sol 235 the Navcams looked at
two small rocks in featureless terrain, and "many more features were found on the largest
shape in the image: the rover's shadow", which moves with the rover; VO took the shadow's
motion (none) for the ground's and made a false update. Since then the drivers "had to take
the rover shadow into account". The flight software knows everything needed to take it into
account itself: the Sun's direction (SAPP's attitude and its ephemeris, IVP), the rover's
shape (its flight copy, ``estimation.geometry``) and, for each stereo feature, its 3D point
in the body frame. A ground point is in the rover's shadow when the ray from it towards the
Sun meets a part of the rover; a feature near the shadow's edge (where the shadow's
corners are, the textured part of the shadow) is one whose ray passes within
``margin_m`` of a part. ``in_rover_shadow`` tests each point's ray against the parts (boxes
by the slab test, cylinders exactly), each part grown by the margin; the VO front drops the
features it flags before tracking (``estimation.vo.odometry``, the ``sun_b`` keyword).

Frames (docs/CONVENTIONS.md): body ``b`` x forward, y right, z down; ``sun_b`` the unit
vector towards the Sun in ``b``. Flight software: numpy only.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimation.geometry import FLIGHT_GEOMETRY, ROVER_BOXES_B, ROVER_CYLINDERS_B, FlightGeometry

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

SHADOW_MARGIN_M = 0.10  # a feature within this of the shadow's edge is dropped too
_EPS = 1e-12


def rover_boxes_b() -> FloatArray:
    """The rover's boxes (n, 6): centre (x, y, z) and half sizes, body frame, m."""
    return _BOXES_B.copy()


_BOXES_B = np.array([[*c, *(0.5 * s for s in size)] for _, c, size in ROVER_BOXES_B])


def rover_cylinders_b(geometry: FlightGeometry = FLIGHT_GEOMETRY) -> FloatArray:
    """The rover's cylinders (m, 8): centre, unit axis, radius, half length; the mast and
    the HGA (axes along body z) and the six wheels at zero suspension angles (axes along
    body y)."""
    parts = [[*c, 0.0, 0.0, 1.0, r, 0.5 * length] for _, c, r, length in ROVER_CYLINDERS_B]
    g = geometry
    for x_m, y_m in g.wheel_xy_b():
        parts.append([x_m, y_m, g.wheel_centre_z_m, 0.0, 1.0, 0.0, g.wheel_radius_m,
                      0.5 * g.wheel_width_m])  # fmt: skip
    return np.array(parts)


def _check(points_b: ArrayLike, sun_b: ArrayLike, margin_m: float) -> tuple[FloatArray, FloatArray]:
    p = np.asarray(points_b, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3 or not np.all(np.isfinite(p)):
        raise ValueError(f"points_b: must be a finite (N, 3) array, got shape {p.shape}")
    s = np.asarray(sun_b, dtype=np.float64)
    if s.shape != (3,) or not np.all(np.isfinite(s)) or abs(float(np.linalg.norm(s)) - 1.0) > 1e-6:
        raise ValueError(f"sun_b: must be a unit 3-vector, got {sun_b!r}")
    if not (np.isfinite(margin_m) and margin_m >= 0.0):
        raise ValueError(f"margin_m: must be finite and non-negative, got {margin_m!r}")
    return p, s


def _hits_boxes(p: FloatArray, s: FloatArray, t_max: FloatArray, boxes: FloatArray,
                margin_m: float) -> BoolArray:  # fmt: skip
    """Whether each ray ``p + t s`` (0 < t <= t_max; ``s`` (N, 3)) enters a box grown by
    ``margin_m`` (the slab test, every box at once)."""
    safe = np.where(np.abs(s) < _EPS, _EPS, s)[:, None, :]  # (N, 1, 3)
    lo = (boxes[:, :3] - boxes[:, 3:] - margin_m)[None]  # (1, n, 3)
    hi = (boxes[:, :3] + boxes[:, 3:] + margin_m)[None]
    t1 = (lo - p[:, None, :]) / safe
    t2 = (hi - p[:, None, :]) / safe
    t_near = np.maximum(np.minimum(t1, t2).max(axis=2), 0.0)  # (N, n)
    t_far = np.minimum(np.maximum(t1, t2).min(axis=2), t_max[:, None])
    out: BoolArray = np.any((t_far >= t_near) & (t_far > 0.0), axis=1)
    return out


def _hits_cylinders(p: FloatArray, s: FloatArray, t_max: FloatArray, cyls: FloatArray,
                    margin_m: float) -> BoolArray:  # fmt: skip
    """Whether each ray ``p + t s`` (0 < t <= t_max) meets a finite cylinder grown by
    ``margin_m``: the ray's interval inside the infinite cylinder (a quadratic in ``t``)
    intersected with its interval between the end planes (every cylinder at once)."""
    centre, axis = cyls[:, :3], cyls[:, 3:6]  # (n, 3)
    radius, half = cyls[:, 6] + margin_m, cyls[:, 7] + margin_m  # (n,)
    d = p[:, None, :] - centre[None]  # (N, n, 3)
    d_ax = np.einsum("knj,nj->kn", d, axis)
    s_ax = s @ axis.T  # (N, n)
    d_perp = d - d_ax[..., None] * axis[None]
    s_perp = s[:, None, :] - s_ax[..., None] * axis[None]
    a = np.einsum("knj,knj->kn", s_perp, s_perp)
    b = 2.0 * np.einsum("knj,knj->kn", d_perp, s_perp)
    cc = np.einsum("knj,knj->kn", d_perp, d_perp) - radius**2
    along = a < _EPS  # a ray along the axis: inside the radius or not
    a_safe = np.where(along, 1.0, a)
    disc = b * b - 4.0 * a_safe * cc
    root = np.sqrt(np.maximum(disc, 0.0))
    t_in = np.where(disc >= 0.0, (-b - root) / (2.0 * a_safe), np.inf)
    t_out = np.where(disc >= 0.0, (-b + root) / (2.0 * a_safe), -np.inf)
    t_in = np.where(along, np.where(cc <= 0.0, -np.inf, np.inf), t_in)
    t_out = np.where(along, np.where(cc <= 0.0, np.inf, -np.inf), t_out)
    flat = np.abs(s_ax) < _EPS  # a ray across the axis: between the end planes or not
    s_safe = np.where(flat, 1.0, s_ax)
    ta, tb = (-half - d_ax) / s_safe, (half - d_ax) / s_safe
    inside = np.abs(d_ax) <= half
    s_in = np.where(flat, np.where(inside, -np.inf, np.inf), np.minimum(ta, tb))
    s_out = np.where(flat, np.where(inside, np.inf, -np.inf), np.maximum(ta, tb))
    lo = np.maximum(np.maximum(t_in, s_in), 0.0)
    hi = np.minimum(np.minimum(t_out, s_out), t_max[:, None])
    out: BoolArray = np.any((hi >= lo) & (hi > 0.0), axis=1)
    return out


def rays_meet_rover(
    points_b: ArrayLike,
    dirs_b: ArrayLike,
    t_max: ArrayLike | None = None,
    margin_m: float = 0.0,
    geometry: FlightGeometry = FLIGHT_GEOMETRY,
) -> BoolArray:
    """Whether each ray from ``points_b`` (N, 3) along the unit ``dirs_b`` (N, 3), body
    frame, meets a rover part grown by ``margin_m`` within ``t_max`` (N,) metres
    (default: unbounded). (N,) bool. The ground advisor asks it whether the rover hides
    a ground point from the Navcam (the ray from the point to the eye)."""
    p = np.asarray(points_b, dtype=np.float64).reshape(-1, 3)
    s = np.asarray(dirs_b, dtype=np.float64).reshape(-1, 3)
    if s.shape != p.shape:
        raise ValueError(f"dirs_b: must match points_b's shape {p.shape}, got {s.shape}")
    t = np.full(len(p), np.inf) if t_max is None else np.broadcast_to(
        np.asarray(t_max, dtype=np.float64), (len(p),))  # fmt: skip
    if len(p) == 0:
        return np.zeros(0, dtype=bool)
    return _hits_boxes(p, s, t, _BOXES_B, margin_m) | _hits_cylinders(
        p, s, t, rover_cylinders_b(geometry), margin_m
    )


def in_rover_shadow(
    points_b: ArrayLike,
    sun_b: ArrayLike,
    margin_m: float = 0.0,
    geometry: FlightGeometry = FLIGHT_GEOMETRY,
) -> BoolArray:
    """Whether each point (N, 3), body frame (m), is in the rover's shadow for the Sun along
    the unit ``sun_b``: its ray towards the Sun meets a rover part grown by ``margin_m``
    (module docstring). (N,) bool.

    >>> sun = np.array([-0.6, 0.0, -0.8])  # behind the rover and high
    >>> in_rover_shadow([[1.2, 0.0, 0.3], [4.0, 3.0, 0.3]], sun).tolist()
    [True, False]
    """
    p, s = _check(points_b, sun_b, margin_m)
    return rays_meet_rover(p, np.broadcast_to(s, p.shape), None, margin_m, geometry)
