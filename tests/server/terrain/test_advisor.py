"""The pointing advisor (server.terrain.advisor) on hand-made maps: it points at texture and
away from the rover's shadow, a mirrored scene mirrors its advice, its predictions obey
their own definitions, and it reads nothing of the simulator."""

from __future__ import annotations

import math

import numpy as np
import pytest

from server.terrain.advisor import AdviceParams, PlannedDrive, advise, body_poses
from server.terrain.ground_map import GroundMap
from tests.test_layout import ROOT, import_graph

CELL_M = 0.25
HALF_M = 12.0
DENSE, PLAIN = 30.0, 3.0  # features per m²: a textured patch, the sparser ground around it
NORTH = np.array([0.0, 0.0, 0.0, 1.0])  # q_b_m: heading North, level
P0_M = np.array([0.0, 0.0, -0.30])
DRIVE = PlannedDrive("straight", distance_m=3.0)
# a coarser grid than the default, for speed: the rule is the same
PARAMS = AdviceParams(
    az_deg=(-90.0, -45.0, 0.0, 45.0, 90.0), el_deg=(-35.0, -45.0), rays_per_side=12
)


def _map(texture_of: object) -> GroundMap:
    n = int(2 * HALF_M / CELL_M) + 1
    axis = -HALF_M + CELL_M * np.arange(n)
    north, east = np.meshgrid(axis, axis, indexing="ij")
    texture = np.asarray(texture_of(north, east), dtype=np.float64)  # type: ignore[operator]
    return GroundMap(-HALF_M, -HALF_M, CELL_M, np.zeros((n, n)), np.full((n, n), 0.05),
                     np.full((n, n), 0.13), texture, np.isfinite(texture))  # fmt: skip


def _sun(az_deg: float, el_deg: float) -> np.ndarray:
    az, el = math.radians(az_deg), math.radians(el_deg)
    return np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), -math.sin(el)])


def _patch(side: float) -> object:
    """A textured patch 1.5-4 m to one side (``side`` +1 East, the rover's right; -1 West)."""
    return lambda n, e: np.where((side * e > 1.5) & (side * e < 4.0), DENSE, PLAIN)


HIGH_SUN = _sun(0.0, 89.0)  # overhead: the shadow under the rover


def test_it_points_at_the_textured_patch_and_a_mirrored_patch_mirrors_it() -> None:
    for side in (+1.0, -1.0):
        advice = advise(_map(_patch(side)), P0_M, NORTH, DRIVE, HIGH_SUN, PARAMS)
        best = advice.recommended
        assert best is not None
        assert 45.0 <= side * best.az_deg <= 90.0  # looking at the patch
        # the patch is why: the best pointing to the other side predicts far fewer features
        other = max(c.features_min for c in advice.candidates if side * c.az_deg < 0.0)
        assert other < 0.5 * best.features_min


def test_it_points_at_the_patch_away_from_the_shadow_on_the_other_side() -> None:
    # the Sun low in the East: the rover's shadow falls to the West, on its left
    sun = _sun(90.0, 25.0)
    advice = advise(_map(_patch(+1.0)), P0_M, NORTH, DRIVE, sun, PARAMS)
    best = advice.recommended
    assert best is not None and best.az_deg > 0.0 and best.shadow_max <= PARAMS.max_shadow_fraction
    by_pointing = {(c.az_deg, c.el_deg): c for c in advice.candidates}
    assert by_pointing[(-90.0, -35.0)].shadow_max > PARAMS.max_shadow_fraction  # looking at it
    # with the patch on the shadow's side, it still keeps out of the shadow
    shaded = advise(_map(_patch(-1.0)), P0_M, NORTH, DRIVE, sun, PARAMS).recommended
    assert shaded is not None and shaded.shadow_max <= PARAMS.max_shadow_fraction


