"""A dragged wheel: not driven, it slides; what it costs the five driven wheels, and the yaw.

From sol 125 Spirit's right front wheel drew too much current and was left undriven and
dragged on many drives; visual odometry bounded the position error that dragging added
(Cheng, Maimone and Matthies 2005, sec. 4.2). A drive command may name such a wheel
(``drag_wheel``), and the test conductor may fail a wheel's motor without telling the flight
software (``RoverSim.failed_wheel``): either way that wheel is dragged.

The model, in the terms of ``sim.rover.slip`` (Wong, *Theory of Ground Vehicles*, ch. 2;
Bekker 1969; Janosi and Hanamoto 1961), each wheel carrying a sixth of the weight and of the
traction limit (``h_w = H_max / 6``, rolling resistance ``r_w = R / 6``):

- The dragged wheel slides (its 1500:1 gear train is hardly back-driven): the soil under it
  is sheared through a large displacement, so it resists with the full Mohr-Coulomb shear
  strength of its contact patch, ``c A + N tan φ = h_w`` (the shear law at ``j -> ∞``), plus
  the compaction resistance it still makes, ``r_w``: ``F_d = h_w + r_w`` per dragged wheel.
  It rolls ``roll_fraction`` of the ground it travels (assumption, 5 %: "little"), which is
  what its encoder reads.
- The driven wheels of each side turn at the commanded rate, each side's at one slip. Their
  net pulls ``u_L``, ``u_R`` (thrust less rolling resistance, summed over the side's driven
  wheels) balance the grade ``G = W sin θ_a`` and the drag, and the yaw moment about the
  body origin (z down, y right: a pull ``f`` at ``y`` has moment ``-y f``)::

      u_L + u_R = G + Σ F_d
      (B/2) (u_L - u_R) + Σ y_d F_d + M_lat(κ) = 0

  so the dragged side's driven wheels pull the more. Each wheel's slip follows from its
  thrust ``h = r_w + u / n`` by the shear law inverted (``sim.rover.slip``):
  ``s = -(K/L) ln(1 - h / h_w)``.
- Unequal slips make the rover yaw as a skid-steered vehicle does (Wong, ch. 7, kinematics
  of skid steering): the sides move at ``v (1 - s_L)`` and ``v (1 - s_R)``, so the heading
  changes by ``κ = (s_R - s_L) / B`` per commanded metre, towards the dragged side. The
  yaw is resisted by the corner wheels, pushed sideways at ``x_j κ`` per metre: the lateral
  shear law gives each ``h_w (1 - exp(-|x_j κ| / (K/L)_lat))``, a moment
  ``M_lat = -sgn(κ) Σ |x_j| h_w (1 - exp(-|x_j κ| / (K/L)_lat))`` (the dragged wheel's own
  lateral force, already sliding, is left out). ``κ`` is the fixed point of
  ``κ = (s_R(κ) - s_L(κ)) / B``, found by bisection (the right side decreases with ``κ``).
- The body slips the mean of the two sides, ``(s_L + s_R) / 2``; ``path_effect`` returns
  that less the six-wheel slip of ``sim.rover.slip.slip_curve`` (the model's own, noise
  and all, is kept and this is added), and ``κ``. With no dragged wheel the balance gives
  ``κ = 0`` and the six-wheel slip exactly.
- A turn in place with a dragged corner wheel: the five driven wheels also turn the
  dragged one round, a moment ``F_d |r_d|`` (``r_d`` its distance from the turn centre),
  so their thrust per wheel grows by ``F_d |r_d| / (n r̄)`` (``r̄`` the driven wheels' mean
  distance): the turn slips more. Its lateral push on the body is not modelled.

Lateral creep and sinkage follow the driven wheels' slip as in ``sim.rover.slip``; the
traction ellipse between a wheel's pull and its side force is not applied here. A commanded
slip (``SlipParams.slip_range``, benchmarks) gets the drag's extra slip added too.

What it gives: on level Gusev soil one dragged wheel adds about 5.5 % to the six-wheel
2.2 % slip and veers the rover about 3° per metre towards it; on bedrock 4 % and 2.3° per
metre. Our sources give no figure for Spirit's veer or slip while dragging, so these are
the model's figures, not a calibration. With the ideal rolling of ``SlipModel.ideal`` there
is no slip, so no extra slip or veer either: the dragged wheel still rolls little.

Wheel order: ``sim.rover.truth.WHEEL_NAMES``; commands name wheels as
``estimation.geometry.WHEEL_KEYS`` (lower case, the same order).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from estimation.geometry import WHEEL_KEYS
from sim.errors import InputError
from sim.rover.geometry import LEFT, RIGHT, RoverGeometry
from sim.rover.slip import SlipModel, SlipParams, SlipSample, _loads, _shear_law
from sim.world.terrain import Soil

FloatArray = NDArray[np.float64]

ROLL_FRACTION = 0.05  # assumption: a dragged wheel rolls 5 % of the ground it slides over
BISECTIONS = 60  # halvings of the yaw bracket: far below float resolution of κ


@dataclass(frozen=True)
class Drag:
    """The dragged wheels of a drive: ``wheels`` their indices in the wheel order (sorted,
    distinct, at most two a side so that each side keeps a driven wheel), and the fraction
    of its ground travel a dragged wheel rolls."""

    wheels: tuple[int, ...]
    roll_fraction: float = ROLL_FRACTION

    def __post_init__(self) -> None:
        w = self.wheels
        if not w or list(w) != sorted(set(w)) or not all(0 <= i < 6 for i in w):
            raise InputError("drag_wheel", f"must be distinct wheels of 0..5, got {w!r}")
        if set(LEFT) <= set(w) or set(RIGHT) <= set(w):
            raise InputError("drag_wheel", "a side needs at least one driven wheel")
        if not (math.isfinite(self.roll_fraction) and 0.0 <= self.roll_fraction <= 1.0):
            raise InputError("roll_fraction", f"must be in [0, 1], got {self.roll_fraction}")

    @classmethod
    def of(cls, *keys: str | None) -> Drag | None:
        """The drag of the wheels ``keys`` names (``WHEEL_KEYS``; None skipped, repeats
        once); None when no wheel is named.

        >>> Drag.of(None, "rf", "rf")
        Drag(wheels=(3,), roll_fraction=0.05)
        """
        idx = set()
        for key in keys:
            if key is None:
                continue
            if not isinstance(key, str) or key not in WHEEL_KEYS:
                raise InputError(
                    "drag_wheel", f"must be one of {', '.join(WHEEL_KEYS)}, got {key!r}"
                )
            idx.add(WHEEL_KEYS.index(key))
        return cls(tuple(sorted(idx))) if idx else None

    def mask(self) -> NDArray[np.bool_]:
        """Dragged wheels, (6,) in the wheel order."""
        out = np.zeros(6, dtype=bool)
        out[list(self.wheels)] = True
        return out

    def side_slips(
        self,
        soil: Soil,
        tan_along: FloatArray,
        tan_cross: FloatArray,
        kappa_per_m: FloatArray,
        params: SlipParams,
        geometry: RoverGeometry,
    ) -> tuple[FloatArray, FloatArray]:
        """Slip of the left and of the right driven wheels at yaw ``kappa_per_m`` (rad per
        commanded metre, > 0 to the right), from the force and moment balance (module
        docstring); arrays of the slopes' shape."""
        along, _, rolling, h_max = _loads(soil, tan_along, tan_cross, geometry)
        h_w, r_w = h_max / 6.0, rolling / 6.0
        f_d = h_w + r_w  # the dragged wheel's resistance: shear strength plus compaction
        dragged = self.mask()
        xy = geometry.wheel_xy_b()
        n_left = sum(1 for i in LEFT if not dragged[i])
        n_right = sum(1 for i in RIGHT if not dragged[i])
        y_drag = float(np.sum(xy[dragged, 1]))  # Σ y_d: the drag's moment over F_d
        corners = np.abs(xy[(~dragged) & (xy[:, 0] != 0.0), 0])  # |x_j| of driven corners
        k = np.asarray(kappa_per_m, dtype=np.float64)
        side = np.abs(k)[..., None] * corners / params.lateral_shear_ratio
        m_lat = -np.sign(k) * h_w * np.sum(corners * -np.expm1(-side), axis=-1)
        half = 0.5 * geometry.track_m
        total = along + len(self.wheels) * f_d
        turn = (y_drag * f_d + m_lat) / half
        u_left, u_right = 0.5 * (total - turn), 0.5 * (total + turn)
        s_left = _shear_law((r_w + u_left / n_left) / h_w, params.shear_ratio, params.slip_max)
        s_right = _shear_law((r_w + u_right / n_right) / h_w, params.shear_ratio, params.slip_max)
        return s_left, s_right

    def path_effect(
        self,
        soil: Soil,
        tan_along: FloatArray,
        tan_cross: FloatArray,
        params: SlipParams,
        geometry: RoverGeometry,
    ) -> tuple[FloatArray, FloatArray]:
        """``(extra slip, κ)`` of a drive along a path at these slopes: the body's slip
        beyond the six-wheel model's, and the yaw in rad per commanded metre (> 0 to the
        right, towards a dragged right wheel). Arrays of the slopes' shape."""
        ta = np.asarray(tan_along, dtype=np.float64)
        tc = np.asarray(tan_cross, dtype=np.float64)
        track = geometry.track_m

        def excess(k: FloatArray) -> FloatArray:  # κ - g(κ): increasing in κ
            s_l, s_r = self.side_slips(soil, ta, tc, k, params, geometry)
            out: FloatArray = k - (s_r - s_l) / track
            return out

        k0 = -excess(np.zeros(ta.shape))  # the yaw with no lateral resistance
        lo, hi = np.minimum(k0, 0.0), np.maximum(k0, 0.0)
        for _ in range(BISECTIONS):
            mid = 0.5 * (lo + hi)
            above = excess(mid) > 0.0
            hi, lo = np.where(above, mid, hi), np.where(above, lo, mid)
        kappa = 0.5 * (lo + hi)
        s_l, s_r = self.side_slips(soil, ta, tc, kappa, params, geometry)
        along, _, rolling, h_max = _loads(soil, ta, tc, geometry)
        six = _shear_law((along + rolling) / h_max, params.shear_ratio, params.slip_max)
        extra: FloatArray = 0.5 * (s_l + s_r) - six
        return extra, kappa

    def turn_extra_slip(
        self, soil: Soil, slope_rad: FloatArray, params: SlipParams, geometry: RoverGeometry
    ) -> FloatArray:
        """The turn-rate slip a turn in place on a fall-line slope ``slope_rad`` gets beyond
        the six-wheel model's (``sim.rover.slip.turn_slip_curve``): the driven wheels also
        turn the dragged ones round (module docstring)."""
        t = np.tan(np.abs(np.asarray(slope_rad, dtype=np.float64)))
        zero = np.zeros(t.shape)
        along, _, rolling, h_max = _loads(soil, t, zero, geometry)
        h_w, r_w = h_max / 6.0, rolling / 6.0
        dragged = self.mask()
        xy = geometry.wheel_xy_b()
        dist = np.hypot(xy[:, 0], xy[:, 1])
        n = int(np.count_nonzero(~dragged))
        moment = (h_w + r_w) * float(np.sum(dist[dragged]))  # Σ F_d |r_d|
        pull = along + n * r_w + moment / float(np.mean(dist[~dragged]))
        dragged_slip = _shear_law(pull / (n * h_w), params.shear_ratio, params.slip_max)
        six = _shear_law((along + rolling) / h_max, params.shear_ratio, params.slip_max)
        out: FloatArray = dragged_slip - six
        return out

    def path_sample(
        self, model: SlipModel, tan_along: FloatArray, tan_cross: FloatArray, sample: SlipSample
    ) -> tuple[SlipSample, FloatArray]:
        """A path step's slip ``sample`` (``SlipModel.drive``'s) with the extra slip of the
        dragged wheels added (capped, the sinkage following), and their yaw ``κ`` (rad per
        commanded metre)."""
        extra, kappa = self.path_effect(
            model.soil, tan_along, tan_cross, model.params, model.geometry
        )
        return _with_slip(model, sample, sample.slip + extra), kappa

    def turn_sample(
        self, model: SlipModel, slope_rad: FloatArray, sample: SlipSample
    ) -> SlipSample:
        """A turn step's slip ``sample`` (``SlipModel.turn``'s) with the dragged wheels'
        extra turn slip added."""
        extra = self.turn_extra_slip(model.soil, slope_rad, model.params, model.geometry)
        return _with_slip(model, sample, sample.slip + extra)

    def wheel_rad(self, wheel_rad: FloatArray, slip: FloatArray) -> FloatArray:
        """The wheels' cumulative rotation (K + 1, 6) from the commanded ``wheel_rad`` with
        the dragged wheels rolling ``roll_fraction`` of their ground travel, the commanded
        roll times ``1 - slip`` of each step (``slip`` (K,), the body's)."""
        out = wheel_rad.copy()
        d = list(self.wheels)
        steps = np.diff(wheel_rad[:, d], axis=0) * (1.0 - slip)[:, None] * self.roll_fraction
        out[1:, d] = wheel_rad[0, d] + np.cumsum(steps, axis=0)
        return out


def _with_slip(model: SlipModel, sample: SlipSample, slip: FloatArray) -> SlipSample:
    """``sample`` with the longitudinal slip ``slip`` (capped) and the sinkage it brings."""
    cap = model.params.slip_max
    s = np.clip(slip, -cap, cap)
    return SlipSample(s, sample.creep, model.sinkage_m(s))
