"""The orbital product a mission's mapping team delivers for a site: a stereo DEM and an
orthoimage, with their errors, made once from the site's terrain and a fixed seed.

This is what the ground knows of the terrain before the rover has imaged it. It is not the
simulator's terrain: today's ``sim.sensors.landmarks.OrbitalDem`` samples the truth exactly at
its posts; this product smooths it, adds the stereo matcher's noise and loses what is below its
resolution, after the error model of HiRISE stereo DEMs (Kirk et al. 2008):

- **Posts** every ``POST_M`` = 1 m: HiRISE images have 0.25-0.32 m pixels and their DEMs are
  posted at 1 m, 3-4 image pixels (Kirk et al. 2008).
- **Smoothing**: a stereo matcher's correlation window spans several pixels, so a DEM
  resolves features a few posts across, not one post. Modelled as a Gaussian low-pass of the
  terrain with ``SMOOTHING_SIGMA_M`` = 1 m (half-power width ~2.4 m, about 3 posts): rocks,
  ripples and the decimetre roughness are gone from the DEM ("no rocks below its resolution").
- **Vertical noise**: Kirk et al. 2008 estimate the expected vertical precision of a HiRISE
  DEM as ``EP = ρ · GSD / (p/h)``, with a matching error ``ρ`` of ~0.2 pixel: for a 0.25 m GSD
  and a parallax/height ratio of 0.2, ``EP`` = 0.25 m (``VERTICAL_SIGMA_M``; tens of cm for the
  usual convergence angles). The error is correlated over the matching window: white noise
  on the post lattice, smoothed with a Gaussian of one post and rescaled to ``EP``.
- Not modelled: the DEM's absolute (MOLA) offset and tilt and its horizontal registration;
  the ground ties the DEM to the mission frame at the landing point (``server.terrain``), where
  a constant offset cancels.

Orthoimage: the albedo at ``IMAGE_M_PX`` = 0.25 m/px (HiRISE's best, Kirk et al. 2008), band-
limited to that pixel (``sim.world.albedo.AlbedoTexture.evaluate``'s footprint), blurred by a
Gaussian point-spread function of ``IMAGE_PSF_PX`` pixel and given a relative noise of
``IMAGE_NOISE_REL`` (a signal-to-noise ratio of ~100, approximate).

Both products are pure functions of (site, seed, extent): the noise is attached to the global
post and pixel lattice (``sim.world.noise.lattice_uniform``), so every run, and the ground, get
the same product for the same site, and two overlapping extents agree where they overlap
(away from their edges' smoothing margin, which is built and cut off).

Frames: the Site frame of ``sim.world.terrain`` (x North, y East, m; heights up).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.ndimage import gaussian_filter

from sim.errors import InputError
from sim.world.noise import derive_key, lattice_uniform
from sim.world.sites import make_terrain

FloatArray = NDArray[np.float64]

POST_M = 1.0  # DEM post spacing (Kirk et al. 2008: HiRISE DEMs at 1 m)
SMOOTHING_SIGMA_M = 1.0  # Gaussian σ of the matcher's smoothing: ~3 posts half-power width
VERTICAL_SIGMA_M = 0.25  # EP = 0.2 px x 0.25 m / (p/h = 0.2) (Kirk et al. 2008)
NOISE_CORRELATION_POSTS = 1.0  # Gaussian σ of the noise's correlation, posts
IMAGE_M_PX = 0.25  # orthoimage pixel (HiRISE)
IMAGE_PSF_PX = 0.7  # Gaussian σ of the point-spread function, pixels (approximate)
IMAGE_NOISE_REL = 0.01  # relative noise of the orthoimage, SNR ~100 (approximate)
SAMPLE_M = 0.5  # spacing at which the terrain is sampled before smoothing (σ / 2)
MAX_HALF_M = 500.0  # the largest product: 1 km square
_LABEL_DEM_NOISE = 0x0DE3
_LABEL_IMAGE_NOISE = 0x1A6E


@dataclass(frozen=True)
class OrbitalProduct:
    """A site's orbital DEM and orthoimage (module docstring), Site frame.

    DEM post ``(i, j)`` is at ``(north0_m + i post_m, east0_m + j post_m)``; ``height_m``
    (ny, nx) elevation up, m; ``sigma_m`` the stated 1σ vertical precision of a post.
    Image pixel ``(i, j)`` is centred at ``(image_north0_m + i image_m_px, image_east0_m + j
    image_m_px)``; ``albedo`` (my, mx) in [0, 1].
    """

    site_name: str
    seed: int
    north0_m: float
    east0_m: float
    post_m: float
    height_m: FloatArray
    sigma_m: float
    smoothing_sigma_m: float
    image_north0_m: float
    image_east0_m: float
    image_m_px: float
    albedo: FloatArray

    def height_at(self, north_m: ArrayLike, east_m: ArrayLike) -> FloatArray:
        """The DEM's bilinear elevation (m, up) at Site points, clamped to its edge."""
        return _bilinear(self.height_m, self.north0_m, self.east0_m, self.post_m, north_m, east_m)

    def albedo_at(self, north_m: ArrayLike, east_m: ArrayLike) -> FloatArray:
        """The orthoimage's bilinear albedo at Site points, clamped to its edge."""
        return _bilinear(
            self.albedo, self.image_north0_m, self.image_east0_m, self.image_m_px, north_m, east_m
        )


