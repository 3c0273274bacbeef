"""The 3D view's marks of mobility fault protection: the keep-out zones the rover reports
holding, drawn on the ground, and where each halt happened.

Both come from the rover's own events in the frames (``estimation.protection.keepout``'s
texts, the ``mobility`` halt events), as the ground learns them: a zone is drawn in its Site
(the Site's origin as the flight software planted it), a halt at the estimated pose of the
frame that reports it for everyone, and in the truth view also at the true pose.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import viser
from numpy.typing import NDArray

from estimation.protection.keepout import KeepOutZone, apply_reported
from server.validation.reported import HALT_PREFIX
from sim.world.terrain import Terrain

FloatArray = NDArray[np.float64]

ZONE_RGB = (255, 80, 60)
HALT_RGB = {"est": (255, 60, 60), "true": (255, 170, 40)}
CIRCLE_POINTS = 48
ABOVE_GROUND_M = 0.03  # drawn this far above the ground, so the terrain does not hide it


@dataclass
class Halt:
    """A halt as drawn: its text and where (mission frame) by the estimate and the truth."""

    text: str
    p_est: FloatArray
    p_true: FloatArray | None


@dataclass
class Marks:
    """The zones and halts seen so far (``take`` each frame; ``draw`` what changed)."""

    terrain: Terrain
    origin_world: FloatArray
    truth: bool
    zones: dict[str, KeepOutZone] = field(default_factory=dict)
    halts: list[Halt] = field(default_factory=list)
    _drawn_zones: set[str] = field(default_factory=set)
    _drawn_halts: int = 0
    _zones_dirty: bool = False

    def take(self, frame: Mapping[str, Any]) -> None:
        for event in frame.get("events") or ():
            kind, text = event.get("kind"), str(event.get("text", ""))
            if kind == "keepout":
                apply_reported(self.zones, text)
                self._zones_dirty = True
            elif kind == "mobility" and text.startswith(HALT_PREFIX):
                true = frame.get("p_mission_true") if self.truth else None
                self.halts.append(
                    Halt(
                        text.removeprefix(HALT_PREFIX),
                        np.asarray(frame["p_mission_est"], dtype=float),
                        None if true is None else np.asarray(true, dtype=float),
                    )
                )

    def draw(self, scene: viser.SceneApi, site_origins: Mapping[int, FloatArray]) -> None:
        """Draw what changed since the last call (``site_origins``: mission frame)."""
        if self._zones_dirty:
            for name in self._drawn_zones - set(self.zones):
                scene.remove_by_name(f"/keepout/{name}")
            drawn = set()
            for name, zone in self.zones.items():
                origin = site_origins.get(zone.site_index)
                if origin is None:
                    continue  # its Site not seen yet: drawn when it is
                scene.add_line_segments(
                    f"/keepout/{name}", self._outline(zone, origin), ZONE_RGB, thickness=0.04
                )
                scene.add_label(
                    f"/keepout/{name}/label",
                    f"keep-out {name}",
                    position=self._label_at(zone, origin),
                )
                drawn.add(name)
            self._drawn_zones = drawn
            self._zones_dirty = len(drawn) != len(self.zones)
        for k in range(self._drawn_halts, len(self.halts)):
            halt = self.halts[k]
            where = [("est", halt.p_est)] + (
                [("true", halt.p_true)] if halt.p_true is not None else []
            )
            for which, p in where:
                scene.add_icosphere(
                    f"/halts/{k}_{which}", radius=0.12, color=HALT_RGB[which], position=tuple(p)
                )
            scene.add_label(
                f"/halts/{k}_est/label", f"halt: {halt.text[:60]}", position=(0.0, 0.0, -0.4)
            )
        self._drawn_halts = len(self.halts)

    def _ground_d(self, x_m: FloatArray, y_m: FloatArray) -> FloatArray:
        """The ground's Down coordinate (mission frame) under mission ``x_m``, ``y_m``."""
        o = self.origin_world
        h = np.asarray(self.terrain.height_m(x_m + o[0], y_m + o[1]), dtype=float)
        out: FloatArray = -h - o[2] - ABOVE_GROUND_M
        return out

    def _outline(self, zone: KeepOutZone, origin: FloatArray) -> FloatArray:
        """The zone's outline as (n, 2, 3) segments in the mission frame."""
        if zone.is_circle:
            a = np.linspace(0.0, 2.0 * math.pi, CIRCLE_POINTS + 1)
            cx, cy = zone.centre_s
            xy = np.stack([cx + zone.radius_m * np.cos(a), cy + zone.radius_m * np.sin(a)], 1)
        else:
            corners = np.asarray(zone.vertices_s, dtype=float)
            xy = np.vstack([corners, corners[:1]])
        x, y = xy[:, 0] + origin[0], xy[:, 1] + origin[1]
        points = np.stack([x, y, self._ground_d(x, y)], axis=1)
        out: FloatArray = np.stack([points[:-1], points[1:]], axis=1)
        return out

    def _label_at(self, zone: KeepOutZone, origin: FloatArray) -> tuple[float, float, float]:
        x, y = zone.centre_s if zone.is_circle else np.mean(zone.vertices_s, axis=0)
        x, y = float(x) + float(origin[0]), float(y) + float(origin[1])
        d = float(self._ground_d(np.array([x]), np.array([y]))[0])
        return (x, y, d - 0.3)
