"""Rocker and bogie angle sensors: quantised, noisy readings of the suspension's truth.

Rocky-7 reads its internal angles with potentiometers (Balaram 2000 sec. 1.3); Balaram's
estimator uses them, smoothed and differenced, as known inputs to its slip constraints
(sec. 3). The simulator had no such sensors; these read ``TruthTrajectory.rocker_rad``
and ``bogie_rad``. Approximate values (no public MER figure): a 16-bit ADC over 360 deg
(LSB 0.0055 deg) and 0.01 deg of electrical noise (1σ, white), the class of a conductive
plastic potentiometer read through a good ADC. Differenced over an 8 Hz interval that is
about 0.002 rad/s of joint-rate noise, which the filter's slip noise allows for.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sim.errors import InputError
from sim.rover.truth import TruthTrajectory

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class JointEncoderParams:
    """ADC resolution and noise of the suspension angle sensors (units in the names)."""

    adc_bits: int = 16  # approximate
    range_rad: float = 2.0 * math.pi  # approximate: the ADC spans a full turn
    noise_rad: float = math.radians(0.01)  # approximate, 1σ

    def __post_init__(self) -> None:
        if not 1 <= self.adc_bits <= 24:
            raise InputError("adc_bits", "must be in 1..24")
        if not (math.isfinite(self.range_rad) and self.range_rad > 0.0):
            raise InputError("range_rad", "must be positive")
        if not (math.isfinite(self.noise_rad) and self.noise_rad >= 0.0):
            raise InputError("noise_rad", "must be finite and >= 0")

    @property
    def lsb_rad(self) -> float:
        return self.range_rad / float(2**self.adc_bits)


@dataclass(frozen=True)
class JointSamples:
    """Readings at ``t_s`` (N,): ``rocker_rad`` (N,) left rocker, ``bogie_rad`` (N, 2)."""

    t_s: FloatArray
    rocker_rad: FloatArray
    bogie_rad: FloatArray


class JointEncoders:
    """The rocker (differential) and two bogie angle sensors of one rover."""

    def __init__(self, params: JointEncoderParams, rng: np.random.Generator) -> None:
        self._p = params
        self._rng = rng

    def state(self) -> dict[str, Any]:
        """The noise generator's state (plain data; a checkpoint)."""
        return {"rng": self._rng.bit_generator.state}

    def load_state(self, state: Mapping[str, Any]) -> None:
        """Load ``state`` (``state()``) onto a sensor built from the same parameters."""
        self._rng.bit_generator.state = state["rng"]

    def read(self, truth: TruthTrajectory) -> JointSamples:
        """Quantised noisy readings of the truth suspension angles."""
        rocker, bogie = self.read_angles(truth.rocker_rad, truth.bogie_rad)
        return JointSamples(truth.t_s.copy(), rocker, bogie)

    def read_angles(
        self, rocker_rad: FloatArray, bogie_rad: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        """Quantised noisy readings ``(rocker (N,), bogie (N, 2))`` of the true angles."""
        angles = np.column_stack([rocker_rad, bogie_rad])
        if not np.all(np.isfinite(angles)):
            raise InputError("truth", "suspension angles are not finite")
        noisy = angles + self._p.noise_rad * self._rng.standard_normal(angles.shape)
        read = np.rint(noisy / self._p.lsb_rad) * self._p.lsb_rad
        return read[:, 0].copy(), read[:, 1:].copy()
