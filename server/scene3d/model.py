"""What the 3D view draws of one frame: the rover model, its pose, the traverses and the
vectors (``server.scene3d.scene`` runs the viser server that shows them; the terrain is
``server.scene3d.terrain_mesh``'s).

The rover is the shape table of ``sim.rover.geometry`` (boxes and cylinders, the one the
Navcam's rover shadow uses too) with its six wheels placed on their rocker and bogie angles
and steered. Coordinates are the mission frame of the frames' ``p_mission_*`` (the first
Site: x North, y East, z Down, metres); attitudes are the frames' ``q_b_ll``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import viser
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from sim.rover.geometry import (
    HGA_DISH_B,
    MAST_HEAD_B,
    MER_GEOMETRY,
    ROVER_BOXES,
    ROVER_CYLINDERS,
    STEERED_INDEX,
    wheel_kinematics,
)

FloatArray = NDArray[np.float64]

TRACK_STEP_M = 0.05  # a traverse gets a new vertex after this much motion
TRACK_CHUNK = 200  # vertices per traverse node (10 m): a draw re-sends one chunk
ARROW_LENGTH_M = 2.0

TRUE_RGB = (230, 230, 225)
GHOST_RGB = (90, 170, 255)
SUN_RGB = (255, 205, 60)
EARTH_RGB = (80, 160, 255)
HGA_RGB = (90, 230, 120)
SIDE_RGB = (217, 140, 255)  # an estimator run beside SAPP (sim.loop.side.kinematic) ...
TRACK_RGB = {  # ... with its own colour where it has one (the timeline's too: web/timeline.js)
    "true": TRUE_RGB,
    "est": GHOST_RGB,
    "kinematic_ekf": (255, 140, 66),
    "radio_ekf": (230, 90, 200),
}
VECTORS = (  # the arrows: node name, the frame's unit vector (LL), where it starts, colour
    ("sun", "sun_ll_true", "head", SUN_RGB),
    ("earth", "earth_ll_true", "head", EARTH_RGB),
    ("hga", "hga_boresight_ll_true", "dish", HGA_RGB),
)
REPLAY_NODES = ("/rover", "/ghost", *(f"/{name}" for name, *_ in VECTORS))  # a viewer's own


def wxyz_from_q(q_xyzw: ArrayLike) -> tuple[float, float, float, float]:
    """viser's scalar-first ``wxyz`` from our scalar-last ``[x, y, z, w]`` (docs/CONVENTIONS.md:
    the one conversion, at the scene boundary).

    >>> wxyz_from_q([0.0, 0.0, 0.0, 1.0])
    (1.0, 0.0, 0.0, 0.0)
    """
    x, y, z, w = (float(v) for v in np.asarray(q_xyzw, dtype=float))
    return (w, x, y, z)


@dataclass(frozen=True)
class RoverPose:
    """What the scene needs of a frame for one rover model: the body origin in the mission
    frame, ``q_w_b`` (body to mission/LL, ``[x, y, z, w]``) and the suspension, rad."""

    p_w: FloatArray
    q_w_b: FloatArray
    rocker_rad: float
    bogie_rad: FloatArray
    steer_rad: FloatArray

    @staticmethod
    def from_frame(frame: Mapping[str, Any], which: str) -> RoverPose:
        """The ``"true"`` or ``"est"`` pose of a telemetry frame: the true pose on the true
        joint angles, the estimate on the angles the rover's encoders read (the downlink's)."""
        q_b_w = Rotation.from_quat(np.asarray(frame[f"q_b_ll_{which}"], dtype=float))
        joint = "{}_deg" if which == "true" else "{}_enc_deg"

        def angles(name: str, default: float | list[float]) -> FloatArray:
            value = frame.get(joint.format(name))
            value = default if value is None else value  # frames stored before encoders: 0
            radians: FloatArray = np.radians(np.asarray(value, dtype=float))
            return radians

        return RoverPose(
            p_w=np.asarray(frame[f"p_mission_{which}"], dtype=float),
            q_w_b=q_b_w.inv().as_quat(),
            rocker_rad=float(angles("rocker", 0.0)),
            bogie_rad=angles("bogie", [0.0, 0.0]),
            steer_rad=angles("steer", [0.0] * 4),
        )


def wheel_poses_b(pose: RoverPose) -> list[tuple[FloatArray, FloatArray]]:
    """Each wheel's ``(centre_b, q_b_wheel)``, WHEEL_NAMES order; the wheel's local z is its
    axle (viser's cylinders are along z), pitched with its link and steered.

    R_b_wheel = Ry(link) Rz(steer) Rx(-90°): Rx(-90°) takes z to y (the axle at rest),
    Rz steers it about Down, Ry pitches it with the rocker or bogie (``sim.rover.geometry``).
    """
    kin = wheel_kinematics(MER_GEOMETRY, pose.rocker_rad, pose.bogie_rad, pose.steer_rad)
    steer = np.zeros(6)
    steer[list(STEERED_INDEX)] = pose.steer_rad
    out = []
    for i in range(6):
        r = Rotation.from_euler("YZX", [kin.link_rad[i], steer[i], -math.pi / 2])
        out.append((kin.centre_b[i], r.as_quat()))
    return out


@dataclass
class Track:
    """A traverse as a polyline that grows by ``TRACK_STEP_M`` steps, kept in chunks of
    ``TRACK_CHUNK`` vertices so that a draw re-sends only the chunk still growing (a
    chunk's last vertex is the next one's first: the line stays joined)."""

    points: list[FloatArray] = field(default_factory=list)
    dirty: set[int] = field(default_factory=set)  # chunks changed since the last draw

    def add(self, p: ArrayLike) -> bool:
        """Append ``p`` if it is far enough from the last vertex; True when it was."""
        q = np.asarray(p, dtype=float)
        if self.points and float(np.linalg.norm(q - self.points[-1])) < TRACK_STEP_M:
            return False
        self.points.append(q)
        if len(self.points) > 1:
            self.dirty.add((len(self.points) - 2) // TRACK_CHUNK)
        return True

    def segments(self, chunk: int) -> FloatArray:
        """The (n, 2, 3) segments of ``chunk`` for ``add_line_segments``."""
        pts = np.asarray(self.points[chunk * TRACK_CHUNK : (chunk + 1) * TRACK_CHUNK + 1])
        return np.stack([pts[:-1], pts[1:]], axis=1)

    def take_dirty(self) -> dict[int, FloatArray]:
        """The segments of every chunk changed since the last call."""
        out = {c: self.segments(c) for c in sorted(self.dirty)}
        self.dirty.clear()
        return out


class RoverModel:
    """The rover drawn from boxes and cylinders under one scene node, wheels on joints: the
    shape table of ``sim.rover.geometry`` (``ROVER_BOXES``, ``ROVER_CYLINDERS``)."""

    def __init__(
        self, scene: viser.SceneApi, name: str, rgb: tuple[int, int, int], opacity: float | None
    ) -> None:
        g = MER_GEOMETRY
        self.root = scene.add_frame(name, show_axes=False)
        kw: dict[str, Any] = {"opacity": opacity, "cast_shadow": opacity is None}
        # the solid rover's deck is solar-cell blue; a translucent ghost is one colour
        colours = {"deck": (40, 55, 90) if opacity is None else rgb}
        boxes = {b.name: b for b in ROVER_BOXES}
        cylinders = {c.name: c for c in ROVER_CYLINDERS}
        # viser's cylinder axis is z, as the table's
        for part in ("body", "deck", "mast", "pancam", "hga"):  # the order they are added
            colour = colours.get(part, rgb)
            if part in boxes:
                box = boxes[part]
                scene.add_box(f"{name}/{part}", colour, box.size_m, position=box.centre_b, **kw)
            else:
                c = cylinders[part]
                scene.add_cylinder(
                    f"{name}/{part}", c.radius_m, c.length_m, colour, position=c.centre_b, **kw
                )
        self.wheels = [
            scene.add_cylinder(
                f"{name}/wheel_{i}", g.wheel_radius_m, g.wheel_width_m, (60, 60, 60), **kw
            )
            for i in range(6)
        ]

    def show(self, pose: RoverPose) -> None:
        self.root.position = tuple(pose.p_w)
        self.root.wxyz = wxyz_from_q(pose.q_w_b)
        for handle, (centre_b, q_b_wheel) in zip(self.wheels, wheel_poses_b(pose), strict=True):
            handle.position = tuple(centre_b)
            handle.wxyz = wxyz_from_q(q_b_wheel)


def _points_w(pose: RoverPose, p_b: Sequence[float]) -> FloatArray:
    return np.asarray(pose.p_w + Rotation.from_quat(pose.q_w_b).apply(np.asarray(p_b, float)))


def draw_vectors(scene: viser.SceneApi, frame: Mapping[str, Any], pose: RoverPose) -> None:
    """Sun and Earth from the mast head, the HGA boresight from the dish (truth, LL); a
    vector the frame lacks is hidden (a replaying viewer must not see the live one)."""
    start = {
        "head": _points_w(pose, MAST_HEAD_B),
        "dish": _points_w(pose, HGA_DISH_B),
    }
    for name, key, where, rgb in VECTORS:
        v = frame.get(key)
        end = start[where] + ARROW_LENGTH_M * np.asarray(v if v else [0.0, 0.0, 0.0], float)
        scene.add_arrows(
            f"/{name}",
            np.array([[start[where], end]]),
            rgb,
            shaft_radius=0.015,
            head_radius=0.05,
            visible=bool(v),
        )


def status_text(frame: Mapping[str, Any], live: bool, now_t_s: float | None = None) -> str:
    """The status line of a viewer: sol, LMST, live or replay, mode, AQF, and the position
    error where the frame carries the truth. Across light time (a frame with its
    ``received_t_s``) the rover's time is its data's, with when it came down; the truth view's
    truth is live (``truth_t_s``)."""
    h = float(frame["lmst_h"])
    clock = f"{int(h):02d}:{int(h * 60) % 60:02d}"
    mode = "live" if live else "replay"
    received = frame.get("received_t_s")
    if received is not None and now_t_s is not None:
        mode = f"data received {max(0.0, now_t_s - received) / 60.0:.0f} min ago"
    text = f"Sol {frame['sol']} {clock} LMST ({mode}) · {frame['nate_mode']} · AQF {frame['aqf']}"
    error = frame.get("position_error_m")
    if frame.get("truth_t_s") is not None:
        text += " · truth live"
    return text + (f" · position error {error:.2f} m" if error is not None else "")
