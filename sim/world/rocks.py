"""Rocks from the Golombek & Rapp (1997) size-frequency model, placed on the terrain.

Golombek & Rapp (1997, JGR 102(E2) 4117) and Golombek et al. (2003, JGR 108(E12) 8086)
fit the rock populations seen at the Viking and Pathfinder sites (and on Earth) with an
exponential cumulative fractional area: the fraction of the ground covered by rocks of
diameter ``D`` or larger is::

    F_k(D) = k · exp(-q(k) · D),        q(k) = 1.79 + 0.152 / k        (D in metres)

with ``k`` the total rock abundance (the fraction covered by all rocks). The
size-frequency density follows by differentiation; a rock of diameter ``D`` covers
``a(D) = π D² / 4``::

    n(D) = -F_k'(D) / a(D) = 4 k q exp(-q D) / (π D²)          rocks per m² per m
    N(≥D) = ∫_D^∞ n = (4 k q / π) · (exp(-q D) / D - q E1(q D))   rocks per m²

(``E1`` the exponential integral). We keep diameters in ``[d_min_m, d_max_m]``: rocks
are a Poisson process in the plane with density ``N(≥d_min) - N(≥d_max)``, diameters
drawn by inverting the truncated ``N`` (tabulated in log D).

Shape: each rock is a half-ellipsoid on an elliptical footprint of equivalent-area
diameter ``D`` (semi-axes ``a ≥ b``, ``a·b = D²/4``, aspect ``b/a`` uniform in
[0.6, 1], approximate), long axis at a random azimuth, height ``≈ 0.5 D`` (Golombek et
al. 2003's height/diameter ratio for rocks half buried; ±20 % scatter, mean 0.5). It is
seated on the plane tangent to the ground at its centre and added to a heightmap as
``max(ground, rock)``.

Rocks are sampled per square cell from ``(seed, cell index)``, so any region can be
generated in any order with the same result; a heightmap tile gathers the rocks of every
cell within one rock radius of it, so rocks near a tile border appear in both tiles.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.special import exp1

from sim.world.noise import GroundField, derive_key

FloatArray = NDArray[np.float64]

Q_INTERCEPT_PER_M = 1.79  # q(k) = 1.79 + 0.152/k, Golombek & Rapp 1997
Q_SLOPE_PER_M = 0.152  # same source
HEIGHT_TO_DIAMETER = 0.5  # rock height / diameter, Golombek et al. 2003
ASPECT_MIN = 0.6  # smallest footprint axis ratio b/a (approximate)
HEIGHT_SCATTER = 0.2  # height ratio uniform in 0.5·(1 ± 0.2) (approximate)
_ROCK_STREAM = 0x50C5  # derive_key label of the rock random stream


def q_of_k(k: float) -> float:
    """Decay constant ``q(k)`` (1/m) of the Golombek & Rapp model for rock abundance ``k``."""
    return Q_INTERCEPT_PER_M + Q_SLOPE_PER_M / k


def cumulative_area_fraction(d_m: ArrayLike, k: float) -> FloatArray:
    """``F_k(D)``: fraction of the ground covered by rocks of diameter ``≥ D`` (m)."""
    out: FloatArray = k * np.exp(-q_of_k(k) * np.asarray(d_m, np.float64))
    return out


def number_density(d_m: ArrayLike, k: float) -> FloatArray:
    """``n(D)``: rocks per m² per metre of diameter at diameter ``D`` (m)."""
    d = np.asarray(d_m, np.float64)
    q = q_of_k(k)
    out: FloatArray = 4.0 * k * q * np.exp(-q * d) / (np.pi * d * d)
    return out


def cumulative_number_per_m2(d_m: ArrayLike, k: float) -> FloatArray:
    """``N(≥D)``: rocks per m² with diameter ``≥ D`` (m), untruncated model."""
    d = np.asarray(d_m, np.float64)
    q = q_of_k(k)
    out: FloatArray = (4.0 * k * q / np.pi) * (np.exp(-q * d) / d - q * exp1(q * d))
    return out


@dataclass(frozen=True)
class RockPopulation:
    """Rock abundance ``k`` and the diameter range (m) we place on the terrain."""

    k: float
    d_min_m: float = 0.05
    d_max_m: float = 1.0

    def __post_init__(self) -> None:
        if not 0.0 < self.k < 1.0:
            raise ValueError("rock abundance k must be in (0, 1)")
        if not 0.0 < self.d_min_m < self.d_max_m:
            raise ValueError("need 0 < d_min_m < d_max_m")

    @property
    def density_per_m2(self) -> float:
        """Rocks per m² with diameters in ``[d_min_m, d_max_m]``."""
        n = cumulative_number_per_m2(np.array([self.d_min_m, self.d_max_m]), self.k)
        return float(n[0] - n[1])

    @property
    def max_semi_major_m(self) -> float:
        """Largest footprint semi-axis any rock can have (m)."""
        return 0.5 * self.d_max_m / float(np.sqrt(ASPECT_MIN))

    def area_fraction(self, d_m: ArrayLike) -> FloatArray:
        """Expected fraction of ground covered by placed rocks of diameter ``≥ D``."""
        d = np.clip(np.asarray(d_m, np.float64), self.d_min_m, self.d_max_m)
        out: FloatArray = cumulative_area_fraction(d, self.k) - cumulative_area_fraction(
            self.d_max_m, self.k
        )
        return out

    @cached_property
    def _inverse_cdf(self) -> tuple[FloatArray, FloatArray]:
        """``(P(diameter ≥ D), log D)`` tabulated in log D, increasing in P: the table of
        ``sample_diameters``, built once (every heightmap tile samples rocks)."""
        log_d = np.linspace(np.log(self.d_min_m), np.log(self.d_max_m), 4097)
        cum = cumulative_number_per_m2(np.exp(log_d), self.k)
        p_ge = (cum - cum[-1]) / (cum[0] - cum[-1])  # P(diameter ≥ D), 1 -> 0
        return p_ge[::-1], log_d[::-1]

    def sample_diameters(self, rng: np.random.Generator, n: int) -> FloatArray:
        """``n`` diameters (m) from the truncated size-frequency law, by inverse CDF."""
        p_ge, log_d = self._inverse_cdf
        u = rng.random(n)
        out: FloatArray = np.exp(np.interp(u, p_ge, log_d))
        return out


@dataclass(frozen=True)
class Rocks:
    """A set of rocks; every field has shape ``(n,)``.

    Centre ``(x_m, y_m)`` in the Site frame (North, East, m); equivalent-area
    ``diameter_m``; footprint semi-axes ``semi_major_m ≥ semi_minor_m``; ``azimuth_rad``
    of the long axis clockwise from North; ``height_m`` of the top above its base; the base
    plane ``z = base_m + slope_x·(x - x_m) + slope_y·(y - y_m)`` (elevation up, m).
    """

    x_m: FloatArray
    y_m: FloatArray
    diameter_m: FloatArray
    semi_major_m: FloatArray
    semi_minor_m: FloatArray
    azimuth_rad: FloatArray
    height_m: FloatArray
    base_m: FloatArray
    slope_x: FloatArray
    slope_y: FloatArray

    def __len__(self) -> int:
        return int(self.x_m.shape[0])

    def select(self, mask: NDArray[np.bool_]) -> Rocks:
        """The rocks where ``mask`` is true."""
        return Rocks(**{f: getattr(self, f)[mask] for f in self.__dataclass_fields__})

    @staticmethod
    def concatenate(parts: list[Rocks]) -> Rocks:
        """All rocks of ``parts`` in one set."""
        fields = Rocks.__dataclass_fields__
        return Rocks(**{f: np.concatenate([getattr(p, f) for p in parts]) for f in fields})


def sample_rocks(
    population: RockPopulation,
    rng: np.random.Generator,
    x0_m: float,
    y0_m: float,
    size_m: float,
    ground: GroundField | None = None,
) -> Rocks:
    """Rocks with centres in the square ``[x0, x0+size) x [y0, y0+size)`` (m).

    Poisson count with mean ``density_per_m2 · size²``, uniform positions, diameters from
    ``population``, shapes as in the module docstring. With ``ground``, each rock sits on
    the ground's tangent plane at its centre (forward differences over half its long
    axis); without, on the plane z = 0.
    """
    n = int(rng.poisson(population.density_per_m2 * size_m * size_m))
    x = x0_m + size_m * rng.random(n)
    y = y0_m + size_m * rng.random(n)
    d = population.sample_diameters(rng, n)
    aspect = rng.uniform(ASPECT_MIN, 1.0, n)
    a = 0.5 * d / np.sqrt(aspect)
    b = 0.5 * d * np.sqrt(aspect)
    azimuth = rng.uniform(0.0, np.pi, n)
    height = HEIGHT_TO_DIAMETER * d * rng.uniform(1.0 - HEIGHT_SCATTER, 1.0 + HEIGHT_SCATTER, n)
    if ground is None or n == 0:
        base = np.zeros(n)
        sx = np.zeros(n)
        sy = np.zeros(n)
    else:
        h = 0.5 * a  # forward differences over half the long axis: the rock-scale tilt
        g = ground.at(np.concatenate([x, x + h, x]), np.concatenate([y, y, y + h])).reshape(3, n)
        base = g[0]
        sx = (g[1] - g[0]) / h
        sy = (g[2] - g[0]) / h
    return Rocks(x, y, d, a, b, azimuth, height, base, sx, sy)


def stamp_rocks(heights: FloatArray, rocks: Rocks, i0: int, j0: int, spacing_m: float) -> None:
    """Raise ``heights[a, b]`` (samples at ``x = (i0+a)·s``, ``y = (j0+b)·s``) to the rocks.

    In place: ``heights = max(heights, rock top)`` wherever a footprint covers a sample.
    Vectorised over all (rock, sample) pairs of the rocks' bounding windows.
    """
    if not heights.flags.c_contiguous:
        raise ValueError("heights must be C-contiguous (it is updated in place)")
    n_a, n_b = heights.shape
    lo_a = np.maximum(np.ceil((rocks.x_m - rocks.semi_major_m) / spacing_m) - i0, 0)
    hi_a = np.minimum(np.floor((rocks.x_m + rocks.semi_major_m) / spacing_m) - i0, n_a - 1)
    lo_b = np.maximum(np.ceil((rocks.y_m - rocks.semi_major_m) / spacing_m) - j0, 0)
    hi_b = np.minimum(np.floor((rocks.y_m + rocks.semi_major_m) / spacing_m) - j0, n_b - 1)
    len_a = (hi_a - lo_a + 1).astype(np.int64)
    len_b = (hi_b - lo_b + 1).astype(np.int64)
    keep = (len_a > 0) & (len_b > 0)
    if not keep.any():
        return
    r = rocks.select(keep)
    lo_a, lo_b, len_a, len_b = lo_a[keep], lo_b[keep], len_a[keep], len_b[keep]
    counts = len_a * len_b
    rock = np.repeat(np.arange(len(r)), counts)  # which rock each pair belongs to
    k = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
    a_idx = lo_a.astype(np.int64)[rock] + k // len_b[rock]
    b_idx = lo_b.astype(np.int64)[rock] + k % len_b[rock]
    dx = (i0 + a_idx) * spacing_m - r.x_m[rock]  # same node arithmetic as the ground grid
    dy = (j0 + b_idx) * spacing_m - r.y_m[rock]
    c = np.cos(r.azimuth_rad[rock])
    s = np.sin(r.azimuth_rad[rock])
    along = (c * dx + s * dy) / r.semi_major_m[rock]
    across = (-s * dx + c * dy) / r.semi_minor_m[rock]
    rho2 = along * along + across * across
    inside = rho2 < 1.0
    top = (
        r.base_m[rock]
        + r.slope_x[rock] * dx
        + r.slope_y[rock] * dy
        + r.height_m[rock] * np.sqrt(np.maximum(1.0 - rho2, 0.0))
    )
    flat_idx = (a_idx * n_b + b_idx)[inside]
    np.maximum.at(heights.reshape(-1), flat_idx, top[inside])


class RockField:
    """Rocks over the whole plane, sampled per ``cell_m`` square cell from the seed.

    Cell ``(ci, cj)`` holds the rocks centred in ``[ci·cell, (ci+1)·cell) x [cj·cell, ...)``,
    drawn from a generator seeded by ``(seed, ci, cj)`` alone. ``stamp`` fits the
    ``TileStamper`` signature of ``sim.world.heightmap``. Thread-safe; caches recent cells.
    """

    def __init__(
        self,
        seed: int,
        population: RockPopulation,
        ground: GroundField | None = None,
        cell_m: float = 8.0,
        cache_cells: int = 512,
    ) -> None:
        if population.max_semi_major_m >= cell_m:
            raise ValueError("rocks must be smaller than the sampling cell")
        self.seed = seed
        self.population = population
        self.cell_m = float(cell_m)
        self._ground = ground
        self._cache: OrderedDict[tuple[int, int], Rocks] = OrderedDict()
        self._cache_cells = cache_cells
        self._lock = threading.Lock()

    def rocks_in_cell(self, ci: int, cj: int) -> Rocks:
        """The rocks centred in cell ``(ci, cj)`` (deterministic from the seed)."""
        key = (int(ci), int(cj))
        with self._lock:
            hit = self._cache.get(key)
            if hit is not None:
                self._cache.move_to_end(key)
                return hit
        rng = np.random.default_rng(derive_key(self.seed, _ROCK_STREAM, key[0], key[1]))
        rocks = sample_rocks(
            self.population,
            rng,
            key[0] * self.cell_m,
            key[1] * self.cell_m,
            self.cell_m,
            self._ground,
        )
        with self._lock:
            self._cache[key] = rocks
            while len(self._cache) > self._cache_cells:
                self._cache.popitem(last=False)
        return rocks

    def rocks_in_box(self, x_min_m: float, x_max_m: float, y_min_m: float, y_max_m: float) -> Rocks:
        """Rocks whose centres lie in ``[x_min, x_max] x [y_min, y_max]`` (m)."""
        c = self.cell_m
        parts = [
            self.rocks_in_cell(ci, cj)
            for ci in range(int(np.floor(x_min_m / c)), int(np.floor(x_max_m / c)) + 1)
            for cj in range(int(np.floor(y_min_m / c)), int(np.floor(y_max_m / c)) + 1)
        ]
        rocks = Rocks.concatenate(parts)
        inside = (
            (rocks.x_m >= x_min_m)
            & (rocks.x_m <= x_max_m)
            & (rocks.y_m >= y_min_m)
            & (rocks.y_m <= y_max_m)
        )
        return rocks.select(inside)

    def stamp(self, heights: FloatArray, i0: int, j0: int, spacing_m: float) -> None:
        """Add every rock that reaches the samples of ``heights`` (see ``stamp_rocks``)."""
        reach = self.population.max_semi_major_m
        n_a, n_b = heights.shape
        rocks = self.rocks_in_box(
            i0 * spacing_m - reach,
            (i0 + n_a - 1) * spacing_m + reach,
            j0 * spacing_m - reach,
            (j0 + n_b - 1) * spacing_m + reach,
        )
        stamp_rocks(heights, rocks, i0, j0, spacing_m)
