"""Wheel drive encoders and steering angle sensors: quantised readings from the truth.

Wheel odometry on MER counts the drive motors' encoder pulses (Ali et al. 2005, sec. 2.5). Each
wheel's actuator turns its wheel through a gearbox of about 1500:1 (JPL, Spirit sol 2113
release: "about 1,500 motor rotations for each full wheel rotation"). The motor encoder
resolution is not in our public sources; we take 16 counts per motor revolution
(approximate: a two-channel magnetic encoder read in quadrature), which gives 24,000
counts per wheel revolution, 0.26 mrad of wheel angle, or 34 um of travel on a 0.13 m
radius wheel. The encoder is incremental: it counts from zero at power-on with an unknown
sub-count phase (drawn uniformly), ``count = floor((theta - theta_on) / lsb + phase)``.
Backlash and gear compliance are not modelled.

The four corner wheels' steering angle is read absolutely by a potentiometer through an
ADC (approximate: 12 bits over 360 deg, LSB 0.088 deg, with 0.05 deg of electrical noise,
1 sigma); ``count = round((delta + noise) / lsb)``.

Frames and signs follow ``sim.rover.truth``: wheel angles are cumulative, positive rolling
forward; steering angles positive turn the wheel's front to the right (about body +z).
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
IntArray = NDArray[np.int64]

MER_DRIVE_GEAR_RATIO = 1500.0  # JPL Spirit sol 2113 release ("about 1,500")
MER_DRIVE_MOTOR_COUNTS_PER_REV = 16  # approximate (assumed; see the module docstring)


@dataclass(frozen=True)
class EncoderParams:
    """Resolution and noise of the mobility sensors (units in the names)."""

    motor_counts_per_rev: int = MER_DRIVE_MOTOR_COUNTS_PER_REV
    drive_gear_ratio: float = MER_DRIVE_GEAR_RATIO
    steer_adc_bits: int = 12  # approximate
    steer_range_rad: float = 2.0 * math.pi  # approximate: the ADC spans a full turn
    steer_noise_rad: float = math.radians(0.05)  # approximate, 1 sigma

    def __post_init__(self) -> None:
        if self.motor_counts_per_rev < 1:
            raise InputError("motor_counts_per_rev", "must be at least 1")
        if not (math.isfinite(self.drive_gear_ratio) and self.drive_gear_ratio > 0.0):
            raise InputError("drive_gear_ratio", "must be positive")
        if not 1 <= self.steer_adc_bits <= 24:
            raise InputError("steer_adc_bits", "must be in 1..24")
        if not (math.isfinite(self.steer_range_rad) and self.steer_range_rad > 0.0):
            raise InputError("steer_range_rad", "must be positive")
        if not (math.isfinite(self.steer_noise_rad) and self.steer_noise_rad >= 0.0):
            raise InputError("steer_noise_rad", "must be non-negative")

    @property
    def wheel_counts_per_rev(self) -> float:
        """Encoder counts per wheel revolution (24,000 by default)."""
        return float(self.motor_counts_per_rev * self.drive_gear_ratio)

    @property
    def wheel_lsb_rad(self) -> float:
        """Wheel angle per encoder count, radians."""
        return 2.0 * math.pi / self.wheel_counts_per_rev

    @property
    def steer_lsb_rad(self) -> float:
        """Steering angle per ADC count, radians."""
        return self.steer_range_rad / float(2**self.steer_adc_bits)


@dataclass(frozen=True)
class EncoderSamples:
    """Readings at the truth instants ``t_s`` (N,).

    ``wheel_counts`` (N, 6) incremental counts since power-on, ``WHEEL_NAMES`` order;
    ``steer_counts`` (N, 4) ADC counts and ``steer_rad`` (N, 4) the angle they encode,
    ``STEERED_WHEELS`` order.
    """

    t_s: FloatArray
    wheel_counts: IntArray
    steer_counts: IntArray
    steer_rad: FloatArray


class MobilityEncoders:
    """The six wheel encoders and four steering sensors of one rover.

    The wheel encoders' reference angle and phase are fixed at the first reading, so counts
    continue across the truth segments the simulator produces one at a time.
    """

    def __init__(self, params: EncoderParams, rng: np.random.Generator):
        self._p = params
        self._rng = rng
        self._phase = rng.uniform(0.0, 1.0, 6)
        self._theta_on_rad: FloatArray | None = None

    def state(self) -> dict[str, Any]:
        """The counts' phase and reference angle and the noise generator (plain data)."""
        theta = self._theta_on_rad
        return {
            "phase": self._phase.copy(),
            "theta_on_rad": None if theta is None else theta.copy(),
            "rng": self._rng.bit_generator.state,
        }

    def load_state(self, state: Mapping[str, Any]) -> None:
        """Load ``state`` (``state()``) onto encoders built from the same parameters."""
        self._phase = np.array(state["phase"], dtype=np.float64)
        theta = state["theta_on_rad"]
        self._theta_on_rad = None if theta is None else np.array(theta, dtype=np.float64)
        self._rng.bit_generator.state = state["rng"]

    @property
    def params(self) -> EncoderParams:
        return self._p

    def read(self, truth: TruthTrajectory) -> EncoderSamples:
        """Quantised readings of ``truth.wheel_angle_rad`` and ``truth.steer_rad``."""
        wheel = truth.wheel_angle_rad
        steer = truth.steer_rad
        if not (np.all(np.isfinite(wheel)) and np.all(np.isfinite(steer))):
            raise InputError("truth", "wheel or steering angles are not finite")
        if self._theta_on_rad is None:
            self._theta_on_rad = wheel[0].copy()
        counts_f = (wheel - self._theta_on_rad[None, :]) / self._p.wheel_lsb_rad + self._phase
        wheel_counts = np.floor(counts_f).astype(np.int64)

        noisy = steer + self._p.steer_noise_rad * self._rng.standard_normal(steer.shape)
        half_range = 2 ** (self._p.steer_adc_bits - 1)
        steer_counts = np.clip(
            np.rint(noisy / self._p.steer_lsb_rad), -half_range, half_range - 1
        ).astype(np.int64)
        return EncoderSamples(
            truth.t_s.copy(),
            wheel_counts,
            steer_counts,
            steer_counts.astype(np.float64) * self._p.steer_lsb_rad,
        )

    def wheel_angle_rad(self, counts: IntArray) -> FloatArray:
        """Wheel rotation since power-on that ``counts`` encode (what odometry uses)."""
        out: FloatArray = np.asarray(counts, dtype=np.float64) * self._p.wheel_lsb_rad
        return out
