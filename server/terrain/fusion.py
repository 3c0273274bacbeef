"""Fusing the rover's stereo into the ground's map: the orbital prior, then every pair's points,
each cell with a height, an honest 1σ, an albedo and a texture measure (``GroundMap``).

**The prior** (``prior_from_orbital``): the orbital product (``sim.world.orbital_map``) in the
mission frame. The ground knows where the rover landed in the orbital map (its localisation)
and that its body origin stood ``BODY_HEIGHT_M`` above the ground there, so the mission
frame's heights are the DEM's minus the DEM at the landing point minus that height. The tie
carries the DEM's own error at the landing point into every cell: the prior's σ is the DEM's
stated precision and the tie's, added in quadrature (``sqrt(2)`` times the DEM's).

**One pair, one cell**: the points falling in a cell are fitted with a plane by weighted
least squares, if there are at least as many as one correlation window holds (``window²``
pixels: one independent measurement, below) and they surround the cell's centre (their
centroid within ``MAX_CENTROID_OFFSET`` of a cell of it: a plane through points in one
corner extrapolated to the centre errs by its slope's error times the distance) (weights
``1/σ_i²``, the points' height σ from the disparity,
``server.terrain.stereo``; a weak prior of ±1 on the slopes keeps a thin strip of points
solvable); its value at the cell's centre is the cell's height. Its variance:

- the fit's, ``(Aᵀ W A)⁻¹₀₀`` (the normal matrix's inverse at the intercept), times the number
  of points that share one correlation window (``window²`` pixels, at most the cell's point
  count): SGBM's disparities are correlated over its block, so ``n`` points carry about
  ``n / window²`` independent measurements;
- the roughness the plane does not explain: the residuals' weighted mean square less the
  points' own mean variance, if positive. The map is scored against the terrain at the cell's
  centre; a rock or a ripple inside the cell puts the centre off the plane by about that much;
- the pose's share, common to all cells of the pair: the rover's position 1σ ``σ_p`` (taken
  for the vertical too), the tilt's 1σ ``σ_t`` seen at the cell's horizontal range ``r`` from
  the camera, and the position and heading errors moving the cell sideways on its slope ``s``:
  ``σ_pose² = σ_p² + (s σ_p)² + (r σ_t)² + (s r σ_ψ)²`` (see "Alignment" for the first and
  third terms of a pair that overlaps the map).

**Alignment**: a pair's heights carry its pose's error whole: a drive's vertical drift (a few
mm to cm per step), its tilt, its horizontal position. Where the pair overlaps cells the map
already has from stereo (``MIN_OVERLAP_CELLS`` at least; MER's drivers kept 60 % overlap
between VO steps) its datum is moved onto the map's: the differences are fitted by weighted
least squares (the cells' variances of both; a second pass without differences beyond 3σ)
with ``δ + t_n Δn + t_e Δe - ∂h/∂n s_n - ∂h/∂e s_e``: an offset (free), a tilt (prior σ
``σ_t``) and a horizontal shift ``s`` (prior σ ``σ_p``, moving the cell's plane of slope
``∂h``), ``Δ`` a cell's offset from the camera. The fit's covariance (Birge-scaled), carried
to each cell, plus the overlapped cells' own pose variance replaces the pair's
``σ_p² + (s σ_p)² + (r σ_t)²``; where the overlap cannot tell a parameter its prior keeps it.
The first pair, or one seeing no stereo yet, keeps its reported pose.

**Many pairs**: the cells' stereo heights are averaged with inverse-variance weights on the
fit and roughness variances; the pose's variance is not averaged down (consecutive pairs share
most of their pose error: a drive's drift) but carried as its weighted mean. If the pairs
disagree beyond their stated σ the stereo variance is scaled by the Birge ratio
``χ²/(N - 1)`` (never down). The stereo estimate is then combined with the prior by inverse
variance.

**Albedo**: each pair's grey levels averaged per cell, scaled by one gain per pair so that
their mean matches the orbital albedo's over the cells the pair saw (the images are not
radiometrically calibrated here; slope shading remains in them). **Texture**: the pair's
Shi-Tomasi features per cell divided by the area of the cells it measured (features per m²),
summed over pairs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.ndimage import gaussian_filter

from estimation.sapp.gyrocompass import NADIR_TILT_SIGMA_RAD
from server.terrain.ground_map import GroundMap
from server.terrain.stereo import StereoPoints
from sim.rover.geometry import MER_GEOMETRY
from sim.world.orbital_map import OrbitalProduct

FloatArray = NDArray[np.float64]

CELL_M = 0.25  # the map's cell: a few Navcam pixels' ground at 5 m, a quarter of a DEM post
MAX_CENTROID_OFFSET = 0.25  # of a cell: its points' centroid at most this far from its centre
OUTLIER_K = 3.0  # points this many robust σ off their cell's plane are dropped
MIN_OVERLAP_CELLS = 30  # cells shared with the map for a pair's vertical alignment
SLOPE_PRIOR = 1.0  # 1σ of a cell's slopes in the plane fit (45°)
BODY_HEIGHT_M = MER_GEOMETRY.wheel_centre_z_m + MER_GEOMETRY.wheel_radius_m  # 0.30 m
# The attitude's knowledge in the pose σ: the tilt's 1σ is the flight software's own, the
# accelerometers' 300 µg bias over Mars gravity (0.045°); the heading's ~1° (3σ) after a sun
# update (approximate).
TILT_SIGMA_RAD = NADIR_TILT_SIGMA_RAD
HEADING_SIGMA_RAD = math.radians(1.0) / 3.0
TIE_FEATHER_M = 1.0  # the orbital ground meets the measured patches over about this (tied_prior)
TIE_FEATHER_FLOOR = 0.05  # the measured share below which the local residual fades out


@dataclass(frozen=True)
class PoseSigma:
    """The 1σ of the rover's pose at capture: ``position_m`` (horizontal, used for the
    vertical too), ``tilt_rad``, ``heading_rad``."""

    position_m: float = 0.0
    tilt_rad: float = TILT_SIGMA_RAD
    heading_rad: float = HEADING_SIGMA_RAD

    def __post_init__(self) -> None:
        for name in ("position_m", "tilt_rad", "heading_rad"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value >= 0.0):
                raise ValueError(f"{name}: must be a finite non-negative number, got {value!r}")


@dataclass(frozen=True)
class Prior:
    """The orbital prior on the map's grid, mission frame (module docstring)."""

    north0_m: float
    east0_m: float
    cell_m: float
    height_m: FloatArray
    sigma_m: FloatArray
    albedo: FloatArray