def _bilinear(
    grid: FloatArray, n0: float, e0: float, step: float, north_m: ArrayLike, east_m: ArrayLike
) -> FloatArray:
    i = (np.asarray(north_m, dtype=np.float64) - n0) / step
    j = (np.asarray(east_m, dtype=np.float64) - e0) / step
    ny, nx = grid.shape
    i = np.clip(i, 0.0, ny - 1.000001)
    j = np.clip(j, 0.0, nx - 1.000001)
    i0, j0 = np.floor(i).astype(np.intp), np.floor(j).astype(np.intp)
    fi, fj = i - i0, j - j0
    out: FloatArray = (1 - fi) * ((1 - fj) * grid[i0, j0] + fj * grid[i0, j0 + 1]) + fi * (
        (1 - fj) * grid[i0 + 1, j0] + fj * grid[i0 + 1, j0 + 1]
    )
    return out


def _lattice_noise(key: int, i0: int, j0: int, ni: int, nj: int, corr: float) -> FloatArray:
    """Unit-σ Gaussian-smoothed noise on lattice indices ``i0 .. i0+ni-1`` x ``j0 ..``: white
    uniform deviates attached to the global lattice, smoothed with σ ``corr`` cells and
    rescaled so one cell has σ 1 (the smoothing's gain for a 2-D Gaussian is 1/(2 √π σ))."""
    pad = math.ceil(4.0 * corr) if corr > 0.0 else 0
    ii = np.arange(i0 - pad, i0 + ni + pad)[:, None]
    jj = np.arange(j0 - pad, j0 + nj + pad)[None, :]
    white = lattice_uniform(key, ii, jj) * math.sqrt(3.0)  # uniform on [-1, 1): σ 1/√3
    if corr > 0.0:
        white = gaussian_filter(white, corr, mode="nearest", truncate=4.0)
        white /= 1.0 / (2.0 * math.sqrt(math.pi) * corr)
    out: FloatArray = white[pad : pad + ni, pad : pad + nj]
    return out


def orbital_product(
    site_name: str, seed: int, centre_north_m: float, centre_east_m: float, half_m: float
) -> OrbitalProduct:
    """The orbital DEM and orthoimage of site ``site_name`` (terrain ``seed``) over the square
    of half-size ``half_m`` around ``(centre_north_m, centre_east_m)`` (Site frame, m), snapped
    outwards to the post lattice. Deterministic; cached. InputError on a bad argument."""
    for name, value in (("centre_north_m", centre_north_m), ("centre_east_m", centre_east_m)):
        if not (isinstance(value, int | float) and math.isfinite(value) and abs(value) < 1e5):
            raise InputError(name, f"must be a finite number within 100 km, got {value!r}")
    if not (isinstance(half_m, int | float) and 2.0 <= half_m <= MAX_HALF_M):
        raise InputError("half_m", f"must be in [2, {MAX_HALF_M:g}] m, got {half_m!r}")
    i_lo = math.floor((centre_north_m - half_m) / POST_M)
    i_hi = math.ceil((centre_north_m + half_m) / POST_M)
    j_lo = math.floor((centre_east_m - half_m) / POST_M)
    j_hi = math.ceil((centre_east_m + half_m) / POST_M)
    return _product(site_name, int(seed), i_lo, i_hi, j_lo, j_hi)


