"""Soil patches: which soil lies where (circle, band, polygon; the topmost wins), and their
plain-data state. Regions are checked against independent geometry: distances for the
circle and the band, a convex polygon's half-planes and hand-placed points of a concave one.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from sim.errors import InputError
from sim.world.soil_patches import (
    Band,
    Circle,
    Polygon,
    SoilMap,
    SoilPatch,
    patch_from_data,
    sand_trap,
)
from sim.world.terrain import BEDROCK, GUSEV_SOIL, MERIDIANI_SAND, SAND_TRAP

RNG_SEED = 20


def _points(n: int = 4000) -> tuple[np.ndarray, np.ndarray]:
    xy = np.random.default_rng(RNG_SEED).uniform(-6.0, 6.0, (2, n))
    return xy[0], xy[1]


def test_a_circle_holds_the_points_within_its_radius() -> None:
    x, y = _points()
    inside = Circle(1.0, -2.0, 2.5).contains(x, y)
    np.testing.assert_array_equal(inside, np.hypot(x - 1.0, y + 2.0) <= 2.5)
    assert bool(Circle(0.0, 0.0, 1.0).contains(np.array(1.0), np.array(0.0)))  # the rim


def test_a_band_holds_the_points_near_its_segment_between_its_ends() -> None:
    x, y = _points()
    band = Band(-3.0, -3.0, 3.0, 3.0, 0.75)  # along the North-East diagonal
    # independent: rotate the points by -45 deg so the segment lies on the x axis
    u = (x + 3.0 + y + 3.0) / math.sqrt(2.0)
    v = (-(x + 3.0) + (y + 3.0)) / math.sqrt(2.0)
    expected = (u >= 0.0) & (u <= 6.0 * math.sqrt(2.0)) & (np.abs(v) <= 0.75)
    np.testing.assert_array_equal(band.contains(x, y), expected)


def test_a_convex_polygon_is_the_intersection_of_its_half_planes() -> None:
    x, y = _points()
    c, s = math.cos(0.4), math.sin(0.4)
    square = [(2.0 * (c * a - s * b), 2.0 * (s * a + c * b)) for a, b in
              ((1, 1), (-1, 1), (-1, -1), (1, -1))]  # fmt: skip
    inside = Polygon(tuple(square)).contains(x, y)
    cross = [
        (xb - xa) * (y - ya) - (yb - ya) * (x - xa)
        for (xa, ya), (xb, yb) in zip(square, square[1:] + square[:1], strict=True)
    ]
    expected = np.all(np.array(cross) > 0.0, axis=0)  # counter-clockwise in (x, y)
    near_edge = np.min(np.abs(cross), axis=0) < 1e-9
    np.testing.assert_array_equal(inside[~near_edge], expected[~near_edge])
    assert 0.1 < inside.mean() < 0.3  # 16 m² of 144 m²: the test sees both answers


def test_a_concave_polygon_leaves_out_its_notch() -> None:
    ell = Polygon(((0.0, 0.0), (4.0, 0.0), (4.0, 1.0), (1.0, 1.0), (1.0, 4.0), (0.0, 4.0)))
    x = np.array([0.5, 3.0, 0.5, 3.0, 2.0, -0.5])
    y = np.array([0.5, 0.5, 3.0, 3.0, 2.0, 0.5])
    np.testing.assert_array_equal(ell.contains(x, y), [True, True, True, False, False, False])


def test_the_topmost_patch_wins_and_lifting_it_uncovers_the_one_below() -> None:
    m = SoilMap(MERIDIANI_SAND)
    m.add("wide", SoilPatch(GUSEV_SOIL, Circle(0.0, 0.0, 3.0)))
    m.add("trap", sand_trap(1.0, 0.0, 1.0))
    m.add("strip", SoilPatch(BEDROCK, Band(-5.0, 2.5, 5.0, 2.5, 0.2)))
    assert m.soil_at(1.2, 0.1) is SAND_TRAP  # in "wide" and "trap": the trap is on top
    assert m.soil_at(-2.0, 0.0) is GUSEV_SOIL
    assert m.soil_at(0.0, 2.5) is BEDROCK  # the strip crosses "wide" on top of it
    assert m.soil_at(0.0, 5.0) is MERIDIANI_SAND  # the base
    np.testing.assert_array_equal(m.index_at([1.2, -2.0, 0.0, 0.0], [0.1, 0.0, 2.5, 5.0]),
                                  [2, 1, 3, 0])  # fmt: skip
    assert m.remove("trap").soil is SAND_TRAP
    assert m.soil_at(1.2, 0.1) is GUSEV_SOIL
    m.add("wide", SoilPatch(BEDROCK, Circle(0.0, 0.0, 3.0)))  # re-adding moves it on top
    assert m.soil_at(0.0, 2.5) is BEDROCK and m.soil_at(-2.0, 0.0) is BEDROCK
    assert list(m.patches()) == ["strip", "wide"]
    with pytest.raises(InputError, match="name"):
        m.remove("trap")


def test_a_rim_grades_the_soil_in_from_the_base() -> None:
    m = SoilMap(MERIDIANI_SAND, {"trap": sand_trap(0.0, 0.0, 1.0, rim_m=0.4)})
    x = np.array([0.0, 0.55, 0.8, 0.98, 1.2])
    idx = m.index_at(x, 0.0)
    np.testing.assert_allclose(m.weight_at(x, np.zeros(5), idx), [1.0, 1.0, 0.5, 0.05, 1.0])
    assert m.soil_at(0.3, 0.0) is SAND_TRAP  # deeper than the rim: the patch's own
    mid = m.soil_at(0.8, 0.0)  # half way through the rim: half way between the soils
    assert mid.embedding and mid.name == "sand_trap"
    assert mid.friction_angle_deg == pytest.approx(0.5 * (30.0 + 18.0))
    assert mid.sinkage_m == pytest.approx(0.5 * (0.01 + SAND_TRAP.sinkage_m))
    # a band's and a polygon's depth: the distance to the nearest side
    band = Band(0.0, 0.0, 4.0, 0.0, 1.0)
    np.testing.assert_allclose(band.depth_m(np.array([2.0, 0.5, 2.0]), np.array([0.0, 0.0, 0.9])),
                               [1.0, 0.5, 0.1])  # fmt: skip
    square = Polygon(((0.0, 0.0), (2.0, 0.0), (2.0, 2.0), (0.0, 2.0)))
    depth = square.depth_m(np.array([1.0, 0.25, 3.0]), np.array([1.0, 1.0, 1.0]))
    np.testing.assert_allclose(depth, [1.0, 0.25, -1.0])


def test_patches_are_plain_data_that_load_back() -> None:
    m = SoilMap(MERIDIANI_SAND)
    m.add("trap", sand_trap(5.0, -1.0, 1.5))
    m.add("band", SoilPatch(GUSEV_SOIL, Band(0.0, 0.0, 3.0, 4.0, 0.5)))
    m.add("poly", SoilPatch(BEDROCK, Polygon(((0.0, 0.0), (1.0, 0.0), (0.0, 1.0)))))
    state = json.loads(json.dumps(m.state()))  # numbers, strings, lists and dicts only
    other = SoilMap(MERIDIANI_SAND)
    other.load_state(state)
    assert other.patches() == m.patches()
    assert patch_from_data(state[0]).soil.embedding
    with pytest.raises(InputError, match="patch"):
        patch_from_data({"soil": {"name": "x"}, "kind": "circle", "region": {}})


def test_bad_regions_are_refused() -> None:
    with pytest.raises(InputError, match="radius_m"):
        Circle(0.0, 0.0, 0.0)
    with pytest.raises(InputError, match="half_width_m"):
        Band(0.0, 0.0, 1.0, 0.0, -1.0)
    with pytest.raises(InputError, match="vertices_m"):
        Polygon(((0.0, 0.0), (1.0, 0.0)))
    with pytest.raises(InputError, match="x_m"):
        Circle(float("nan"), 0.0, 1.0)
