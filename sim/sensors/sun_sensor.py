"""A wide-angle sun sensor (WASS-like), Balaram 2000 sec. 1.3 and eqs. 14-16.

Rocky-7 carries Lockheed-Martin's Wide Angle Sun Sensor: a fish-eye lens images the Sun
on a two-dimensional position-sensing device whose edge currents give the centroid
(eq. 14); the optics make the output the unit sun vector's lateral components scaled by
``(2/π) asin(ρ)/ρ`` (eq. 15), so ``|s_m|`` is the angle off the boresight over 90 deg.
Field of view 160 deg (80 deg off the boresight); outside it, or with the Sun behind the
sensor, a sample is flagged invalid (its ``s_m`` is NaN).

Mounting: on the deck looking up, ``R_WASS_B`` of the flight software
(``estimation.fusion.kinematic.attitude_sensors``; no mounting error is modelled). Noise: eq. 15's
``n_s`` lumps electronics noise and calibration error; we take 0.0022 in output units per
axis (1σ, 0.2 deg of angle; approximate, the class of a WASS after calibration), white
from sample to sample.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from estimation.fusion.kinematic.attitude_sensors import R_WASS_B
from sim.errors import InputError

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


@dataclass(frozen=True)
class SunSensorParams:
    """Field of view and noise of the sensor (units in the names)."""

    half_fov_rad: float = math.radians(80.0)  # 160 deg field of view (Balaram 2000 sec. 1.3)
    noise_sm: float = 0.0022  # 1σ per output axis (approximate, see the module docstring)

    def __post_init__(self) -> None:
        if not (math.isfinite(self.half_fov_rad) and 0.0 < self.half_fov_rad <= math.pi / 2):
            raise InputError("half_fov_rad", "must be in (0, pi/2]")
        if not (math.isfinite(self.noise_sm) and self.noise_sm >= 0.0):
            raise InputError("noise_sm", "must be finite and >= 0")


@dataclass(frozen=True)
class SunSensorSamples:
    """``s_m`` (N, 2) readings at ``t_s`` (N,); ``valid`` (N,) False outside the field of
    view (``s_m`` NaN there)."""

    t_s: FloatArray
    s_m: FloatArray
    valid: BoolArray


def wass_output(sun_wass: ArrayLike) -> FloatArray:
    """Eq. 15 without noise for unit sun vectors in the sensor frame (..., 3) -> (..., 2).

    >>> np.round(wass_output([[0.0, 1.0, 1.0]]) , 12).tolist()  # 45 deg off the boresight
    [[0.0, 0.5]]
    """
    s = np.asarray(sun_wass, dtype=float)
    lateral = s[..., :2]
    rho = np.linalg.norm(lateral, axis=-1, keepdims=True)
    off = np.arctan2(rho, s[..., 2:3])  # the angle off the boresight; asin(ρ) in front
    gain = np.where(rho > 0.0, off / np.where(rho > 0.0, rho, 1.0), 1.0)
    out: FloatArray = (2.0 / np.pi) * gain * lateral
    return out


class WassSunSensor:
    """One sensor; draws its noise from ``rng``."""

    def __init__(self, params: SunSensorParams, rng: np.random.Generator) -> None:
        self._p = params
        self._rng = rng

    def state(self) -> dict[str, Any]:
        """The noise generator's state (plain data; a checkpoint)."""
        return {"rng": self._rng.bit_generator.state}

    def load_state(self, state: Mapping[str, Any]) -> None:
        """Load ``state`` (``state()``) onto a sensor built from the same parameters."""
        self._rng.bit_generator.state = state["rng"]

    def measure(self, t_s: ArrayLike, q_s_b: ArrayLike, sun_s: ArrayLike) -> SunSensorSamples:
        """Readings for the truth attitude ``q_s_b`` (N, 4) and the unit Sun ``sun_s``
        ((3,) or (N, 3), Site frame)."""
        t = np.atleast_1d(np.asarray(t_s, dtype=float))
        q = np.atleast_2d(np.asarray(q_s_b, dtype=float))
        sun = np.broadcast_to(np.asarray(sun_s, dtype=float), (t.shape[0], 3)).copy()
        if q.shape != (t.shape[0], 4) or not np.all(np.isfinite(q)):
            raise InputError("q_s_b", f"must be finite with shape ({t.shape[0]}, 4)")
        if not np.allclose(np.linalg.norm(sun, axis=-1), 1.0, atol=1e-6):
            raise InputError("sun_s", "must be unit vectors")
        sun_b = Rotation.from_quat(q).inv().apply(sun)
        sun_wass = sun_b @ R_WASS_B.T
        off = np.arccos(np.clip(sun_wass[:, 2], -1.0, 1.0))
        valid = off <= self._p.half_fov_rad
        s_m = wass_output(sun_wass) + self._p.noise_sm * self._rng.standard_normal((t.size, 2))
        s_m[~valid] = np.nan
        return SunSensorSamples(t.copy(), s_m, valid)