def prior_from_orbital(
    product: OrbitalProduct,
    landing_north_m: float,
    landing_east_m: float,
    half_m: float,
    cell_m: float = CELL_M,
) -> Prior:
    """The prior over the square of half-size ``half_m`` around the landing point (mission
    origin), from the orbital ``product``; ``landing_*`` where the rover landed in the
    product's Site frame (module docstring)."""
    n = round(2.0 * half_m / cell_m) + 1
    offsets = -half_m + cell_m * np.arange(n)
    gn, ge = np.meshgrid(offsets, offsets, indexing="ij")
    tie = float(product.height_at(landing_north_m, landing_east_m)) + BODY_HEIGHT_M
    height = product.height_at(gn + landing_north_m, ge + landing_east_m) - tie
    sigma = np.full(height.shape, math.sqrt(2.0) * product.sigma_m)
    albedo = product.albedo_at(gn + landing_north_m, ge + landing_east_m)
    return Prior(-half_m, -half_m, cell_m, height, sigma, albedo)


@dataclass(frozen=True)
class CellFits:
    """One pair's plane per cell: ``cells`` (K,) flat cell indices, ``coef`` (K, 3) the
    plane ``h = a + bx dx + by dy`` (``a`` at the centre), ``var_a`` (K,) the intercept's
    variance from the fit, ``roughness`` (K,) the variance the plane leaves unexplained,
    ``n`` (K,) the points."""

    cells: NDArray[np.intp]
    coef: FloatArray
    var_a: FloatArray
    roughness: FloatArray
    n: FloatArray

    @property
    def slope(self) -> FloatArray:
        out: FloatArray = np.hypot(self.coef[:, 1], self.coef[:, 2])
        return out


