"""A relay orbiter around Mars on a Keplerian (two-body) orbit: truth for Jiang, Li et al. 2014's
radio.

The orbit is Mars Odyssey's mapping orbit, approximately: 370 x 432 km altitude over the
equatorial radius (``a = 3797.2 km``, ``e = 0.0082``), inclination 93.2° to Mars' equator
(near polar, Sun-synchronous), period ~117.8 min (NASA/JPL Mars Odyssey mission pages;
values approximate). Perturbations (J2, drag) are left out, as Jiang, Li et al. 2014 does over a
pass.

Frames: the elements are referred to Mars' equator at the epoch, in the Mars-centred
inertial frame ``mci`` whose ``z`` is the IAU pole and ``x`` the node of Mars' equator on
the ICRF equator (``W = 0`` of the IAU rotation, ``sim.world.mars_frames``). The state is given
in J2000 (ICRF axes, Mars-centred: what the DSN would upload) and in Mars-fixed axes.
Kepler's equation is solved with the onboard solver (``estimation.ivp.solve_kepler``),
the same mathematics any orbit-determination ground tool uses.

Range measurements (Jiang, Li et al. 2014, eqs. 7-9): the distance from the rover's antenna to the
orbiter plus Gaussian noise of the case's accuracy, only while the orbiter is above the
elevation mask at the rover (UHF relay passes: ~10°, approximate).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from datetime import UTC, datetime

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimation.ivp import solve_kepler
from estimation.mars_constants import MARS_EQUATORIAL_RADIUS_M, MARS_GM_M3_S2
from sim.errors import InputError
from sim.world.mars_frames import R_ll_mf, R_mf_j2000, elevation_rad, iau_mars_angles_rad

FloatArray = NDArray[np.float64]

ELEVATION_MASK_DEG = 10.0  # approximate: UHF relay passes are used above ~10°
ORBIT_EPOCH = datetime(2004, 3, 1, tzinfo=UTC)  # the elements' epoch: Opportunity's first months


@dataclass(frozen=True)
class KeplerOrbit:
    """Classical elements (m, rad) at ``epoch_t_s`` (TT s since J2000), Mars-equatorial."""

    semi_major_axis_m: float = MARS_EQUATORIAL_RADIUS_M + 401_000.0  # 370 x 432 km
    eccentricity: float = 0.0082
    inclination_rad: float = math.radians(93.2)
    raan_rad: float = 0.0
    arg_periapsis_rad: float = math.radians(270.0)
    mean_anomaly_rad: float = 0.0
    epoch_t_s: float = 0.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.semi_major_axis_m) and self.semi_major_axis_m > 3.4e6):
            raise InputError("semi_major_axis_m", "must exceed Mars' radius (3.4e6 m)")
        if not (math.isfinite(self.eccentricity) and 0.0 <= self.eccentricity < 0.9):
            raise InputError("eccentricity", f"must be in [0, 0.9), got {self.eccentricity}")
        periapsis = self.semi_major_axis_m * (1.0 - self.eccentricity)
        if periapsis < MARS_EQUATORIAL_RADIUS_M + 100_000.0:
            raise InputError("eccentricity", f"periapsis {periapsis:.0f} m is inside the air")
        for name in ("inclination_rad", "raan_rad", "arg_periapsis_rad", "mean_anomaly_rad"):
            if not math.isfinite(getattr(self, name)):
                raise InputError(name, "must be finite")
        if not math.isfinite(self.epoch_t_s):
            raise InputError("epoch_t_s", "must be finite")

    @property
    def period_s(self) -> float:
        """Kepler's third law: ``T = 2π sqrt(a³ / μ)``."""
        return 2.0 * math.pi * math.sqrt(self.semi_major_axis_m**3 / MARS_GM_M3_S2)


def _rot_z(angle: float) -> FloatArray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _rot_x(angle: float) -> FloatArray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


