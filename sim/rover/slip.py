"""Wheel slip, lateral creep and sinkage of the rover on a soil, from the local slope.

A terramechanics-flavoured model (Wong, *Theory of Ground Vehicles*, 4th ed., ch. 2;
Bekker 1969), reduced to the whole vehicle:

- Traction limit (Mohr-Coulomb over the contact area ``A`` of the six wheels)::

      H_max = c A + W cos(θ) tan(φ)

  with ``W = m g`` the rover's weight, ``θ`` the total slope, ``φ`` the soil friction
  angle, ``c`` its cohesion; ``A = 6 b L`` with the contact length of a rigid wheel sunk
  by ``z``: ``L = sqrt(2 r z)``.
- Thrust needed to climb: the along-track weight component plus the compaction (rolling)
  resistance of a rigid wheel, Bekker's ``R_c / W = 3 / ((n+1)(3-n)) sqrt(z / 2r)`` with
  the exponent ``n = 1``::

      H_req = W (sin θ_a + f_r cos θ),   f_r = 0.75 sqrt(z / (2 r))

- Slip from the shear stress-displacement law ``τ = τ_max (1 - exp(-j / K))`` (Janosi and
  Hanamoto 1961) with the shear displacement at the rear of the contact ``j = s L``:
  ``H(s) = H_max (1 - exp(-s L / K))``, inverted::

      s = -(K / L) ln(1 - ρ),   ρ = H_req / H_max

  small on level ground, growing with uphill slope and infinite as ``ρ -> 1``: the slope
  at which the soil cannot hold the rover (just below the friction angle, because of the
  rolling resistance). Beyond it the rover slides back: ``s`` is capped at ``slip_max``
  (> 1, MER measured up to 125 %, Cheng, Maimone and Matthies 2005 and docs/REFERENCES.md). Downhill
  ``ρ < 0`` and the same law, odd in ``ρ``, gives skid (``s < 0``).
- Lateral creep on a cross slope: the same law for the cross-slope weight component
  against the traction left over by the longitudinal thrust (the traction ellipse, Wong
  ch. 2), directed downslope, as a fraction of the rolled distance.
- Slip-sinkage (Lyasko 2010; Ding et al. 2011, linearised): ``z = z0 (1 + k_z max(s, 0))``,
  so a digging wheel sinks deeper and the rover rides lower: ``sim.rover.settle`` puts the wheel
  centres ``r - z`` above the surface. Slip is on the undeformed radius (Wong, ch. 2).

With the default parameters the curve reproduces MER's experience (Ali et al. 2005 section 4;
Maimone et al. 2007): a few % on level ground, tens of % at 15-20° on loose sand, 100 %
and more (sliding back) from ~24° on sand and ~34° on Gusev soil.

The random part is a first-order Gauss-Markov process in *rolled distance*, one for the
longitudinal slip and one for the lateral creep fraction:
``e_k = φ_k e_{k-1} + σ sqrt(1 - φ_k²) w_k``, ``φ_k = exp(-Δd_k / λ)``, ``w_k ~ N(0, 1)``
(the exact discretisation of the continuous process, so its statistics do not depend on
the step size).

Signs: the along-track slope is positive uphill along the heading; the cross slope is
positive when the ground rises to the rover's right; lateral creep is positive to the
right, so it takes the sign opposite to the cross slope.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.signal import lfilter

from estimation.mars_constants import MARS_GRAVITY_M_S2
from sim.errors import InputError
from sim.rover.geometry import MER_GEOMETRY, RoverGeometry
from sim.world.terrain import Soil

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class SlipParams:
    """Parameters of the slip model (dimensionless unless the name says otherwise)."""

    # K / L: shear-deformation modulus over contact length. Wong gives K ~ 1-2.5 cm for
    # dry sands; with L ~ 7 cm for a MER wheel at ~1 cm sinkage, 0.15 (calibrated so
    # level-ground slip is a few % as on MER).
    shear_ratio: float = 0.15
    lateral_shear_ratio: float = 0.15  # the same law sideways (assumption)
    slip_max: float = 1.5  # cap on |s| and |creep|: beyond the traction limit (assumption)
    sigma_slip: float = 0.02  # std of the correlated slip noise (assumption: ~2 %)
    sigma_creep: float = 0.01  # std of the correlated lateral creep noise (assumption)
    correlation_length_m: float = 0.5  # Gauss-Markov correlation distance (assumption)
    slip_sinkage_gain: float = 1.0  # k_z: sinkage doubles at 100 % slip (assumption)
    max_sinkage_fraction: float = 0.3  # sinkage capped at this fraction of the radius
    # Commanded slip (benchmarks): ``(lo, hi)`` replaces the longitudinal slip of the model
    # by one draw, uniform in [lo, hi], per drive primitive (``SlipModel.noise`` call), held
    # over it; creep and sinkage still follow the model. None: the terramechanics above.
    slip_range: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        for name in (
            "shear_ratio",
            "lateral_shear_ratio",
            "slip_max",
            "correlation_length_m",
            "max_sinkage_fraction",
        ):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise InputError(name, f"must be finite and > 0, got {value}")
        for name in ("sigma_slip", "sigma_creep", "slip_sinkage_gain"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise InputError(name, f"must be finite and >= 0, got {value}")
        if self.max_sinkage_fraction >= 1.0:
            raise InputError("max_sinkage_fraction", "must be below 1")
        if self.slip_range is not None and not _is_slip_range(self.slip_range):
            raise InputError(
                "slip_range", f"must be (lo, hi) with 0 <= lo <= hi < 1, got {self.slip_range!r}"
            )


def _is_slip_range(value: object) -> bool:
    """Whether ``value`` is a pair of numbers ``0 <= lo <= hi < 1``."""
    if not isinstance(value, tuple) or len(value) != 2:
        return False
    if not all(isinstance(v, int | float) and not isinstance(v, bool) for v in value):
        return False
    lo, hi = value
    return bool(0.0 <= lo <= hi < 1.0)


@dataclass(frozen=True)
class SlipSample:
    """Slip state per step, arrays of one shape: longitudinal slip ratio
    ``1 - v_actual / v_wheel``, lateral creep as a fraction of the rolled distance
    (positive to the right), wheel sinkage (m)."""

    slip: FloatArray
    creep: FloatArray
    sinkage_m: FloatArray


def _shear_law(rho: FloatArray, ratio: float, cap: float) -> FloatArray:
    """``-sign(ρ) (K/L) ln(1 - |ρ|)``, capped at ``cap`` (also where ``|ρ| >= 1``)."""
    a = np.abs(rho)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(a < 1.0, -ratio * np.log1p(-np.minimum(a, 1.0)), np.inf)
    out: FloatArray = np.sign(rho) * np.minimum(s, cap)
    return out


def _loads(
    soil: Soil, tan_along: FloatArray, tan_cross: FloatArray, geometry: RoverGeometry
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Weight components and traction limit (N): (along, cross, rolling resistance, H_max)."""
    weight = geometry.mass_kg * MARS_GRAVITY_M_S2
    r, z0 = geometry.wheel_radius_m, soil.sinkage_m
    cos_total = 1.0 / np.sqrt(1.0 + tan_along**2 + tan_cross**2)
    along = weight * tan_along / np.sqrt(1.0 + tan_along**2)  # W sin θ_a
    cross = weight * tan_cross / np.sqrt(1.0 + tan_cross**2)  # W sin θ_c
    f_r = 0.75 * math.sqrt(z0 / (2.0 * r))  # Bekker compaction resistance, n = 1
    rolling = weight * f_r * cos_total
    area = 6.0 * geometry.wheel_width_m * math.sqrt(2.0 * r * z0)  # six contact patches
    h_max = soil.cohesion_kpa * 1e3 * area + weight * cos_total * math.tan(
        math.radians(soil.friction_angle_deg)
    )
    return along, cross, rolling, h_max


