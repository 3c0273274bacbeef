"""Soil patches: ground whose soil differs from its terrain's, by region of the Site frame.

A terrain has one base soil (``Terrain.soil``); a ``SoilMap`` lays named ``SoilPatch``es
over it, each a ``Soil`` on a region of the Site frame (x North, y East, metres): a
``Circle``, a ``Band`` (the points within a half-width of a segment, a strip with square
ends: a ripple crest) or a ``Polygon`` (even-odd rule). The soil at a point is the soil of
the topmost patch that contains it (the one added last), else the base soil. Patches are
geometry and numbers only; what a soil does to the wheels is ``sim.rover.patch_slip``'s.

A patch may have a rim: within ``rim_m`` of its edge its soil grades linearly from the base
soil's properties at the edge to its own at ``rim_m`` inside (``blend_soil``; an
assumption: loose sand deepens towards a ripple's crest and a trap's centre rather than
starting at a wall). A rover entering such a patch sinks in over the rim instead of
dropping by the whole sinkage in one control step.

A map's ``state()`` is plain data (numbers, strings, lists, dicts), so a checkpoint keeps
the patches a test conductor laid while the rover ran.

>>> from sim.world.terrain import MERIDIANI_SAND, SAND_TRAP
>>> m = SoilMap(MERIDIANI_SAND)
>>> m.add("trap", SoilPatch(SAND_TRAP, Circle(5.0, 0.0, 1.0)))
>>> m.soil_at(5.2, 0.3).name, m.soil_at(0.0, 0.0).name
('sand_trap', 'meridiani_sand')
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sim.errors import InputError
from sim.world.terrain import SAND_TRAP, Soil

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
IntArray = NDArray[np.int64]

RIM_LEVELS = 100  # a rim grades its soil in this many steps: a batch shares few soils
MAX_PATCHES = 64  # a map holds at most this many patches (a test conductor's, the places')


def _finite(name: str, value: float) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise InputError(name, f"must be a finite number, got {value!r}")
    return float(value)


@dataclass(frozen=True)
class Circle:
    """The disc of ``radius_m`` (> 0) about ``(x_m, y_m)``, Site frame, boundary included."""

    x_m: float
    y_m: float
    radius_m: float

    def __post_init__(self) -> None:
        for name in ("x_m", "y_m", "radius_m"):
            _finite(name, getattr(self, name))
        if not self.radius_m > 0.0:
            raise InputError("radius_m", f"must be > 0, got {self.radius_m}")

    def contains(self, x_m: FloatArray, y_m: FloatArray) -> BoolArray:
        """Whether each point lies in the disc; broadcast shape."""
        out: BoolArray = (x_m - self.x_m) ** 2 + (y_m - self.y_m) ** 2 <= self.radius_m**2
        return out

    def depth_m(self, x_m: FloatArray, y_m: FloatArray) -> FloatArray:
        """Distance (m) from each point inside to the rim (negative outside)."""
        out: FloatArray = self.radius_m - np.hypot(x_m - self.x_m, y_m - self.y_m)
        return out


@dataclass(frozen=True)
class Band:
    """The points within ``half_width_m`` (> 0) of the segment from ``(x0_m, y0_m)`` to
    ``(x1_m, y1_m)``, measured across it, between the perpendiculars at its ends (a
    rectangle; Site frame, boundary included)."""

    x0_m: float
    y0_m: float
    x1_m: float
    y1_m: float
    half_width_m: float

    def __post_init__(self) -> None:
        for name in ("x0_m", "y0_m", "x1_m", "y1_m", "half_width_m"):
            _finite(name, getattr(self, name))
        if not self.half_width_m > 0.0:
            raise InputError("half_width_m", f"must be > 0, got {self.half_width_m}")
        if self.x0_m == self.x1_m and self.y0_m == self.y1_m:
            raise InputError("x1_m", "the band's segment must have two distinct ends")

    def _frame(self, x_m: FloatArray, y_m: FloatArray) -> tuple[FloatArray, FloatArray, float]:
        """``(along, across, length)``: the points along the segment from its first end and
        across it (m)."""
        ux, uy = self.x1_m - self.x0_m, self.y1_m - self.y0_m
        length = math.hypot(ux, uy)
        ux, uy = ux / length, uy / length
        dx, dy = x_m - self.x0_m, y_m - self.y0_m
        return dx * ux + dy * uy, -dx * uy + dy * ux, length

    def contains(self, x_m: FloatArray, y_m: FloatArray) -> BoolArray:
        """Whether each point lies in the band; broadcast shape."""
        along, across, length = self._frame(x_m, y_m)
        out: BoolArray = (along >= 0.0) & (along <= length) & (np.abs(across) <= self.half_width_m)
        return out

    def depth_m(self, x_m: FloatArray, y_m: FloatArray) -> FloatArray:
        """Distance (m) from each point inside to the nearest side (negative outside;
        inside exact, outside a lower bound)."""
        along, across, length = self._frame(x_m, y_m)
        out: FloatArray = np.minimum(
            self.half_width_m - np.abs(across), np.minimum(along, length - along)
        )
        return out


@dataclass(frozen=True)
class Polygon:
    """A simple polygon of at least three ``(x_m, y_m)`` vertices (Site frame, either
    winding); a point is inside by the even-odd rule (a ray to +y crosses an odd number of
    edges)."""

    vertices_m: tuple[tuple[float, float], ...]

    def __post_init__(self) -> None:
        v = self.vertices_m
        if not isinstance(v, tuple) or len(v) < 3:
            raise InputError("vertices_m", "must be a tuple of at least three (x_m, y_m) pairs")
        for p in v:
            if not isinstance(p, tuple) or len(p) != 2:
                raise InputError("vertices_m", f"each vertex must be an (x_m, y_m) pair: {p!r}")
            for c in p:
                _finite("vertices_m", c)

    def contains(self, x_m: FloatArray, y_m: FloatArray) -> BoolArray:
        """Whether each point lies inside (even-odd rule); broadcast shape."""
        inside = np.zeros(np.broadcast_shapes(np.shape(x_m), np.shape(y_m)), dtype=bool)
        v = self.vertices_m
        for (xa, ya), (xb, yb) in zip(v, v[1:] + v[:1], strict=True):
            if xa == xb:
                continue  # parallel to the ray
            spans = (x_m >= min(xa, xb)) & (x_m < max(xa, xb))
            y_cross = ya + (x_m - xa) * (yb - ya) / (xb - xa)
            inside ^= spans & (y_m < y_cross)
        return inside

    def depth_m(self, x_m: FloatArray, y_m: FloatArray) -> FloatArray:
        """Distance (m) from each point to the nearest edge, negative outside."""
        x, y = np.broadcast_arrays(np.asarray(x_m, float), np.asarray(y_m, float))
        d = np.full(x.shape, np.inf)
        v = self.vertices_m
        for (xa, ya), (xb, yb) in zip(v, v[1:] + v[:1], strict=True):
            ex, ey = xb - xa, yb - ya
            t = np.clip(((x - xa) * ex + (y - ya) * ey) / (ex * ex + ey * ey), 0.0, 1.0)
            d = np.minimum(d, np.hypot(x - xa - t * ex, y - ya - t * ey))
        out: FloatArray = np.where(self.contains(x, y), d, -d)
        return out


Region = Circle | Band | Polygon
_REGIONS: dict[str, type[Circle] | type[Band] | type[Polygon]] = {
    "circle": Circle,
    "band": Band,
    "polygon": Polygon,
}


@dataclass(frozen=True)
class SoilPatch:
    """A ``soil`` on a ``region`` of the Site frame, graded in from the base soil over a
    rim of ``rim_m`` (>= 0; 0: a sharp edge) inside the region's edge."""

    soil: Soil
    region: Region
    rim_m: float = 0.0

    def __post_init__(self) -> None:
        if not isinstance(self.soil, Soil):
            raise InputError("soil", f"must be a Soil, got {self.soil!r}")
        if not isinstance(self.region, Circle | Band | Polygon):
            raise InputError("region", f"must be a Circle, Band or Polygon: {self.region!r}")
        if not _finite("rim_m", self.rim_m) >= 0.0:
            raise InputError("rim_m", f"must be >= 0, got {self.rim_m}")

    def weight(self, x_m: FloatArray, y_m: FloatArray) -> FloatArray:
        """How far each point is into the patch's own soil: 0 at the edge, 1 from ``rim_m``
        inside on (1 everywhere inside without a rim), in steps of ``1 / RIM_LEVELS``."""
        if self.rim_m == 0.0:
            return np.ones(np.broadcast_shapes(np.shape(x_m), np.shape(y_m)))
        w = np.clip(self.region.depth_m(x_m, y_m) / self.rim_m, 0.0, 1.0)
        out: FloatArray = np.round(w * RIM_LEVELS) / RIM_LEVELS
        return out

    def to_data(self) -> dict[str, Any]:
        """The patch as plain data (``patch_from_data`` reads it back)."""
        kind = next(k for k, cls in _REGIONS.items() if isinstance(self.region, cls))
        region = dataclasses.asdict(self.region)
        if kind == "polygon":
            region["vertices_m"] = [list(p) for p in self.region.vertices_m]  # type: ignore[union-attr]
        return {
            "soil": dataclasses.asdict(self.soil),
            "kind": kind,
            "region": region,
            "rim_m": self.rim_m,
        }