def test_the_rule_and_the_predictions() -> None:
    advice = advise(
        _map(lambda n, e: np.full(n.shape, PLAIN)), P0_M, NORTH, DRIVE, HIGH_SUN, PARAMS
    )
    assert advice.pairs == 5  # 3 m in MER's 0.75 m steps
    for c in advice.candidates:
        assert len(c.features) == len(c.overlap) == 4
        assert c.ok == (c.overlap_min >= 0.6 and c.shadow_max <= PARAMS.max_shadow_fraction)
        assert all(0.0 <= x <= 1.0 for x in c.overlap + c.shadow + c.featureless)
    best = advice.recommended
    assert best is not None
    assert best.features_min == max(c.features_min for c in advice.candidates if c.ok)
    ahead = {(c.az_deg, c.el_deg): c for c in advice.candidates}[(0.0, -35.0)]
    # looking along the motion the ground ahead grows in the image step after step: fewer
    # trackable features than looking across it
    assert ahead.features_min < best.features_min
    # featureless sand everywhere: nothing trackable, whatever the pointing
    sand = advise(_map(lambda n, e: np.zeros(n.shape)), P0_M, NORTH, DRIVE, HIGH_SUN, PARAMS)
    assert all(c.features_min == 0.0 and c.featureless_max == 1.0 for c in sand.candidates)


def test_the_poses_follow_the_drive_and_the_maps_slope() -> None:
    tilted = _map(lambda n, e: np.full(n.shape, PLAIN))
    rise = 0.1  # the ground rises 10 cm per metre towards North
    slope = GroundMap(tilted.north0_m, tilted.east0_m, CELL_M,
                      rise * (tilted.north0_m + CELL_M * np.arange(tilted.shape[0]))[:, None]
                      * np.ones(tilted.shape), tilted.sigma_m, tilted.albedo, tilted.texture,
                      tilted.imaged)  # fmt: skip
    positions, rotations = body_poses(slope, P0_M, 0.0, DRIVE)
    assert np.allclose(positions[:, 0], np.linspace(0.0, 3.0, 5))
    nose_b = np.array([1.0, 0.0, 0.0])
    for R in rotations:  # nose up by atan(0.1): its Down component negative
        assert (R @ nose_b)[2] == pytest.approx(-math.sin(math.atan(rise)), abs=1e-9)
    arc = PlannedDrive("arc", radius_m=2.0, angle_deg=90.0)
    offsets, yaws = arc.step_headings(0.0)
    assert offsets[-1] == pytest.approx([2.0, 2.0])  # a quarter turn right about (0, 2)
    assert yaws[-1] == pytest.approx(math.pi / 2)


def test_bad_input_is_refused() -> None:
    gmap = _map(lambda n, e: np.full(n.shape, PLAIN))
    with pytest.raises(ValueError, match="sun_m"):
        advise(gmap, P0_M, NORTH, DRIVE, _sun(0.0, -5.0), PARAMS)
    with pytest.raises(ValueError, match="q_b_m"):
        advise(gmap, P0_M, [0.0, 0.0, 0.0, 2.0], DRIVE, HIGH_SUN, PARAMS)
    with pytest.raises(ValueError, match="kind"):
        PlannedDrive("hop", distance_m=1.0)
    with pytest.raises(ValueError, match="distance_m"):
        PlannedDrive("straight", distance_m=0.0)
    with pytest.raises(ValueError, match="el_deg"):
        AdviceParams(el_deg=(10.0,))


def test_the_advisor_imports_nothing_of_the_simulator() -> None:
    """The advice is computed from the ground's map and the flight software's models alone:
    nothing the advisor imports, directly or not, is the simulator's but its input errors
    (the route module's own imports are the ground's, tests/test_truth_layout.py)."""
    graph = import_graph(ROOT, ("server", "sim", "estimation", "sequences"))
    seen, todo = set(), ["server.terrain.advisor"]
    while todo:
        m = todo.pop()
        if m not in seen:
            seen.add(m)
            todo.extend(graph.get(m, ()))
    assert {m for m in seen if m.startswith("sim.")} <= {"sim.errors"}
    assert not {m for m in graph.get("server.terrain.advice_api", ()) if m.startswith("sim.")}