@lru_cache(maxsize=8)
def _product(
    site_name: str, seed: int, i_lo: int, i_hi: int, j_lo: int, j_hi: int
) -> OrbitalProduct:
    terrain = make_terrain(site_name, seed)  # InputError on a bad site or seed
    # The terrain, sampled every SAMPLE_M with a margin for the smoothing, low-passed.
    per_post = round(POST_M / SAMPLE_M)
    margin = math.ceil(4.0 * SMOOTHING_SIGMA_M / POST_M)
    ni = (i_hi - i_lo + 2 * margin) * per_post + 1
    nj = (j_hi - j_lo + 2 * margin) * per_post + 1
    n = (i_lo - margin) * POST_M + SAMPLE_M * np.arange(ni)
    e = (j_lo - margin) * POST_M + SAMPLE_M * np.arange(nj)
    gn, ge = np.meshgrid(n, e, indexing="ij")
    fine = np.asarray(terrain.height_m(gn, ge), dtype=np.float64)
    smooth = gaussian_filter(fine, SMOOTHING_SIGMA_M / SAMPLE_M, mode="nearest", truncate=4.0)
    keep = slice(margin * per_post, -margin * per_post, per_post)
    dem = smooth[keep, keep].copy()
    ny, nx = i_hi - i_lo + 1, j_hi - j_lo + 1
    key = derive_key(seed, _LABEL_DEM_NOISE)
    dem += VERTICAL_SIGMA_M * _lattice_noise(key, i_lo, j_lo, ny, nx, NOISE_CORRELATION_POSTS)
    # The orthoimage over the same square, pixel centres on the global pixel lattice.
    per_px = round(POST_M / IMAGE_M_PX)
    pad = math.ceil(4.0 * IMAGE_PSF_PX)
    pi_lo, pj_lo = i_lo * per_px - pad, j_lo * per_px - pad
    mi, mj = (ny - 1) * per_px + 1 + 2 * pad, (nx - 1) * per_px + 1 + 2 * pad
    pn, pe = np.meshgrid(
        IMAGE_M_PX * (pi_lo + np.arange(mi)), IMAGE_M_PX * (pj_lo + np.arange(mj)), indexing="ij"
    )
    texture = getattr(terrain, "texture", None)
    if texture is not None and hasattr(texture, "evaluate"):
        albedo = np.asarray(texture.evaluate(pn, pe, IMAGE_M_PX), dtype=np.float64)
    else:
        albedo = np.asarray(terrain.albedo(pn, pe), dtype=np.float64)
    albedo = gaussian_filter(albedo, IMAGE_PSF_PX, mode="nearest")[pad:-pad, pad:-pad]
    noise = _lattice_noise(derive_key(seed, _LABEL_IMAGE_NOISE), pi_lo + pad, pj_lo + pad,
                           albedo.shape[0], albedo.shape[1], 0.0)  # fmt: skip
    albedo = np.clip(albedo * (1.0 + IMAGE_NOISE_REL * noise), 0.0, 1.0)
    dem.setflags(write=False)  # cached and shared: nobody may edit it
    albedo.setflags(write=False)
    return OrbitalProduct(
        site_name=site_name,
        seed=seed,
        north0_m=i_lo * POST_M,
        east0_m=j_lo * POST_M,
        post_m=POST_M,
        height_m=dem,
        sigma_m=VERTICAL_SIGMA_M,
        smoothing_sigma_m=SMOOTHING_SIGMA_M,
        image_north0_m=i_lo * POST_M,
        image_east0_m=j_lo * POST_M,
        image_m_px=IMAGE_M_PX,
        albedo=albedo,
    )
