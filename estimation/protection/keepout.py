"""Keep-out zones: places the ground tells a drive not to enter, and the onboard test.

A zone is a circle or a simple polygon in the Site frame that was current when it was
added (x North, y East, m; the Site's horizontal plane). Onboard, the rover does not know
where it is to better than its position uncertainty, so the test is on a disc: the estimated
position grown by ``k`` times its 1σ (``MobilityLimits.keepout_k_sigma``) must not touch the
zone (Biesiadecki and Maimone 2006 sec. 3: drives were stopped on what the rover knew of its
own position, never on where it truly was). The same geometry gives the ground's check of a
drive's nominal path against the zones (``path_clearance_m``).

Distances are signed: positive outside the zone, negative inside (the depth).

>>> zone = KeepOutZone.circle("rock", 0, 5.0, 0.0, 1.0)
>>> round(zone.clearance_m((2.0, 0.0)), 6), zone.disc_touches((3.5, 0.0), 0.6)
(2.0, True)
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Any

Point = tuple[float, float]

MAX_VERTICES = 64  # a polygon's corners: more is a terrain map, not a keep-out zone
MAX_EXTENT_M = 1.0e4  # no zone is more than 10 km from its Site's origin
MAX_ZONES = 32  # onboard table size (approximate: a flight table is small and fixed)


def _finite(name: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ValueError(f"{name}: must be a number, got {value!r}")
    number = float(value)
    if not (math.isfinite(number) and abs(number) <= MAX_EXTENT_M):
        raise ValueError(f"{name}: must be finite and within {MAX_EXTENT_M:g} m, got {value!r}")
    return number


@dataclass(frozen=True)
class KeepOutZone:
    """A named zone in Site ``site_index``: a circle (``centre_s``, ``radius_m``) when
    ``vertices_s`` is empty, else the polygon of ``vertices_s`` (3 to 64 corners, in order)."""

    name: str
    site_index: int
    centre_s: Point = (0.0, 0.0)
    radius_m: float = 0.0
    vertices_s: tuple[Point, ...] = ()

    def __post_init__(self) -> None:
        if not self.name or len(self.name) > 64 or not self.name.replace("_", "").isalnum():
            raise ValueError(f"name: letters, digits and _ (1-64), got {self.name!r}")
        if self.vertices_s:
            if not 3 <= len(self.vertices_s) <= MAX_VERTICES:
                raise ValueError(
                    f"polygon: 3 to {MAX_VERTICES} corners, got {len(self.vertices_s)}"
                )
            for i, (x, y) in enumerate(self.vertices_s):
                _finite(f"polygon corner {i + 1} x_m", x)
                _finite(f"polygon corner {i + 1} y_m", y)
            if abs(_signed_area(self.vertices_s)) < 1e-6:
                raise ValueError("polygon: its corners enclose no area")
        else:
            _finite("x_m", self.centre_s[0])
            _finite("y_m", self.centre_s[1])
            r = _finite("radius_m", self.radius_m)
            if not r > 0.0:
                raise ValueError(f"radius_m: must be positive, got {self.radius_m!r}")

    @classmethod
    def circle(
        cls, name: str, site_index: int, x_m: float, y_m: float, radius_m: float
    ) -> KeepOutZone:
        return cls(name, site_index, (float(x_m), float(y_m)), float(radius_m))

    @classmethod
    def polygon(cls, name: str, site_index: int, vertices_s: list[Point]) -> KeepOutZone:
        return cls(name, site_index, vertices_s=tuple((float(x), float(y)) for x, y in vertices_s))

    @property
    def is_circle(self) -> bool:
        return not self.vertices_s

    def clearance_m(self, p_s: Point) -> float:
        """Signed distance from the point ``p_s`` (this zone's Site, m) to the zone."""
        x, y = float(p_s[0]), float(p_s[1])
        if self.is_circle:
            cx, cy = self.centre_s
            return math.hypot(x - cx, y - cy) - self.radius_m
        edges = _edges(self.vertices_s)
        d = min(_point_segment_m((x, y), a, b) for a, b in edges)
        return -d if _inside((x, y), self.vertices_s) else d

    def disc_touches(self, p_s: Point, radius_m: float) -> bool:
        """Whether the disc of ``radius_m`` about ``p_s`` touches or overlaps the zone."""
        return self.clearance_m(p_s) <= radius_m

    def path_clearance_m(self, a_s: Point, b_s: Point) -> float:
        """The least signed distance from the segment ``a_s``-``b_s`` to the zone (≤ 0 when
        it enters it): the ground's check of a drive's nominal path."""
        a = (float(a_s[0]), float(a_s[1]))
        b = (float(b_s[0]), float(b_s[1]))
        if self.is_circle:
            return _point_segment_m(self.centre_s, a, b) - self.radius_m
        if _inside(a, self.vertices_s) or _inside(b, self.vertices_s):
            return min(self.clearance_m(a), self.clearance_m(b), 0.0)
        edges = _edges(self.vertices_s)
        if any(_segments_cross(a, b, c, d) for c, d in edges):
            return 0.0
        return min(
            min(_point_segment_m(a, c, d) for c, d in edges),
            min(_point_segment_m(b, c, d) for c, d in edges),
            min(_point_segment_m(v, a, b) for v in self.vertices_s),
        )

    def describe(self) -> str:
        """The zone as an operator reads it."""
        if self.is_circle:
            cx, cy = self.centre_s
            shape = f"circle at ({cx:.2f}, {cy:.2f}) m, radius {self.radius_m:.2f} m"
        else:
            shape = f"polygon of {len(self.vertices_s)} corners"
        return f"keep-out zone {self.name}: {shape} in Site {self.site_index}"

    def as_dict(self) -> dict[str, Any]:
        """Plain data (a checkpoint, a report)."""
        return {
            "name": self.name,
            "site_index": self.site_index,
            "centre_s": list(self.centre_s),
            "radius_m": self.radius_m,
            "vertices_s": [list(v) for v in self.vertices_s],
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> KeepOutZone:
        c = data["centre_s"]
        return cls(
            str(data["name"]),
            int(data["site_index"]),
            (float(c[0]), float(c[1])),
            float(data["radius_m"]),
            tuple((float(x), float(y)) for x, y in data["vertices_s"]),
        )


def parse_polygon(text: str) -> list[Point]:
    """Corners written ``"x1,y1 x2,y2 x3,y3"`` (``;`` also separates), m.

    >>> parse_polygon("0,0; 2,0; 2,1")
    [(0.0, 0.0), (2.0, 0.0), (2.0, 1.0)]
    """
    corners: list[Point] = []
    for i, item in enumerate(text.replace(";", " ").split()):
        parts = item.split(",")
        if len(parts) != 2:
            raise ValueError(f"polygon_m: corner {i + 1} must be x,y in m, got {item[:40]!r}")
        try:
            x, y = float(parts[0]), float(parts[1])
        except ValueError:
            raise ValueError(
                f"polygon_m: corner {i + 1} must be x,y in m, got {item[:40]!r}"
            ) from None
        corners.append(
            (_finite(f"polygon corner {i + 1} x_m", x), _finite(f"polygon corner {i + 1} y_m", y))
        )
        if len(corners) > MAX_VERTICES:
            raise ValueError(f"polygon_m: at most {MAX_VERTICES} corners")
    if len(corners) < 3:
        raise ValueError(f"polygon_m: at least 3 corners, got {len(corners)}")
    return corners


# ---- what the rover says of its table (events), and the ground reads back ----------------

_ADDED = re.compile(r"keep-out zone (\w+) added in Site (\d+): (.*)")
_CLEARED = re.compile(r"keep-out zones? cleared: (.*)")


def zone_added_text(zone: KeepOutZone) -> str:
    """The event text of a zone added; ``reported_zone`` reads it back exactly."""
    if zone.is_circle:
        cx, cy = zone.centre_s
        shape = f"circle x_m={cx!r} y_m={cy!r} radius_m={zone.radius_m!r}"
    else:
        shape = "polygon " + " ".join(f"{x!r},{y!r}" for x, y in zone.vertices_s)
    return f"keep-out zone {zone.name} added in Site {zone.site_index}: {shape}"


def zones_cleared_text(names: list[str]) -> str:
    """The event text of zones cleared (``names`` may be empty)."""
    return f"keep-out zones cleared: {', '.join(names) if names else 'none'}"


def apply_reported(zones: dict[str, KeepOutZone], text: str) -> None:
    """Update ``zones`` (name to zone) with what an event ``text`` reports, if it is a
    keep-out event (the ground rebuilds the rover's table from its events).

    >>> table: dict[str, KeepOutZone] = {}
    >>> apply_reported(table, zone_added_text(KeepOutZone.circle("rock", 1, 2.0, 3.0, 0.5)))
    >>> table["rock"].centre_s, table["rock"].site_index
    ((2.0, 3.0), 1)
    >>> apply_reported(table, zones_cleared_text(["rock"])); table
    {}
    """
    added = _ADDED.fullmatch(text)
    if added is not None:
        name, site, shape = added[1], int(added[2]), added[3]
        if shape.startswith("circle "):
            values = dict(item.split("=") for item in shape.removeprefix("circle ").split())
            zones[name] = KeepOutZone.circle(
                name, site, float(values["x_m"]), float(values["y_m"]), float(values["radius_m"])
            )
        else:
            zones[name] = KeepOutZone.polygon(
                name, site, parse_polygon(shape.removeprefix("polygon "))
            )
        return
    cleared = _CLEARED.fullmatch(text)
    if cleared is not None:
        for name in cleared[1].split(", "):
            zones.pop(name, None)


# ---- plane geometry ------------------------------------------------------------------------


def _edges(vertices: tuple[Point, ...]) -> list[tuple[Point, Point]]:
    return [(vertices[i], vertices[(i + 1) % len(vertices)]) for i in range(len(vertices))]


def _signed_area(vertices: tuple[Point, ...]) -> float:
    """Shoelace formula."""
    return 0.5 * sum(a[0] * b[1] - b[0] * a[1] for a, b in _edges(vertices))


def _point_segment_m(p: Point, a: Point, b: Point) -> float:
    """Distance from ``p`` to the segment ``a``-``b``."""
    ax, ay = a
    dx, dy = b[0] - ax, b[1] - ay
    length2 = dx * dx + dy * dy
    t = (
        0.0
        if length2 == 0.0
        else max(0.0, min(1.0, ((p[0] - ax) * dx + (p[1] - ay) * dy) / length2))
    )
    return math.hypot(p[0] - (ax + t * dx), p[1] - (ay + t * dy))


def _inside(p: Point, vertices: tuple[Point, ...]) -> bool:
    """Even-odd rule (a ray towards +x crosses the boundary an odd number of times)."""
    x, y = p
    inside = False
    for (x1, y1), (x2, y2) in _edges(vertices):
        if (y1 > y) != (y2 > y) and x < x1 + (y - y1) * (x2 - x1) / (y2 - y1):
            inside = not inside
    return inside


def _orientation(a: Point, b: Point, c: Point) -> float:
    return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])


def _segments_cross(a: Point, b: Point, c: Point, d: Point) -> bool:
    """Whether the segments ``a``-``b`` and ``c``-``d`` intersect (touching counts)."""
    o1, o2 = _orientation(a, b, c), _orientation(a, b, d)
    o3, o4 = _orientation(c, d, a), _orientation(c, d, b)
    if (o1 > 0) != (o2 > 0) and (o3 > 0) != (o4 > 0) and o1 * o2 <= 0 and o3 * o4 <= 0:
        return True
    return (
        min(_point_segment_m(c, a, b), _point_segment_m(d, a, b), _point_segment_m(a, c, d)) == 0.0
    )