def patch_from_data(data: Mapping[str, Any]) -> SoilPatch:
    """The ``SoilPatch`` of ``SoilPatch.to_data()``; InputError on malformed data."""
    try:
        soil = Soil(**dict(data["soil"]))
        cls = _REGIONS[str(data["kind"])]
        fields = dict(data["region"])
        if cls is Polygon:
            fields["vertices_m"] = tuple(tuple(float(c) for c in p) for p in fields["vertices_m"])
        region = cls(**fields)
        rim_m = float(data.get("rim_m", 0.0))
    except (KeyError, TypeError, ValueError) as exc:
        raise InputError("patch", f"not a soil patch: {exc}") from exc
    return SoilPatch(soil, region, rim_m)


def blend_soil(outer: Soil, inner: Soil, weight: float) -> Soil:
    """``inner``'s soil graded by ``weight`` in [0, 1] from ``outer``'s: friction angle,
    cohesion and static sinkage linear in ``weight``; the embedding and the name are
    ``inner``'s (a rim of a sand trap is still loose enough to embed)."""
    w = min(max(float(weight), 0.0), 1.0)
    return Soil(
        inner.name,
        friction_angle_deg=outer.friction_angle_deg
        + w * (inner.friction_angle_deg - outer.friction_angle_deg),
        cohesion_kpa=outer.cohesion_kpa + w * (inner.cohesion_kpa - outer.cohesion_kpa),
        sinkage_m=outer.sinkage_m + w * (inner.sinkage_m - outer.sinkage_m),
        embedding=inner.embedding,
    )


