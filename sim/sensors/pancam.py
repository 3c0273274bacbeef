"""Pancam sun images: the solar disk through the 880 nm ND5 solar filter, with detector noise.

What the image contains, in order of the light path:

- The sun disk, angular radius ``asin(R_sun / d)`` for the Sun-Mars distance ``d`` (about
  0.35 deg across at 1.52 AU), with linear limb darkening ``I(mu) = I0 (1 - u (1 - mu))``;
  ``u = 0.45`` near 880 nm (approximate: the solar limb darkening tabulated in Allen's
  Astrophysical Quantities, 4th ed., falls from ~0.7 at 500 nm to ~0.45 in the near IR).
- Radiometry: the solar spectral irradiance at 880 nm scaled to ``d``, the atmosphere's
  transmission, the 20 nm band and ND 5 (1e-5) of Pancam's R8 solar filter, the 2.15 mm
  aperture (43 mm focal length at f/20) and the optics x quantum-efficiency throughput
  (Bell et al. 2003, JGR 108(E12) 8063; values marked approximate are ours).
- Geometry: the disk is rendered ray by ray through the camera model on a supersampled
  grid (``supersample`` x ``supersample`` rays per pixel), each ray weighted by its solid
  angle ``cos^3(alpha) / f^2`` so the flux of the disk is right anywhere in the field.
  Only the disk's box is traced and only its rows are blurred: the rest of the stamp is
  exactly zero either way, and the test holds the stamp to the whole one, bit for bit.
- Optics: a Gaussian PSF of ``psf_sigma_px``. Diffraction at f/20 and 880 nm has a
  Gaussian-equivalent sigma of ``0.42 lambda N`` = 7.4 um = 0.62 px on the 12 um pixels;
  0.7 px allows a little defocus.
- Exposure: like MER's autoexposure, chosen so the expected peak pixel sits at
  ``peak_fraction`` (default 70 %) of the full well. With no sun in the field the exposure
  is the one predicted for a sun at the boresight (what the sun-finding sequence commands).
- Detector (Bell et al. 2003): full well >= 150,000 e-, read noise < 50 e- (we take the
  bound: conservative), 12-bit ADC; the gain (~full well over 12 bits) and the dark offset
  are approximate. Shot noise is Poisson on the signal; read noise Gaussian; the sky
  through ND 5 is black (the aureole is ~1e-6 of the disk's surface brightness), and dark
  current during a ~0.1 s exposure is a few DN at most, folded into the offset. The read
  noise, a million draws a frame, is drawn in bulk (``sim.sensors.normal_f32``): numpy's
  ``standard_normal`` to the bit, a few times faster.

The sun is far away, so the mast head's offset from the body origin causes no parallax.
"""

from __future__ import annotations

import functools
import math
import threading
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimation.camera_model import PANCAM, PinholeCamera, R_b_pancam
from sim.errors import InputError

FloatArray = NDArray[np.float64]

SUN_RADIUS_M = 6.957e8  # IAU 2015 Resolution B3, nominal solar radius
AU_M = 149_597_870_700.0  # IAU 2012 Resolution B2
MARS_MEAN_SUN_DISTANCE_AU = 1.52367934  # Mars semi-major axis (Mars24 D-2 constant)
PLANCK_J_S = 6.62607015e-34  # SI 2019 exact
LIGHT_SPEED_M_S = 299_792_458.0  # SI exact
# Dust (a fault, sim.faults): the blur of the light it scatters forward, approximate (the
# aureole of a dusty sky widens with optical depth), and its cap.
DUST_BLUR_PX_PER_TAU = 2.0
DUST_BLUR_MAX_PX = 20.0
SOLAR_IRRADIANCE_880NM_1AU_W_M2_NM = 0.95  # approximate, ASTM E-490 AM0 spectrum at 880 nm


@dataclass(frozen=True)
class SolarFilter:
    """Radiometry of one Pancam eye through a solar filter (defaults: R8, 880 nm, ND 5)."""

    wavelength_m: float = 880e-9  # Bell et al. 2003
    bandwidth_nm: float = 20.0  # Bell et al. 2003, filter FWHM
    nd_transmission: float = 1e-5  # ND 5 (Bell et al. 2003)
    throughput: float = 0.25  # approximate: optics x CCD quantum efficiency at 880 nm
    aperture_diameter_m: float = 0.043 / 20.0  # 43 mm focal length at f/20 (Bell et al.)