def _plane_fits(
    index: NDArray[np.intp],
    dx: FloatArray,
    dy: FloatArray,
    h: FloatArray,
    w: FloatArray,
    size: int,
    min_points: int,
    cell_m: float,
) -> CellFits:
    """Per cell with ``min_points`` around its centre (module docstring): weighted least
    squares of ``h = a + bx dx + by dy``."""

    def s(values: FloatArray) -> FloatArray:
        return np.asarray(np.bincount(index, weights=values, minlength=size), np.float64)

    count = np.bincount(index, minlength=size)
    safe = np.maximum(count, 1)
    off_x = np.bincount(index, weights=dx, minlength=size) / safe
    off_y = np.bincount(index, weights=dy, minlength=size) / safe
    centred = np.hypot(off_x, off_y) <= MAX_CENTROID_OFFSET * cell_m
    cells = np.flatnonzero((count >= min_points) & centred)
    sums = [s(v)[cells] for v in (w, w * dx, w * dy, w * dx * dx, w * dx * dy, w * dy * dy)]
    s0, sx, sy, sxx, sxy, syy = sums
    sh, sxh, syh, shh = (s(v)[cells] for v in (w * h, w * dx * h, w * dy * h, w * h * h))
    prior = 1.0 / SLOPE_PRIOR**2
    a_mat = np.stack(
        [
            np.stack([s0, sx, sy], -1),
            np.stack([sx, sxx + prior, sxy], -1),
            np.stack([sy, sxy, syy + prior], -1),
        ],
        -2,
    )
    rhs = np.stack([sh, sxh, syh], -1)
    inv = np.linalg.inv(a_mat)
    coef = np.einsum("kij,kj->ki", inv, rhs)
    rss = (
        shh - 2.0 * np.einsum("ki,ki->k", coef, rhs) + np.einsum("ki,kij,kj->k", coef, a_mat, coef)
    )
    n = count[cells].astype(np.float64)
    mean_sq = np.maximum(rss, 0.0) / s0 * n / np.maximum(n - 3.0, 1.0)
    roughness = np.maximum(mean_sq - n / s0, 0.0)  # n / s0: the points' mean variance
    return CellFits(cells, coef, np.asarray(inv[:, 0, 0], np.float64), roughness, n)


