"""The 3D view's marks: the keep-out zones the rover reports, drawn on the ground in their
Site, and each halt at the estimated pose (and, in the truth view only, the true one)."""

from __future__ import annotations

from typing import Any

import numpy as np

from estimation.protection.keepout import KeepOutZone, zone_added_text, zones_cleared_text
from server.scene3d.marks import Marks
from server.validation.reported import HALT_PREFIX
from sim.world.sites import make_terrain


class Recorder:
    """Records the scene calls (the viser API's names) the marks make."""

    def __init__(self) -> None:
        self.nodes: dict[str, tuple[str, dict[str, Any]]] = {}

    def add_line_segments(self, name: str, points: Any, colors: Any, **kw: Any) -> None:
        self.nodes[name] = ("lines", {"points": np.asarray(points), **kw})

    def add_label(self, name: str, text: str, **kw: Any) -> None:
        self.nodes[name] = ("label", {"text": text, **kw})

    def add_icosphere(self, name: str, **kw: Any) -> None:
        self.nodes[name] = ("sphere", kw)

    def remove_by_name(self, name: str) -> None:
        for key in [k for k in self.nodes if k == name or k.startswith(name + "/")]:
            del self.nodes[key]


def _frame(events: list[dict[str, str]], **extra: Any) -> dict[str, Any]:
    return {"events": events, "p_mission_est": [1.0, 2.0, 0.0], **extra}


def test_a_zone_is_drawn_in_its_site_on_the_ground_and_cleared() -> None:
    terrain = make_terrain("gusev", 3)
    marks = Marks(terrain, np.zeros(3), truth=False)
    zone = KeepOutZone.circle("rock", 1, 2.0, -1.0, 0.5)
    marks.take(_frame([{"kind": "keepout", "text": zone_added_text(zone)}]))
    scene = Recorder()
    marks.draw(scene, {0: np.zeros(3), 1: np.array([10.0, 5.0, 0.0])})  # type: ignore[arg-type]
    kind, drawn = scene.nodes["/keepout/rock"]
    points = drawn["points"].reshape(-1, 3)
    radius = np.hypot(points[:, 0] - 12.0, points[:, 1] - 4.0)  # Site 1's origin + centre
    assert kind == "lines" and np.allclose(radius, 0.5)
    heights = -np.asarray(terrain.height_m(points[:, 0], points[:, 1]))
    assert np.all(points[:, 2] < heights)  # above the ground (z down)
    marks.take(_frame([{"kind": "keepout", "text": zones_cleared_text(["rock"])}]))
    marks.draw(scene, {0: np.zeros(3), 1: np.array([10.0, 5.0, 0.0])})  # type: ignore[arg-type]
    assert not any(k.startswith("/keepout") for k in scene.nodes)


def test_a_halt_is_marked_at_the_estimate_and_at_the_truth_only_in_the_truth_view() -> None:
    halt = {"kind": "mobility", "text": HALT_PREFIX + "slip check: slip 44.5 % > 40 %"}
    for truth in (False, True):
        marks = Marks(make_terrain("flat", 0), np.zeros(3), truth=truth)
        marks.take(_frame([halt], p_mission_true=[1.5, 2.5, 0.0]))
        scene = Recorder()
        marks.draw(scene, {0: np.zeros(3)})  # type: ignore[arg-type]
        assert scene.nodes["/halts/0_est"][1]["position"] == (1.0, 2.0, 0.0)
        assert ("/halts/0_true" in scene.nodes) is truth
        assert "slip check" in scene.nodes["/halts/0_est/label"][1]["text"]