def slip_curve(
    soil: Soil,
    along_slope_rad: ArrayLike,
    cross_slope_rad: ArrayLike = 0.0,
    params: SlipParams | None = None,
    geometry: RoverGeometry = MER_GEOMETRY,
) -> tuple[FloatArray, FloatArray]:
    """Deterministic longitudinal slip and lateral creep while driving, broadcast arrays.

    ``along_slope_rad``: slope along the heading, positive uphill; ``cross_slope_rad``:
    positive when the ground rises to the right. Returns ``(slip, creep)``: slip ratio
    ``1 - v_actual / v_wheel`` and lateral creep per metre rolled (positive right).

    >>> from sim.world.terrain import GUSEV_SOIL
    >>> s, c = slip_curve(GUSEV_SOIL, 0.0)
    >>> bool(0.01 < s < 0.05), float(c) == 0.0
    (True, True)
    """
    p = params or SlipParams()
    ta = np.tan(np.asarray(along_slope_rad, dtype=float))
    tc = np.tan(np.asarray(cross_slope_rad, dtype=float))
    along, cross, rolling, h_max = _loads(soil, ta, tc, geometry)
    h_long = along + rolling
    slip = _shear_law(h_long / h_max, p.shear_ratio, p.slip_max)
    # Traction ellipse: what the longitudinal thrust leaves for holding the cross slope.
    left = np.sqrt(np.clip(h_max**2 - h_long**2, 1e-12, None))
    creep = -_shear_law(cross / left, p.lateral_shear_ratio, p.slip_max)
    return slip, creep


