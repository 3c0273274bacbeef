"""A rehearsal in the 3D view (``server.scene3d.rehearsal``): the ellipses drawn where the
Gaussian fit puts them (their outline holds the share of samples its probability says, for
an ellipse computed here from the covariance independently), the cloud's ribbons on the
ground's map, and a real scene drawing a risk table for a viewer speaking viser's wire
protocol, told "rehearsal #N: R runs" (a viewer that connects later too)."""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

from server.app import data_dir_url
from server.runtime import ROVERS, RoverRuntime
from server.scene3d.rehearsal import (
    ABOVE_GROUND_M,
    NODE,
    ellipse_ne,
    on_ground,
    rehearsal_note,
    ribbon,
    show,
    view_of,
)
from server.scene3d.scene import RoverScene
from server.storage import Store
from tests.viser_wire import WireViewer, wait_for


def _inside(points: Any, polygon: Any) -> Any:
    """Ray casting: which of ``points`` (m, 2) lie inside the closed ``polygon`` (n + 1, 2)."""
    x, y = points[:, 0][:, None], points[:, 1][:, None]
    x0, y0 = polygon[:-1, 0][None, :], polygon[:-1, 1][None, :]
    x1, y1 = polygon[1:, 0][None, :], polygon[1:, 1][None, :]
    crosses = ((y0 > y) != (y1 > y)) & (x < x0 + (y - y0) * (x1 - x0) / (y1 - y0 + 1e-300))
    return np.count_nonzero(crosses, axis=1) % 2 == 1


def _fit(cov: Any, p: float) -> tuple[float, float, float]:
    """Semi-axes and the major axis' bearing (deg from North towards East) of the p ellipse
    of a 2-D Gaussian: eigen-decomposition, k^2 = -2 ln(1 - p) (chi-square, 2 dof)."""
    values, vectors = np.linalg.eigh(cov)
    k = math.sqrt(-2.0 * math.log(1.0 - p))
    major = vectors[:, 1]
    return (
        k * math.sqrt(values[1]),
        k * math.sqrt(values[0]),
        math.degrees(math.atan2(major[1], major[0])) % 180.0,  # an axis: [0, 180)
    )


def test_an_ellipse_outline_lies_on_its_equation_with_the_major_axis_at_its_bearing() -> None:
    mean = np.array([3.0, -1.0])
    ne = ellipse_ne(mean, 0.5, 0.2, 90.0)  # the major axis along East
    assert np.allclose(ne[0], ne[-1])  # closed
    d = ne - mean
    assert np.allclose((d[:, 1] / 0.5) ** 2 + (d[:, 0] / 0.2) ** 2, 1.0)
    assert np.ptp(ne[:, 1]) == pytest.approx(1.0, abs=1e-9) and np.ptp(ne[:, 0]) == pytest.approx(
        0.4, rel=1e-3
    )
    with pytest.raises(ValueError, match="semi-axes"):
        ellipse_ne(mean, -1.0, 0.2, 0.0)


@pytest.mark.parametrize("p", [0.5, 0.95])
def test_the_drawn_ellipse_holds_its_share_of_gaussian_samples(p: float) -> None:
    rng = np.random.default_rng(25)
    cov = np.array([[0.09, 0.05], [0.05, 0.04]])  # tilted: the major axis between N and E
    mean = np.array([2.0, 0.5])
    samples = rng.multivariate_normal(mean, cov, size=40_000)
    a, b, angle = _fit(cov, p)
    assert 0.0 < angle < 90.0
    share = float(np.mean(_inside(samples, ellipse_ne(mean, a, b, angle, n=256))))
    assert share == pytest.approx(p, abs=0.01)  # 40 000 samples: sigma 0.0025
    # the bearing mirrored would miss: the convention is checked, not just the size
    mirrored = float(np.mean(_inside(samples, ellipse_ne(mean, a, b, -angle, n=256))))
    assert mirrored < p - 0.05


class _Flat:
    """A ground map's height_at of a plane rising 0.1 m per m North (what ribbon reads)."""

    def height_at(self, north_m: Any, east_m: Any) -> Any:
        return 0.1 * np.asarray(north_m, dtype=float) + 0.0 * np.asarray(east_m, dtype=float)