class RelayOrbiter:
    """The orbiter's truth: Keplerian state in ``mci``, J2000 and Mars-fixed axes."""

    def __init__(self, orbit: KeplerOrbit | None = None) -> None:
        self.orbit = orbit or KeplerOrbit()
        o = self.orbit
        # Perifocal -> mci: R_z(Ω) R_x(i) R_z(ω) (active rotations of the orbit's axes)
        self._R_mci_pqw = (
            _rot_z(o.raan_rad) @ _rot_x(o.inclination_rad) @ _rot_z(o.arg_periapsis_rad)
        )
        _, _, W = iau_mars_angles_rad(o.epoch_t_s)
        # mci is the Mars-fixed frame with its spin W taken out, frozen at the epoch's pole
        self._R_mci_j2000 = _rot_z(float(W)) @ R_mf_j2000(o.epoch_t_s)

    def state_mci(self, t_s: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Position (m) and velocity (m/s) in ``mci`` at ``t_s``; shapes ``t_s.shape + (3,)``."""
        t = np.asarray(t_s, dtype=np.float64)
        if not np.all(np.isfinite(t)):
            raise InputError("t_s", "must be finite")
        o = self.orbit
        a, e = o.semi_major_axis_m, o.eccentricity
        n = math.sqrt(MARS_GM_M3_S2 / a**3)
        M = o.mean_anomaly_rad + n * (t - o.epoch_t_s)
        E = solve_kepler(np.mod(M, 2.0 * math.pi), e)  # Kepler's equation M = E - e sin E
        cE, sE = np.cos(E), np.sin(E)
        b = a * math.sqrt(1.0 - e * e)
        edot = n / (1.0 - e * cE)
        r_pqw = np.stack([a * (cE - e), b * sE, np.zeros_like(E)], axis=-1)
        v_pqw = np.stack([-a * sE * edot, b * cE * edot, np.zeros_like(E)], axis=-1)
        return r_pqw @ self._R_mci_pqw.T, v_pqw @ self._R_mci_pqw.T

    def state_j2000(self, t_s: float) -> tuple[FloatArray, FloatArray]:
        """Mars-centred J2000 position (m) and velocity (m/s) at ``t_s``: the upload."""
        r, v = self.state_mci(t_s)
        return self._R_mci_j2000.T @ r, self._R_mci_j2000.T @ v

    def position_mf_m(self, t_s: ArrayLike) -> FloatArray:
        """Mars-fixed position (m) at ``t_s``; shape ``t_s.shape + (3,)``."""
        r_mci, _ = self.state_mci(t_s)
        r_j2000 = r_mci @ self._R_mci_j2000  # rows: (R_mci_j2000^T r)^T
        out: FloatArray = np.einsum("...ij,...j->...i", R_mf_j2000(t_s), r_j2000)
        return out

    def elevation_deg(
        self, t_s: ArrayLike, rover_mf_m: ArrayLike, lat_rad: float, lon_east_rad: float
    ) -> FloatArray:
        """Elevation (deg) of the orbiter seen from ``rover_mf_m`` (LL at the given site)."""
        d = self.position_mf_m(t_s) - np.asarray(rover_mf_m, dtype=np.float64)
        d_ll = d @ R_ll_mf(lat_rad, lon_east_rad).T
        return np.degrees(elevation_rad(d_ll))

    def passes(
        self,
        t_start_s: float,
        span_s: float,
        rover_mf_m: ArrayLike,
        lat_rad: float,
        lon_east_rad: float,
        min_peak_deg: float,
        step_s: float = 10.0,
    ) -> FloatArray:
        """Times (TT s) of the culminations above ``min_peak_deg`` within the span."""
        if not (math.isfinite(span_s) and 0.0 < span_s <= 1.0e7):
            raise InputError("span_s", f"must be in (0, 1e7] s, got {span_s}")
        t = t_start_s + np.arange(0.0, span_s, step_s)
        el = self.elevation_deg(t, rover_mf_m, lat_rad, lon_east_rad)
        peak = (el[1:-1] > el[:-2]) & (el[1:-1] >= el[2:]) & (el[1:-1] >= min_peak_deg)
        out: FloatArray = t[1:-1][peak]
        return out

    def ranges(
        self,
        t_s: ArrayLike,
        rover_mf_m: ArrayLike,
        lat_rad: float,
        lon_east_rad: float,
        sigma_m: float,
        rng: np.random.Generator,
        mask_deg: float = ELEVATION_MASK_DEG,
    ) -> tuple[FloatArray, NDArray[np.bool_]]:
        """Measured ranges (eq. 7: true distance + N(0, sigma_m²)), m, at ``t_s`` (N,) from
        the rover's antenna at ``rover_mf_m`` (N, 3), and the mask of those above ``mask_deg``
        (the others are NaN)."""
        if not (math.isfinite(sigma_m) and sigma_m >= 0.0):
            raise InputError("sigma_m", f"must be non-negative, got {sigma_m}")
        t = np.asarray(t_s, dtype=np.float64)
        rover = np.asarray(rover_mf_m, dtype=np.float64)
        if rover.shape != (*t.shape, 3):
            raise InputError("rover_mf_m", f"must have shape {(*t.shape, 3)}, got {rover.shape}")
        d = self.position_mf_m(t) - rover
        truth = np.linalg.norm(d, axis=-1)
        el = np.degrees(elevation_rad(d @ R_ll_mf(lat_rad, lon_east_rad).T))
        visible = el >= mask_deg
        measured = truth + sigma_m * rng.standard_normal(truth.shape)
        return np.where(visible, measured, np.nan), visible