@dataclass(frozen=True)
class PancamDetector:
    """The CCD and its electronics, plus the optical blur and the renderer's supersampling."""

    full_well_e: float = 150_000.0  # Bell et al. 2003: at least 150,000 e-
    gain_e_per_dn: float = 40.0  # approximate: ~full well over 12 bits
    read_noise_e: float = 50.0  # Bell et al. 2003: < 50 e- (bound taken)
    dark_offset_dn: float = 100.0  # approximate electronic bias level
    adc_bits: int = 12  # Bell et al. 2003
    psf_sigma_px: float = 0.7  # diffraction at f/20, 880 nm: 0.62 px; plus a little defocus
    supersample: int = 8  # rays per pixel per axis when rendering the disk

    def __post_init__(self) -> None:
        for name in ("full_well_e", "gain_e_per_dn", "psf_sigma_px"):
            if not getattr(self, name) > 0.0:
                raise InputError(name, "must be positive")
        if self.read_noise_e < 0.0 or self.dark_offset_dn < 0.0:
            raise InputError("read_noise_e/dark_offset_dn", "must be non-negative")
        if not 1 <= self.adc_bits <= 16:
            raise InputError("adc_bits", "must be in 1..16")
        if not 1 <= self.supersample <= 32:
            raise InputError("supersample", "must be in 1..32")


@dataclass(frozen=True)
class SunImage:
    """A rendered frame: ``image`` (H, W) uint16 DN; ``truth_uv_px`` (2,) the projection of
    the sun's centre (column, row; may lie off the detector), None if the sun is behind the
    camera; ``sun_cam`` (3,) the true sun unit vector in the camera frame; ``exposure_s``;
    ``peak_e`` the expected (noise-free) electrons in the brightest pixel (0 if none)."""

    image: NDArray[np.uint16]
    truth_uv_px: FloatArray | None
    sun_cam: FloatArray
    exposure_s: float
    peak_e: float


@dataclass(frozen=True)
class SunStamp:
    """Noise-free sun signal: ``rate_e_s`` (h, w) photoelectrons per second in the pixels
    whose top-left is at (``row0``, ``col0``); may extend beyond the detector."""

    row0: int
    col0: int
    rate_e_s: FloatArray


def sun_angular_radius_rad(sun_distance_au: float) -> float:
    """Apparent angular radius of the sun at ``sun_distance_au``; 0.175 deg at 1.52 AU."""
    if not (math.isfinite(sun_distance_au) and sun_distance_au > 0.01):
        raise InputError("sun_distance_au", f"must be a distance in AU, got {sun_distance_au}")
    return math.asin(SUN_RADIUS_M / (sun_distance_au * AU_M))


def sun_disk_rate_e_s(
    sun_distance_au: float, atmos_transmission: float, optics: SolarFilter
) -> float:
    """Photoelectrons per second from the whole solar disk collected by the aperture."""
    irradiance_w_m2 = (
        SOLAR_IRRADIANCE_880NM_1AU_W_M2_NM
        / sun_distance_au**2
        * optics.bandwidth_nm
        * atmos_transmission
        * optics.nd_transmission
        * optics.throughput
    )
    photon_j = PLANCK_J_S * LIGHT_SPEED_M_S / optics.wavelength_m
    aperture_m2 = math.pi * (0.5 * optics.aperture_diameter_m) ** 2
    return irradiance_w_m2 * aperture_m2 / photon_j