SAND_TRAP_RIM_M = 0.3  # a sand trap's loose sand deepens over its outer 30 cm (assumption)


def sand_trap(
    x_m: float,
    y_m: float,
    radius_m: float,
    soil: Soil | None = None,
    rim_m: float | None = None,
) -> SoilPatch:
    """A sand trap: a disc of embedding soil (default ``SAND_TRAP``) about ``(x_m, y_m)``,
    graded in over ``rim_m`` (default ``SAND_TRAP_RIM_M``, at most the radius)."""
    rim = min(SAND_TRAP_RIM_M, radius_m) if rim_m is None else rim_m
    return SoilPatch(SAND_TRAP if soil is None else soil, Circle(x_m, y_m, radius_m), rim)


class SoilMap:
    """Named soil patches over a ``base`` soil; the last added is on top."""

    def __init__(self, base: Soil, patches: Mapping[str, SoilPatch] | None = None) -> None:
        self.base = base
        self._patches: dict[str, SoilPatch] = {}
        for name, patch in (patches or {}).items():
            self.add(name, patch)

    def __len__(self) -> int:
        return len(self._patches)

    def patches(self) -> dict[str, SoilPatch]:
        """The patches by name, bottom to top (a copy)."""
        return dict(self._patches)

    def add(self, name: str, patch: SoilPatch) -> None:
        """Lay ``patch`` on top as ``name``; a patch of that name is replaced (and moves on
        top). InputError for an empty name, a non-patch or more than ``MAX_PATCHES``."""
        if not isinstance(name, str) or not name.strip():
            raise InputError("name", f"must be a non-empty string, got {name!r}")
        if not isinstance(patch, SoilPatch):
            raise InputError("patch", f"must be a SoilPatch, got {patch!r}")
        self._patches.pop(name, None)
        if len(self._patches) >= MAX_PATCHES:
            raise InputError("patch", f"at most {MAX_PATCHES} soil patches")
        self._patches[name] = patch

    def remove(self, name: str) -> SoilPatch:
        """Lift the patch ``name`` and return it; InputError('name', ...) if there is none."""
        if name not in self._patches:
            known = ", ".join(self._patches) or "none"
            raise InputError("name", f"no soil patch {name!r} (patches: {known})")
        return self._patches.pop(name)

    def soils(self) -> list[Soil]:
        """The soils by index: ``soils()[0]`` the base, ``[k]`` the k-th patch from the bottom."""
        return [self.base, *(p.soil for p in self._patches.values())]

    def index_at(self, x_m: ArrayLike, y_m: ArrayLike) -> IntArray:
        """Index into ``soils()`` of the soil at each point (Site frame, m): the topmost
        patch containing it, 0 (the base) where none does; broadcast shape."""
        x = np.asarray(x_m, dtype=np.float64)
        y = np.asarray(y_m, dtype=np.float64)
        out = np.zeros(np.broadcast_shapes(x.shape, y.shape), dtype=np.int64)
        for k, patch in enumerate(self._patches.values(), start=1):
            out[patch.region.contains(x, y)] = k
        return out

    def weight_at(self, x_m: ArrayLike, y_m: ArrayLike, index: IntArray) -> FloatArray:
        """How far into its patch's own soil each point is (``SoilPatch.weight``), given
        its ``index_at``; 1 on the base soil."""
        x = np.asarray(x_m, dtype=np.float64)
        y = np.asarray(y_m, dtype=np.float64)
        out = np.ones(index.shape)
        for k, patch in enumerate(self._patches.values(), start=1):
            m = index == k
            if patch.rim_m > 0.0 and bool(np.any(m)):
                out[m] = patch.weight(
                    np.broadcast_to(x, m.shape)[m], np.broadcast_to(y, m.shape)[m]
                )
        return out

    def soil_at(self, x_m: float, y_m: float) -> Soil:
        """The soil at one point (Site frame, m), graded in a patch's rim (``blend_soil``)."""
        k = self.index_at(x_m, y_m)
        soil = self.soils()[int(k)]
        w = float(self.weight_at(x_m, y_m, k))
        return soil if w >= 1.0 else blend_soil(self.base, soil, w)

    def state(self) -> list[dict[str, Any]]:
        """The patches as plain data, bottom to top: ``[{"name": ..., **patch.to_data()}]``."""
        return [{"name": name, **p.to_data()} for name, p in self._patches.items()]

    def load_state(self, state: list[Mapping[str, Any]]) -> None:
        """Replace the patches by those of ``state`` (``state()``)."""
        self._patches = {}
        for item in state:
            self.add(str(item["name"]), patch_from_data(item))