def _cell_medians(index: NDArray[np.intp], values: FloatArray, size: int) -> FloatArray:
    """The median (upper middle) of ``values`` per cell index; 0 for empty cells."""
    order = np.lexsort((values, index))
    counts = np.bincount(index, minlength=size)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    out = np.zeros(size)
    has = np.flatnonzero(counts)
    out[has] = values[order[starts[has] + counts[has] // 2]]
    return out


def _robust_plane_fits(
    index: NDArray[np.intp],
    dx: FloatArray,
    dy: FloatArray,
    h: FloatArray,
    w: FloatArray,
    size: int,
    min_points: int,
    cell_m: float,
) -> CellFits:
    """``_plane_fits`` without the points off their cell by more than ``OUTLIER_K`` times the
    larger of their own σ and the cell's robust scale (1.4826 x the median absolute
    deviation): a mismatched blob of disparities in a cell. Two passes: about the cell's
    median height (robust to a blob of up to half the points; on a slope its spread holds
    the slope's relief, so nothing of the slope is cut), then about the plane fitted to
    what the first kept."""
    sigma = 1.0 / np.sqrt(w)
    keep = np.ones(h.shape, dtype=bool)
    centre = _cell_medians(index, h, size)[index]
    for second in (False, True):
        if second:
            fits = _plane_fits(index[keep], dx[keep], dy[keep], h[keep], w[keep], size,
                               min_points, cell_m)  # fmt: skip
            full = np.zeros((3, size))
            full[:, fits.cells] = fits.coef.T
            centre = full[0, index] + full[1, index] * dx + full[2, index] * dy
        resid = np.abs(h - centre)
        scale = 1.4826 * _cell_medians(index[keep], resid[keep], size)[index]
        keep = resid <= OUTLIER_K * np.maximum(scale, sigma)
    return _plane_fits(index[keep], dx[keep], dy[keep], h[keep], w[keep], size, min_points, cell_m)


class MapFusion:
    """The ground's map being built (module docstring): the prior, the stereo accumulators,
    and ``version`` counting the pairs fused. Not thread-safe (the service holds a lock)."""

    def __init__(self, prior: Prior) -> None:
        self.prior = prior
        shape = prior.height_m.shape
        self._w = np.zeros(shape)  # Σ 1/v over pairs (v the fit and roughness variance)
        self._wh = np.zeros(shape)
        self._whh = np.zeros(shape)
        self._wpose = np.zeros(shape)  # Σ v_pose / v
        self._n = np.zeros(shape, dtype=np.int64)  # pairs that measured the cell
        self._grey = np.zeros(shape)  # Σ calibrated albedo x points
        self._grey_n = np.zeros(shape)
        self._features = np.zeros(shape)
        self._covered = np.zeros(shape)  # pairs whose measured cells include this one
        self.nearest_m = np.full(shape, np.inf)  # the nearest camera that measured a cell, m
        self.offsets_m: list[float] = []  # each pair's vertical alignment (NaN: none)
        self.version = 0

    def add(self, points: StereoPoints, pose: PoseSigma, window_px: int) -> int:
        """Fuse one pair's points; returns the number of cells it measured."""
        p = self.prior
        ny, nx = p.height_m.shape
        pts = points.p_mission_m
        fi = (pts[:, 0] - p.north0_m) / p.cell_m
        fj = (pts[:, 1] - p.east0_m) / p.cell_m
        i, j = np.rint(fi).astype(np.intp), np.rint(fj).astype(np.intp)
        inside = (i >= 0) & (i < ny) & (j >= 0) & (j < nx)
        if not np.any(inside):
            return 0
        i, j = i[inside], j[inside]
        index = i * nx + j
        dx, dy = (fi[inside] - i) * p.cell_m, (fj[inside] - j) * p.cell_m
        h = -pts[inside, 2]
        w = 1.0 / np.maximum(points.sigma_up_m[inside], 1e-4) ** 2
        fits = _robust_plane_fits(index, dx, dy, h, w, ny * nx, window_px**2, p.cell_m)
        cells, a, slope = fits.cells, fits.coef[:, 0], fits.slope
        if cells.size == 0:
            return 0
        v = fits.var_a * np.minimum(float(window_px**2), fits.n) + fits.roughness
        ci, cj = np.divmod(cells, nx)
        cam = points.camera_mission_m
        off_n, off_e = p.north0_m + ci * p.cell_m - cam[0], p.east0_m + cj * p.cell_m - cam[1]
        r = np.hypot(off_n, off_e)
        sp = pose.position_m
        ones = np.ones_like(a)
        design = np.stack([ones, off_n, off_e, -fits.coef[:, 1], -fits.coef[:, 2]], 1)
        sigmas = np.array([math.inf, pose.tilt_rad, pose.tilt_rad, sp, sp])
        a, v_datum = self._align(cells, a, v, design, sigmas, sp**2)
        v_pose = v_datum + (slope * r * pose.heading_rad) ** 2
        flat = (self._w.reshape(-1), self._wh.reshape(-1), self._whh.reshape(-1))
        flat[0][cells] += 1.0 / v
        flat[1][cells] += a / v
        flat[2][cells] += a * a / v
        self._wpose.reshape(-1)[cells] += v_pose / v
        self._n.reshape(-1)[cells] += 1
        near = self.nearest_m.reshape(-1)
        near[cells] = np.minimum(near[cells], r)
        self._add_looks(points, inside, index, cells, ny * nx)
        self.version += 1
        return int(cells.size)

    def _align(
        self,
        cells: NDArray[np.intp],
        a: FloatArray,
        v: FloatArray,
        design: FloatArray,
        prior_sigma: FloatArray,
        position_var: float,
    ) -> tuple[FloatArray, FloatArray]:
        """The pair's heights moved onto the map where they overlap cells it already has from
        stereo (module docstring, "Alignment"), and each cell's variance of that datum.

        ``design`` (K, 5) each cell's ``[1, Δn, Δe, -∂h/∂n, -∂h/∂e]``: the height change of
        an offset, a tilt and a horizontal shift of the pair; ``prior_sigma`` (5,) their 1σ
        before the overlap is seen (inf: free; 0: fixed); ``position_var`` the vertical
        offset's variance without an overlap."""
        prior_var = np.where(np.isfinite(prior_sigma), prior_sigma**2, 0.0)
        unaligned = position_var + design[:, 1:] ** 2 @ prior_var[1:]
        seen = self._n.reshape(-1)[cells] > 0
        if np.count_nonzero(seen) < MIN_OVERLAP_CELLS:
            self.offsets_m.append(math.nan)
            return a, unaligned
        h_s, var_s, var_pose = (x.reshape(-1)[cells[seen]] for x in self._stereo_parts())
        resid = a[seen] - h_s
        w = 1.0 / (v[seen] + var_s)
        free = prior_sigma > 0.0  # a parameter with a zero σ stays at zero
        x_all = design[:, free]
        x = x_all[seen]
        precision = np.diag(np.where(np.isfinite(prior_sigma), 1.0 / np.maximum(prior_var, 1e-30),
                                     0.0)[free])  # fmt: skip
        keep = np.ones(resid.shape, dtype=bool)
        for _ in range(2):  # a fit, then again without the differences beyond 3σ
            cov = np.linalg.inv(x[keep].T @ (w[keep, None] * x[keep]) + precision)
            coef = cov @ (x[keep].T @ (w[keep] * resid[keep]))
            keep = np.abs(resid - x @ coef) <= 3.0 / np.sqrt(w)
            if np.count_nonzero(keep) < MIN_OVERLAP_CELLS:
                self.offsets_m.append(math.nan)
                return a, unaligned
        m = int(np.count_nonzero(keep))
        chi2 = float(np.sum(w[keep] * (resid[keep] - x[keep] @ coef) ** 2))
        cov = cov * max(1.0, chi2 / max(m - x.shape[1], 1))
        inherited = float(np.sum(w[keep] * var_pose[keep]) / np.sum(w[keep]))
        self.offsets_m.append(float(coef[0]))
        out: FloatArray = a - x_all @ coef
        var_datum: FloatArray = np.einsum("ki,ij,kj->k", x_all, cov, x_all)
        return out, inherited + var_datum

    def _add_looks(
        self,
        points: StereoPoints,
        inside: NDArray[np.bool_],
        index: NDArray[np.intp],
        cells: NDArray[np.intp],
        size: int,
    ) -> None:
        """The pair's albedo (grey levels scaled to the orbit's) and feature counts."""
        p = self.prior
        count = np.bincount(index, minlength=size)[cells].astype(np.float64)
        grey = np.bincount(index, weights=points.grey[inside], minlength=size)[cells] / count
        orbit = p.albedo.reshape(-1)[cells]
        gain = float(np.sum(orbit)) / max(float(np.sum(grey)), 1e-9)
        self._grey.reshape(-1)[cells] += gain * grey * count
        self._grey_n.reshape(-1)[cells] += count
        self._covered.reshape(-1)[cells] += 1.0
        feats = points.features_mission_m
        if feats.size:
            ny, nx = p.height_m.shape
            fi = np.rint((feats[:, 0] - p.north0_m) / p.cell_m).astype(np.intp)
            fj = np.rint((feats[:, 1] - p.east0_m) / p.cell_m).astype(np.intp)
            ok = (fi >= 0) & (fi < ny) & (fj >= 0) & (fj < nx)
            f_index = fi[ok] * nx + fj[ok]
            measured = np.zeros(size, dtype=bool)
            measured[cells] = True
            f_index = f_index[measured[f_index]]
            self._features.reshape(-1)[:] += np.bincount(f_index, minlength=size)

    def _stereo_parts(self) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Per cell: the stereo height, its variance from the fits (Birge-scaled), and the
        pose's variance (weighted mean over pairs); meaningless where no pair measured."""
        w = np.where(self._n > 0, self._w, 1.0)
        h = self._wh / w
        chi2 = np.maximum(self._whh - self._wh * h, 0.0)
        birge = np.where(self._n > 1, np.maximum(chi2 / np.maximum(self._n - 1, 1), 1.0), 1.0)
        return h, birge / w, self._wpose / w

    def stereo(self) -> tuple[FloatArray, FloatArray, NDArray[np.bool_]]:
        """The stereo-only heights and their 1σ (NaN where no pair measured), and the mask."""
        imaged = self._n > 0
        h, var_fit, var_pose = self._stereo_parts()
        sigma = np.sqrt(var_fit + var_pose)
        return np.where(imaged, h, np.nan), np.where(imaged, sigma, np.nan), imaged

    def ground_map(self) -> GroundMap:
        """The map now (a copy): stereo and prior combined by inverse variance."""
        p = self.prior
        h_s, sigma_s, imaged = self.stereo()
        w_prior = 1.0 / p.sigma_m**2
        w_s = np.where(imaged, 1.0 / np.where(imaged, sigma_s, 1.0) ** 2, 0.0)
        w = w_prior + w_s
        prior_h = tied_prior(np.asarray(p.height_m, dtype=np.float64), h_s, imaged, p.cell_m)
        height = (w_prior * prior_h + w_s * np.where(imaged, h_s, 0.0)) / w
        seen = self._grey_n > 0
        albedo = np.where(seen, self._grey / np.where(seen, self._grey_n, 1.0), p.albedo)
        covered = self._covered > 0
        area = np.where(covered, self._covered, 1.0) * p.cell_m**2
        texture = np.where(covered, self._features / area, np.nan)
        return GroundMap(
            north0_m=p.north0_m,
            east0_m=p.east0_m,
            cell_m=p.cell_m,
            height_m=height,
            sigma_m=np.sqrt(1.0 / w),
            albedo=np.clip(albedo, 0.0, 1.0),
            texture=texture,
            imaged=imaged.copy(),
        )


def tied_prior(
    prior_h: FloatArray, stereo_h: FloatArray, imaged: NDArray[np.bool_], cell_m: float
) -> FloatArray:
    """The orbital heights tied to the stereo the rover measured: shifted by the median of
    (stereo - orbital) over the measured cells (the DEM's own offset where the rover is,
    a few tens of cm), and, near the measured cells, by the local residual, feathered over
    ``TIE_FEATHER_M`` so the measured patches do not stand as steps in the orbital ground.
    The orbital σ is kept: the tie removes the offset, not the DEM's own relief noise."""
    if not imaged.any():
        return prior_h
    residual = np.where(imaged, stereo_h - prior_h, 0.0)
    offset = float(np.median(residual[imaged]))
    s = TIE_FEATHER_M / cell_m
    near = gaussian_filter(imaged.astype(np.float64), s, mode="constant")
    local = gaussian_filter(np.where(imaged, residual - offset, 0.0), s, mode="constant")
    weight = near / (near + TIE_FEATHER_FLOOR)  # 1 amid measured cells, 0 far from them
    out: FloatArray = prior_h + offset + weight * local / np.maximum(near, 1e-12)
    return out