def render_sun_stamp(
    sun_cam: ArrayLike,
    camera: PinholeCamera,
    detector: PancamDetector,
    angular_radius_rad: float,
    limb_darkening_u: float,
    disk_rate_e_s: float,
    *,
    restrict: bool = True,
) -> SunStamp | None:
    """Noise-free photoelectron rate of the sun's image around its centre.

    ``sun_cam`` (3,) is the unit sun vector in the camera frame. Returns None if the sun is
    behind the camera or its image (disk plus PSF wings) misses the detector entirely.
    ``restrict`` traces rays and blurs only where the disk and its blur are (the rest of the
    stamp is exactly zero either way); False does the whole stamp, the reference that the
    test holds the restricted rendering to, bit for bit.
    """
    s = np.asarray(sun_cam, dtype=np.float64).reshape(3)
    s = s / np.linalg.norm(s)
    if s[2] <= 0.0:
        return None
    u0, v0 = (float(c) for c in camera.project(s))
    rho = angular_radius_rad
    # Half-size: the disk (stretched by up to ~1/cos^2 off-axis) plus 5 PSF sigmas.
    half = math.ceil(1.1 * rho * camera.f_px + 5.0 * detector.psf_sigma_px + 2.0)
    col0 = math.floor(u0 + 0.5) - half
    row0 = math.floor(v0 + 0.5) - half
    n = 2 * half + 1
    if col0 + n <= 0 or row0 + n <= 0 or col0 >= camera.width_px or row0 >= camera.height_px:
        return None

    ss = detector.supersample
    m = n * ss
    offsets = (np.arange(m) + 0.5) / ss - 0.5  # sub-pixel centres from a pixel centre
    # Camera-plane coordinates of the sub-pixel centres (camera.unproject, written out).
    x = (col0 + offsets - camera.c_u_px) / camera.f_px
    y = (row0 + offsets - camera.c_v_px) / camera.f_px
    flux = np.zeros((m, m))
    rows = slice(0, m)
    traced = False
    if restrict:
        # The disk's box: its centre plus its stretched radius and a pixel; kept only if no
        # ray on the box's rim sees the sun (the disk's image is convex, so then it all lies
        # inside), else the whole stamp is traced.
        reach = math.ceil((1.1 * rho * camera.f_px + 1.0) * ss)
        centre_r = round((v0 - row0 + 0.5) * ss - 0.5)  # sub-pixel index of the centre
        centre_c = round((u0 - col0 + 0.5) * ss - 0.5)
        rows = slice(max(centre_r - reach, 0), min(centre_r + reach + 1, m))
        cols = slice(max(centre_c - reach, 0), min(centre_c + reach + 1, m))
        box = _disk_flux(x[cols], y[rows], s, rho, limb_darkening_u, camera.f_px * ss)
        rim = np.concatenate([box[0], box[-1], box[:, 0], box[:, -1]])
        if not np.any(rim != 0.0):
            flux[rows, cols] = box
            traced = True
    if not traced:
        rows = slice(0, m)
        flux = _disk_flux(x, y, s, rho, limb_darkening_u, camera.f_px * ss)
    sigma_sub = detector.psf_sigma_px * ss
    # Rows farther than the kernel's reach from the disk blur to exactly zero: the blur runs
    # over the disk's rows and that reach only, over whole rows (OpenCV's arithmetic for
    # a pixel then stays the same as over the whole stamp; cutting columns would not).
    kernel_reach = math.ceil(4.0 * sigma_sub) + 2  # OpenCV's float kernels: 4 sigma
    rows = slice(max(rows.start - kernel_reach, 0), min(rows.stop + kernel_reach, m))
    blurred = np.zeros((m, m))
    blurred[rows] = cv2.GaussianBlur(
        flux[rows], (0, 0), sigmaX=sigma_sub, borderType=cv2.BORDER_CONSTANT
    )
    per_px = blurred.reshape(n, ss, n, ss).sum(axis=(1, 3))
    # Normalise by the disk's analytic flux (radiance 1 at the centre, linear law).
    disk_flux = math.pi * rho**2 * (1.0 - limb_darkening_u / 3.0)
    return SunStamp(row0, col0, per_px * (disk_rate_e_s / disk_flux))


def _disk_flux(
    x: FloatArray, y: FloatArray, s: FloatArray, rho: float, u: float, f_sub: float
) -> FloatArray:
    """Flux of the rays through camera-plane points ``x`` (columns) by ``y`` (rows): the
    limb-darkened radiance where the ray meets the disk, times the ray's solid angle
    ``cos^3(alpha) / f_sub^2`` (``f_sub`` the focal length in sub-pixels); 0 off the disk."""
    xx = x[None, :]
    yy = y[:, None]
    inv_len = 1.0 / np.sqrt(xx * xx + yy * yy + 1.0)  # = cos(alpha), alpha off the boresight
    cos_t = (xx * s[0] + yy * s[1] + s[2]) * inv_len  # cosine of the angle from the sun
    # sin^2 of that angle as (1 - c)(1 + c): cos_t's ~1e-16 rounding is ~1e-11 of sin^2
    # at the limb, so no need for a cross product.
    sin2_t = (1.0 - cos_t) * (1.0 + cos_t)
    # Heliocentric mu of the solar surface point seen there (rho << 1).
    r2 = sin2_t / math.sin(rho) ** 2
    inside = (r2 < 1.0) & (cos_t > 0.0)
    mu = np.sqrt(np.clip(1.0 - r2, 0.0, 1.0))
    radiance = np.where(inside, 1.0 - u * (1.0 - mu), 0.0)
    flux: FloatArray = radiance * inv_len**3 / f_sub**2
    return flux