def test_the_cloud_is_ribbons_of_its_width_on_the_ground() -> None:
    ground: Any = _Flat()
    paths = [[[0.0, 0.0], [1.0, 0.0], [1.0, 0.0], [1.0, 2.0]], [[0.0, 0.0]]]  # a repeat, a point
    vertices, faces = ribbon(ground, paths, width_m=0.04)
    assert vertices.shape == (8, 3) and faces.shape == (
        4,
        3,
    )  # two segments: 4 vertices, 2 faces each
    quads = vertices.reshape(-1, 4, 3)
    for quad in quads:
        assert np.linalg.norm(quad[1, :2] - quad[0, :2]) == pytest.approx(0.04)
    np.testing.assert_allclose(vertices[:, 2], -0.1 * vertices[:, 0] - ABOVE_GROUND_M)
    assert faces.max() == 7 and faces.dtype == np.int32
    empty_v, empty_f = ribbon(ground, [])
    assert empty_v.shape == (0, 3) and empty_f.shape == (0, 3)
    np.testing.assert_allclose(
        on_ground(ground, np.array([[2.0, 5.0]])), [[2.0, 5.0, -0.2 - ABOVE_GROUND_M]]
    )


def _risk(runs: int) -> dict[str, Any]:
    ellipse = {"a_m": 0.3, "b_m": 0.1, "angle_deg": 10.0}
    fit = {
        "mean_m": [2.0, 0.1],
        "cov_m2": [[0.01, 0.0], [0.0, 0.002]],
        "ellipse_50": ellipse,
        "ellipse_95": ellipse,
    }
    lines = [
        {"line": 2, "verdict": "ok", "end_true": fit},
        {"line": 3, "verdict": "risk", "end_true": None},  # never ran: no ellipse
    ]
    paths = [[[0.0, 0.0], [1.0, 0.01 * k], [2.0, 0.02 * k]] for k in range(runs)]
    return {"runs": runs, "lines": lines, "paths": paths}


@pytest.fixture(scope="module")
def scene(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RoverScene]:
    store = Store(data_dir_url(tmp_path_factory.mktemp("rehearsal_scene")))
    rover_scene = RoverScene(RoverRuntime(ROVERS["spirit"]), store, truth=False)
    rover_scene.start()
    try:
        yield rover_scene
    finally:
        rover_scene.stop()
        store.close()


def _notes(viewer: WireViewer) -> list[str]:
    with viewer._lock:
        return [s["_markdown"] for s in viewer.gui.values() if "_markdown" in s]


def test_a_scene_draws_the_cloud_and_ellipses_and_tells_its_viewers(scene: RoverScene) -> None:
    assert view_of(scene).state() is None
    first = WireViewer(f"ws://127.0.0.1:{scene.port}")
    try:
        wait_for(lambda: any("Terrain" in n for n in _notes(first)))
        show([scene, None], 7, _risk(8))
        assert view_of(scene).state() == {
            "id": 7, "runs": 8, "paths": 8, "ellipses": 1, "note": "rehearsal #7: 8 runs",
        }  # fmt: skip
        assert scene.server is not None
        nodes = scene.server.scene._handle_from_node_name
        for name in ("cloud", "line_2/ellipse_50", "line_2/ellipse_95", "line_2/label"):
            assert f"{NODE}/{name}" in nodes, name
        assert not any(n.startswith(f"{NODE}/line_3") for n in nodes)
        wait_for(lambda: "rehearsal #7: 8 runs" in _notes(first))
        wait_for(lambda: ("", f"{NODE}/cloud") in first.nodes)
        later = WireViewer(f"ws://127.0.0.1:{scene.port}")  # connects after: told too
        try:
            wait_for(lambda: "rehearsal #7: 8 runs" in _notes(later))
            show([scene], 8, _risk(1))  # another campaign in its place, the note says so
            wait_for(
                lambda: (
                    "rehearsal #8: 1 run" in _notes(later)
                    and "rehearsal #8: 1 run" in _notes(first)
                )
            )
            assert sum("rehearsal #" in n for n in _notes(later)) == 1
        finally:
            later.close()
        view_of(scene).clear()
        assert view_of(scene).state() is None and f"{NODE}/cloud" not in nodes
        wait_for(lambda: rehearsal_note(None) in _notes(first))
    finally:
        first.close()
