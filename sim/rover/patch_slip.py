"""Slip, creep and sinkage on the soil under the rover: soil patches and embedding soils.

``PatchSlipModel`` is ``sim.rover.slip.SlipModel`` with a ``SoilMap``
(``sim.world.soil_patches``): each control step takes the soil at the body origin where the
step starts (the drive primitives pass the poses, ``sim.rover.drive``) and applies the same
vehicle-level terramechanics to it (Wong, ch. 2; Bekker 1969; Janosi and Hanamoto 1961;
the slip-sinkage of Lyasko 2010 and Ding et al. 2011, linearised). Where no patch lies under
the rover the base model runs unchanged, draws and arithmetic alike, so a run without
patches is bit for bit the run of ``SlipModel``.

Embedding soils (``Soil.embedding``, a sand trap such as the Purgatory ripple) differ in
three ways, each of them something the base model's limits leave out:

- Sinkage ``z = z0 (1 + k_z max(s, 0))`` is capped at ``EMBEDDING_SINKAGE_FRACTION`` (0.9)
  of the wheel radius, the hubs, instead of ``SlipParams.max_sinkage_fraction`` (0.3):
  Opportunity sank to its hubs at Purgatory (the MER mission's sol reports, sol 446).
- Stall: with a deep static sinkage Bekker's compaction resistance
  ``f_r = 0.75 sqrt(z / 2r)`` can exceed what the soil holds (``ρ = H_req / H_max >= 1``
  on level ground). The shear law then runs to its cap ``slip_max`` (> 1: sliding back),
  which is right only when the grade alone, ``W sin θ_a``, exceeds the traction limit
  ``H_max``; a resistance cannot push the rover backwards, so otherwise the wheels spin
  in place: slip is capped at 1 (100 %), the noise included.
- Lateral hold: the traction ellipse leaves a wheel that spends all its shear on thrust
  nothing to hold a cross slope, so the base law would let a stalled rover creep sideways
  at ``slip_max`` of the rolled distance on any tilt. A wheel sunk in its rut is held
  sideways by the rut's wall (the passive earth pressure behind Wong's bulldozing
  resistance, ch. 2), so on an embedding soil the creep law takes the cross-slope weight
  against the whole traction limit, ``ρ_c = W sin θ_c / H_max`` (assumption).

In a patch's rim (``SoilPatch.rim_m``) each step takes its own graded soil
(``sim.world.soil_patches.blend_soil``), so a rover sinks in over the rim.

Shapes follow ``SlipModel``: the position arrays broadcast with the slopes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimation.mars_constants import MARS_GRAVITY_M_S2
from sim.rover.slip import SlipModel, SlipSample, _shear_law, slip_curve, turn_slip_curve
from sim.world.soil_patches import SoilMap, blend_soil
from sim.world.terrain import EMBEDDING_SINKAGE_FRACTION, Soil

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]


@dataclass
class PatchSlipModel(SlipModel):
    """``SlipModel`` on the soil under the rover: ``soil_map``'s patches over ``soil``.

    ``soil_map`` None or empty, or no position given: exactly ``SlipModel``. The map is
    shared, not copied: patches added to it apply from the next control step computed.
    """

    soil_map: SoilMap | None = None

    def _soil_index(
        self, x_m: ArrayLike | None, y_m: ArrayLike | None, shape: tuple[int, ...]
    ) -> IntArray | None:
        """Index of the soil at each step (0 the base), or None where every step is on
        the base soil (the base model then runs as it always has)."""
        if self.soil_map is None or len(self.soil_map) == 0 or x_m is None or y_m is None:
            return None
        idx = np.broadcast_to(self.soil_map.index_at(x_m, y_m), shape)
        return idx if bool(np.any(idx)) else None

    def _soils(self, idx: IntArray, x_m: ArrayLike, y_m: ArrayLike) -> list[tuple[Soil, BoolArray]]:
        """The soils under the steps and which steps stand on each: a patch's own soil
        where its weight is 1, a graded one (``blend_soil``) for each weight in a rim."""
        assert self.soil_map is not None
        soils = self.soil_map.soils()
        weight = self.soil_map.weight_at(x_m, y_m, idx)
        out: list[tuple[Soil, BoolArray]] = []
        for k in np.unique(idx):
            on = idx == k
            if k == 0:
                out.append((self.soil, on))
                continue
            full = on & (weight >= 1.0)
            if bool(np.any(full)):
                out.append((soils[int(k)], full))
            rim = on & ~full
            for w in np.unique(weight[rim]):  # a rim's weights come in RIM_LEVELS steps
                soil = blend_soil(self.soil, soils[int(k)], float(w))
                out.append((soil, rim & (weight == w)))
        return out

    def _traction(self, soil: Soil, cos_total: FloatArray) -> FloatArray:
        """The traction limit ``H_max = c A + W cos θ tan φ`` (N), as ``sim.rover.slip``."""
        weight = self.geometry.mass_kg * MARS_GRAVITY_M_S2
        r = self.geometry.wheel_radius_m
        area = 6.0 * self.geometry.wheel_width_m * math.sqrt(2.0 * r * soil.sinkage_m)
        out: FloatArray = soil.cohesion_kpa * 1e3 * area + weight * cos_total * math.tan(
            math.radians(soil.friction_angle_deg)
        )
        return out

    def _stall_cap(self, soil: Soil, tan_grade: FloatArray, cos_total: FloatArray) -> FloatArray:
        """The largest slip on an embedding soil: 1 where the grade alone, ``W sin θ``, is
        within the traction limit ``H_max = c A + W cos θ tan φ``, else ``slip_max``."""
        weight = self.geometry.mass_kg * MARS_GRAVITY_M_S2
        h_max = self._traction(soil, cos_total)
        grade = weight * np.abs(tan_grade) / np.sqrt(1.0 + tan_grade**2)
        out: FloatArray = np.where(grade < h_max, 1.0, self.params.slip_max)
        return out

    def _soil_sinkage(self, soil: Soil, slip: FloatArray) -> FloatArray:
        """``z0 (1 + k_z max(s, 0))`` on ``soil``, capped at the hubs for an embedding soil."""
        p = self.params
        cap = EMBEDDING_SINKAGE_FRACTION if soil.embedding else p.max_sinkage_fraction
        z = soil.sinkage_m * (1.0 + p.slip_sinkage_gain * np.maximum(slip, 0.0))
        out: FloatArray = np.minimum(z, cap * self.geometry.wheel_radius_m)
        return out

    def _embedded_creep(self, soil: Soil, tan_cross: FloatArray) -> FloatArray:
        """Creep (fraction of the rolled distance, positive right) held by the ruts: the
        shear law for ``W sin θ_c`` against the whole traction limit (module docstring)."""
        weight = self.geometry.mass_kg * MARS_GRAVITY_M_S2
        cos_c = 1.0 / np.sqrt(1.0 + tan_cross**2)
        h_max = self._traction(soil, cos_c)
        rho = weight * tan_cross * cos_c / h_max
        out: FloatArray = -_shear_law(rho, self.params.lateral_shear_ratio, self.params.slip_max)
        return out

    def _on_soil(
        self, soil: Soil, along: FloatArray, cross: FloatArray, noise: FloatArray, turning: bool
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Slip, creep and sinkage of steps on one soil (1-D arrays, noise (n, 2))."""
        cap = self.params.slip_max
        if turning:
            s, c = turn_slip_curve(soil, along, self.params, self.geometry)
            if soil.embedding:
                c = np.abs(self._embedded_creep(soil, np.tan(along)))
            c = np.clip(c + noise[:, 1], 0.0, cap)
        else:
            s, c = slip_curve(soil, along, cross, self.params, self.geometry)
            if soil.embedding:
                c = self._embedded_creep(soil, np.tan(cross))
            c = np.clip(c + noise[:, 1], -cap, cap)
        s = self._longitudinal(s, noise)
        if soil.embedding and self.params.slip_range is None:
            ta, tc = np.tan(along), np.tan(cross)
            s = np.minimum(s, self._stall_cap(soil, ta, 1.0 / np.sqrt(1.0 + ta**2 + tc**2)))
        return s, c, self._soil_sinkage(soil, s)

    def _by_soil(
        self,
        soils: list[tuple[Soil, BoolArray]],
        along: FloatArray,
        cross: FloatArray,
        noise: FloatArray,
        turning: bool,
    ) -> SlipSample:
        shape = soils[0][1].shape
        a = np.broadcast_to(along, shape).reshape(-1)
        c = np.broadcast_to(cross, shape).reshape(-1)
        nz = np.broadcast_to(noise, (*shape, 2)).reshape(-1, 2)
        out = np.empty((3, a.size))
        for soil, on in soils:
            m = on.reshape(-1)
            out[:, m] = self._on_soil(soil, a[m], c[m], nz[m], turning)
        slip, creep, sink = (v.reshape(shape) for v in out)
        return SlipSample(slip, creep, sink)

    def drive(
        self,
        along_slope_rad: ArrayLike,
        cross_slope_rad: ArrayLike,
        noise: FloatArray,
        *,
        x_m: ArrayLike | None = None,
        y_m: ArrayLike | None = None,
    ) -> SlipSample:
        """``SlipModel.drive`` on the soil at ``(x_m, y_m)`` (Site frame, m) of each step."""
        a = np.asarray(along_slope_rad, dtype=float)
        c = np.asarray(cross_slope_rad, dtype=float)
        shape = np.broadcast_shapes(a.shape, c.shape, np.shape(noise)[:-1])
        idx = None if self.no_slip else self._soil_index(x_m, y_m, shape)
        if idx is None:
            return super().drive(a, c, noise)
        soils = self._soils(idx, x_m, y_m)  # type: ignore[arg-type]
        return self._by_soil(soils, a, c, np.asarray(noise, dtype=float), turning=False)

    def turn(
        self,
        slope_rad: ArrayLike,
        noise: FloatArray,
        *,
        x_m: ArrayLike | None = None,
        y_m: ArrayLike | None = None,
    ) -> SlipSample:
        """``SlipModel.turn`` on the soil at ``(x_m, y_m)`` (Site frame, m) of each step."""
        slope = np.abs(np.asarray(slope_rad, dtype=float))
        shape = np.broadcast_shapes(slope.shape, np.shape(noise)[:-1])
        idx = None if self.no_slip else self._soil_index(x_m, y_m, shape)
        if idx is None:
            return super().turn(slope_rad, noise)
        soils = self._soils(idx, x_m, y_m)  # type: ignore[arg-type]
        return self._by_soil(soils, slope, np.zeros(()), np.asarray(noise, dtype=float), True)

    def sinkage_m(
        self, slip: ArrayLike, *, x_m: ArrayLike | None = None, y_m: ArrayLike | None = None
    ) -> FloatArray:
        """``SlipModel.sinkage_m`` on the soil at ``(x_m, y_m)`` (Site frame, m)."""
        s = np.asarray(slip, dtype=float)
        idx = None if self.no_slip else self._soil_index(x_m, y_m, s.shape)
        if idx is None:
            return super().sinkage_m(s)
        out = np.empty(s.shape)
        for soil, on in self._soils(idx, x_m, y_m):  # type: ignore[arg-type]
            out[on] = self._soil_sinkage(soil, s[on])
        return out