def render_sun_image(
    sun_b: ArrayLike,
    az_rad: float,
    el_rad: float,
    rng: np.random.Generator,
    *,
    camera: PinholeCamera = PANCAM,
    detector: PancamDetector | None = None,
    optics: SolarFilter | None = None,
    sun_distance_au: float = MARS_MEAN_SUN_DISTANCE_AU,
    limb_darkening_u: float = 0.45,
    atmos_transmission: float = 0.6,
    peak_fraction: float = 0.7,
    dust_slant_tau: float = 0.0,
) -> SunImage:
    """A Pancam solar-filter frame of the sun at body direction ``sun_b`` (3,).

    The mast points the camera at ``(az_rad, el_rad)`` (see ``R_b_pancam``). Returns the
    12-bit image as uint16 and the truth (see :class:`SunImage`). If the sun is outside the
    field of view the image is dark offset plus noise.

    ``dust_slant_tau``: the optical depth of dust along the line of sight (a fault,
    ``sim.faults``; 0 in a healthy simulation, which then takes no other path). The sun's
    signal is dimmed by Beer-Lambert's ``exp(-dust_slant_tau)`` and blurred by the light the
    dust scatters forward (a Gaussian of ``DUST_BLUR_PX_PER_TAU`` pixels per unit of optical
    depth, approximate), while the exposure stays the one for the clear sun: dimmer, wider
    disks, and with enough dust no sun at all for Sunfind.
    """
    det = detector if detector is not None else PancamDetector()
    opt = optics if optics is not None else SolarFilter()
    sb = np.asarray(sun_b, dtype=np.float64)
    norm = float(np.linalg.norm(sb)) if sb.shape == (3,) else 0.0
    if not (math.isfinite(norm) and norm > 0.0):
        raise InputError("sun_b", "must be a finite non-zero 3-vector")
    if not (math.isfinite(az_rad) and math.isfinite(el_rad)):
        raise InputError("az_rad/el_rad", "must be finite")
    if not 0.0 <= limb_darkening_u <= 1.0:
        raise InputError("limb_darkening_u", "must be in [0, 1]")
    if not 0.0 < atmos_transmission <= 1.0:
        raise InputError("atmos_transmission", "must be in (0, 1]")
    if not 0.0 < peak_fraction <= 1.0:
        raise InputError("peak_fraction", "must be in (0, 1]")
    if not (math.isfinite(dust_slant_tau) and dust_slant_tau >= 0.0):
        raise InputError("dust_slant_tau", f"must be finite and >= 0, got {dust_slant_tau}")

    rho = sun_angular_radius_rad(sun_distance_au)
    disk_rate = sun_disk_rate_e_s(sun_distance_au, atmos_transmission, opt)
    sun_cam = R_b_pancam(az_rad, el_rad).T @ (sb / norm)
    stamp = render_sun_stamp(sun_cam, camera, det, rho, limb_darkening_u, disk_rate)

    # Autoexposure: put the expected peak at peak_fraction of the full well.
    peak_rate = _on_detector_peak(stamp, camera) if stamp is not None else 0.0
    if peak_rate <= 0.0:
        peak_rate = _boresight_peak_rate(camera, det, rho, limb_darkening_u, disk_rate)
    exposure_s = peak_fraction * det.full_well_e / peak_rate
    if stamp is not None and dust_slant_tau > 0.0:
        stamp = _dusted(stamp, dust_slant_tau)

    # Detector: dark offset and read noise everywhere, Poisson shot noise on the signal.
    # (numba, like the Navcam renderer's kernels, is imported with the first frame only.)
    from sim.sensors.normal_f32 import standard_normal_f32

    h, w = camera.height_px, camera.width_px
    dn = _scratch_frame(h, w)
    # rng.standard_normal's draws, bit for bit, in bulk, times the read noise plus the offset
    read_noise_dn = np.float32(det.read_noise_e / det.gain_e_per_dn)
    standard_normal_f32(rng, dn, read_noise_dn, np.float32(det.dark_offset_dn))
    peak_e = 0.0
    if stamp is not None:
        r0, c0 = max(stamp.row0, 0), max(stamp.col0, 0)
        r1 = min(stamp.row0 + stamp.rate_e_s.shape[0], h)
        c1 = min(stamp.col0 + stamp.rate_e_s.shape[1], w)
        if r1 > r0 and c1 > c0:
            mean_e = stamp.rate_e_s[
                r0 - stamp.row0 : r1 - stamp.row0, c0 - stamp.col0 : c1 - stamp.col0
            ]
            mean_e = mean_e * exposure_s
            peak_e = float(mean_e.max())
            electrons = np.minimum(rng.poisson(mean_e), det.full_well_e)  # blooming ignored
            dn[r0:r1, c0:c1] += (electrons / det.gain_e_per_dn).astype(np.float32)
    full_scale = float(2**det.adc_bits - 1)
    # Clipping to [0, full scale] (whole numbers) before rounding to the nearest gives what
    # rounding then clipping gives; the rounding then writes the 12-bit frame directly.
    np.clip(dn, 0.0, full_scale, out=dn)
    image = np.empty((h, w), dtype=np.uint16)
    np.rint(dn, out=image, casting="unsafe")

    uv = camera.project(sun_cam)
    truth_uv = None if sun_cam[2] <= 0.0 else np.array([float(uv[0]), float(uv[1])])
    return SunImage(image, truth_uv, sun_cam, exposure_s, peak_e)