def turn_slip_curve(
    soil: Soil,
    slope_rad: ArrayLike,
    params: SlipParams | None = None,
    geometry: RoverGeometry = MER_GEOMETRY,
) -> tuple[FloatArray, FloatArray]:
    """Slip of the turn rate and downslope creep of a turn in place on a slope ``slope_rad``.

    During a turn in place the corner wheels push in every direction, some straight up
    the fall line, so we take the fall-line slope for both (assumption; MER saw large slips
    turning in place on slopes, Ali et al. 2005 section 4). Returns ``(slip, creep)``, creep a
    non-negative fraction of the mean rolled distance, directed down the fall line.
    """
    slope = np.abs(np.asarray(slope_rad, dtype=float))
    slip, _ = slip_curve(soil, slope, 0.0, params, geometry)
    _, creep = slip_curve(soil, 0.0, slope, params, geometry)
    out: FloatArray = np.abs(creep)
    return slip, out


@dataclass
class SlipModel:
    """Stateful stochastic slip of one rover on one soil.

    ``rng`` drives the Gauss-Markov noise; the same seed gives the same draws. With
    ``no_slip=True`` the wheels roll ideally: zero slip and creep and no sinkage (the
    effective radius is the wheel radius), and ``rng`` is not used.
    """

    soil: Soil
    rng: np.random.Generator | None = None
    params: SlipParams = field(default_factory=SlipParams)
    no_slip: bool = False
    geometry: RoverGeometry = MER_GEOMETRY
    noise_state: FloatArray = field(default_factory=lambda: np.zeros(2))  # (slip, creep) noise

    def __post_init__(self) -> None:
        if not self.no_slip and self.rng is None:
            raise InputError("rng", "a numpy.random.Generator is required unless no_slip")

    def state(self) -> dict[str, Any]:
        """The noise state, the generator and the parameters (a benchmark may change
        them) as plain data."""
        return {
            "noise_state": self.noise_state.copy(),
            "rng": None if self.rng is None else self.rng.bit_generator.state,
            "params": dataclasses.asdict(self.params),
        }

    def load_state(self, state: Mapping[str, Any]) -> None:
        """Load ``state`` (``state()``) onto a model built for the same soil."""
        self.noise_state = np.array(state["noise_state"], dtype=np.float64)
        if self.rng is not None:
            self.rng.bit_generator.state = state["rng"]
        params = dict(state["params"])
        if params.get("slip_range") is not None:
            params["slip_range"] = tuple(params["slip_range"])
        self.params = SlipParams(**params)

    @classmethod
    def ideal(cls, soil: Soil, geometry: RoverGeometry = MER_GEOMETRY) -> SlipModel:
        """Ideal rolling on ``soil``: no slip, no creep, no sinkage."""
        return cls(soil=soil, no_slip=True, geometry=geometry)

    def noise(self, step_distance_m: ArrayLike) -> FloatArray:
        """Draw the correlated noise for steps that roll ``step_distance_m`` each, (n, 2).

        Columns (slip, creep). Advances the internal state; exact for any step lengths.
        With ``params.slip_range`` the slip column is the commanded slip itself, one uniform
        draw for the whole call (``drive`` and ``turn`` then use it in place of the model).
        """
        d = np.asarray(step_distance_m, dtype=float).reshape(-1)
        if not np.all(np.isfinite(d)) or np.any(d < 0):
            raise InputError("step_distance_m", "must be finite and >= 0")
        out = np.zeros((d.shape[0], 2))
        if self.no_slip or d.shape[0] == 0:
            return out
        assert self.rng is not None
        p = self.params
        sigma = np.array([p.sigma_slip, p.sigma_creep])
        w = self.rng.standard_normal((d.shape[0], 2))
        # Runs of equal step length share one AR(1) coefficient: filter each run at once
        # (steps equal to 1e-9 relative count as equal: a schedule's float round-off).
        change = np.abs(np.diff(d)) > 1e-9 * np.maximum(d[1:], d[:-1])
        starts = np.concatenate([[0], np.flatnonzero(change) + 1, [d.shape[0]]])
        state = self.noise_state.copy()
        for lo, hi in itertools.pairwise(starts):
            phi = math.exp(-d[lo] / p.correlation_length_m)
            gain = math.sqrt(max(1.0 - phi * phi, 0.0))
            for j in range(2):
                x = sigma[j] * gain * w[lo:hi, j]
                y, _ = lfilter([1.0], [1.0, -phi], x, zi=[phi * state[j]])
                out[lo:hi, j] = y
                state[j] = y[-1]
        self.noise_state = state
        if p.slip_range is not None:
            out[:, 0] = self.rng.uniform(*p.slip_range)
        return out

    def _longitudinal(self, modelled: FloatArray, noise: FloatArray) -> FloatArray:
        """The slip of a step: the model's plus its noise, or the commanded slip."""
        if self.params.slip_range is not None:
            out: FloatArray = np.broadcast_to(noise[..., 0], modelled.shape).copy()
            return out
        return np.clip(modelled + noise[..., 0], -self.params.slip_max, self.params.slip_max)

    def sinkage_m(
        self, slip: ArrayLike, *, x_m: ArrayLike | None = None, y_m: ArrayLike | None = None
    ) -> FloatArray:
        """Sinkage (m) of the wheels at slip ``slip``: the soil's static sinkage, deeper
        with positive slip; zero in the no-slip mode. ``x_m``, ``y_m``: where the rover is
        (Site frame): one soil everywhere here, a model of soil patches uses them
        (``sim.rover.patch_slip``); the same holds for ``drive`` and ``turn``."""
        s = np.asarray(slip, dtype=float)
        if self.no_slip:
            return np.zeros(s.shape)
        p = self.params
        z = self.soil.sinkage_m * (1.0 + p.slip_sinkage_gain * np.maximum(s, 0.0))
        out: FloatArray = np.minimum(z, p.max_sinkage_fraction * self.geometry.wheel_radius_m)
        return out

    def drive(
        self,
        along_slope_rad: ArrayLike,
        cross_slope_rad: ArrayLike,
        noise: FloatArray,
        *,
        x_m: ArrayLike | None = None,
        y_m: ArrayLike | None = None,
    ) -> SlipSample:
        """Slip while driving at the given slopes, with ``noise`` from :meth:`noise`."""
        a = np.asarray(along_slope_rad, dtype=float)
        if self.no_slip:
            zero = np.zeros(np.broadcast_shapes(a.shape, np.shape(cross_slope_rad)))
            return SlipSample(zero, zero.copy(), zero.copy())
        s, c = slip_curve(self.soil, a, cross_slope_rad, self.params, self.geometry)
        cap = self.params.slip_max
        s = self._longitudinal(s, noise)
        c = np.clip(c + noise[..., 1], -cap, cap)
        return SlipSample(s, c, self.sinkage_m(s))

    def turn(
        self,
        slope_rad: ArrayLike,
        noise: FloatArray,
        *,
        x_m: ArrayLike | None = None,
        y_m: ArrayLike | None = None,
    ) -> SlipSample:
        """Slip of a turn in place on a slope: turn-rate slip and downslope creep (>= 0)."""
        slope = np.asarray(slope_rad, dtype=float)
        if self.no_slip:
            zero = np.zeros(slope.shape)
            return SlipSample(zero, zero.copy(), zero.copy())
        s, c = turn_slip_curve(self.soil, slope, self.params, self.geometry)
        cap = self.params.slip_max
        s = self._longitudinal(s, noise)
        c = np.clip(c + noise[..., 1], 0.0, cap)
        return SlipSample(s, c, self.sinkage_m(s))
