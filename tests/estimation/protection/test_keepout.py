"""Keep-out zones: distances against a brute-force sampling of the boundary, the path check,
and the validation of what the ground sends."""

from __future__ import annotations

import math

import numpy as np
import pytest

from estimation.protection.keepout import KeepOutZone, parse_polygon

L_SHAPE = [(0.0, 0.0), (4.0, 0.0), (4.0, 1.0), (1.0, 1.0), (1.0, 3.0), (0.0, 3.0)]


def _boundary_samples(vertices: list[tuple[float, float]], per_edge: int = 4000) -> np.ndarray:
    pts = []
    for i, a in enumerate(vertices):
        b = vertices[(i + 1) % len(vertices)]
        t = np.linspace(0.0, 1.0, per_edge)[:, None]
        pts.append(np.array(a) + t * (np.array(b) - np.array(a)))
    return np.vstack(pts)


def test_a_circles_clearance_is_the_distance_to_its_rim() -> None:
    zone = KeepOutZone.circle("rock", 0, 3.0, -4.0, 1.5)
    assert zone.clearance_m((0.0, 0.0)) == pytest.approx(5.0 - 1.5)
    assert zone.clearance_m((3.0, -4.0)) == pytest.approx(-1.5)  # the centre: depth 1.5 m
    assert zone.disc_touches((0.0, 0.0), 3.5) and not zone.disc_touches((0.0, 0.0), 3.49)


@pytest.mark.parametrize("point", [(2.0, 2.0), (0.5, 2.0), (3.0, 0.5), (-1.0, -1.0), (5.0, 0.5)])
def test_a_polygons_clearance_matches_a_sampled_boundary(point: tuple[float, float]) -> None:
    zone = KeepOutZone.polygon("l_shape", 0, L_SHAPE)
    sampled = float(np.min(np.hypot(*(_boundary_samples(L_SHAPE) - point).T)))
    inside = point in ((0.5, 2.0), (3.0, 0.5))
    expected = -sampled if inside else sampled
    assert zone.clearance_m(point) == pytest.approx(expected, abs=1e-3)


def test_the_path_check_sees_a_crossing_and_a_near_miss() -> None:
    circle = KeepOutZone.circle("c", 0, 5.0, 1.0, 0.5)
    assert circle.path_clearance_m((0.0, 0.0), (10.0, 0.0)) == pytest.approx(0.5)
    assert circle.path_clearance_m((0.0, 1.0), (10.0, 1.0)) == pytest.approx(-0.5)
    poly = KeepOutZone.polygon("p", 0, [(4.0, -1.0), (6.0, -1.0), (6.0, 1.0), (4.0, 1.0)])
    assert poly.path_clearance_m((0.0, 0.0), (10.0, 0.0)) <= 0.0  # straight through
    assert poly.path_clearance_m((0.0, 3.0), (10.0, 3.0)) == pytest.approx(2.0)
    assert poly.path_clearance_m((0.0, 0.0), (3.0, 0.0)) == pytest.approx(1.0)


@pytest.mark.parametrize(
    ("make", "match"),
    [
        (lambda: KeepOutZone.circle("a", 0, 0.0, 0.0, -1.0), "radius_m"),
        (lambda: KeepOutZone.circle("a", 0, math.nan, 0.0, 1.0), "x_m"),
        (lambda: KeepOutZone.circle("a", 0, 1e9, 0.0, 1.0), "x_m"),
        (lambda: KeepOutZone.circle("bad name!", 0, 0.0, 0.0, 1.0), "name"),
        (lambda: KeepOutZone.polygon("a", 0, [(0.0, 0.0), (1.0, 1.0), (2.0, 2.0)]), "no area"),
        (lambda: KeepOutZone.polygon("a", 0, [(0.0, 0.0), (1.0, 1.0)]), "3 to"),
    ],
)
def test_bad_zones_are_refused_naming_the_problem(make: object, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        make()  # type: ignore[operator]


def test_polygon_text() -> None:
    assert parse_polygon("0,0 2,0;2,1") == [(0.0, 0.0), (2.0, 0.0), (2.0, 1.0)]
    for bad, match in (
        ("0,0 1,1", "at least 3"),
        ("0,0 1 2,2", "corner 2"),
        ("a,b 1,1 2,0", "corner 1"),
    ):
        with pytest.raises(ValueError, match=match):
            parse_polygon(bad)
    with pytest.raises(ValueError, match="at most"):
        parse_polygon(" ".join(f"{i},{i % 7}" for i in range(100)))


def test_a_zone_survives_its_plain_data() -> None:
    for zone in (KeepOutZone.circle("c", 2, 1.0, 2.0, 3.0), KeepOutZone.polygon("p", 1, L_SHAPE)):
        assert KeepOutZone.from_dict(zone.as_dict()) == zone