def _dusted(stamp: SunStamp, slant_tau: float) -> SunStamp:
    """``stamp`` seen through dust of optical depth ``slant_tau`` on the line of sight:
    dimmed by ``exp(-slant_tau)`` (Beer-Lambert) and blurred by a Gaussian of
    ``DUST_BLUR_PX_PER_TAU * slant_tau`` pixels (at most ``DUST_BLUR_MAX_PX``), the stamp
    grown by three of them on each side so no light is cut off."""
    from scipy.ndimage import gaussian_filter

    sigma = min(DUST_BLUR_PX_PER_TAU * slant_tau, DUST_BLUR_MAX_PX)
    pad = math.ceil(3.0 * sigma)
    rate = np.pad(stamp.rate_e_s * math.exp(-slant_tau), pad)
    if sigma > 0.0:
        rate = gaussian_filter(rate, sigma, mode="constant")
    return SunStamp(stamp.row0 - pad, stamp.col0 - pad, rate)


@functools.lru_cache(maxsize=8)
def _boresight_peak_rate(
    camera: PinholeCamera, det: PancamDetector, rho: float, u: float, disk_rate: float
) -> float:
    """The peak rate of a sun at the boresight: the exposure commanded with no sun in the
    field. The same for every such frame, so rendered once."""
    ref = render_sun_stamp(np.array([0.0, 0.0, 1.0]), camera, det, rho, u, disk_rate)
    if ref is None:  # cannot happen: a boresight sun lands on the detector
        raise RuntimeError("reference sun stamp missed the detector")
    return float(ref.rate_e_s.max())


_SCRATCH = threading.local()


def _scratch_frame(h: int, w: int) -> NDArray[np.float32]:
    """A float32 (h, w) work frame reused by the thread's renders: a fresh 4 MB array each
    frame costs its page faults, as much as a third of the noise draws themselves."""
    frame: NDArray[np.float32] | None = getattr(_SCRATCH, "frame", None)
    if frame is None or frame.shape != (h, w):
        frame = np.empty((h, w), dtype=np.float32)
        _SCRATCH.frame = frame
    return frame


def _on_detector_peak(stamp: SunStamp, camera: PinholeCamera) -> float:
    """Largest expected rate among the stamp's pixels that lie on the detector."""
    rows = np.arange(stamp.row0, stamp.row0 + stamp.rate_e_s.shape[0])
    cols = np.arange(stamp.col0, stamp.col0 + stamp.rate_e_s.shape[1])
    r_ok = (rows >= 0) & (rows < camera.height_px)
    c_ok = (cols >= 0) & (cols < camera.width_px)
    part = stamp.rate_e_s[np.ix_(r_ok, c_ok)]
    return float(part.max()) if part.size else 0.0
