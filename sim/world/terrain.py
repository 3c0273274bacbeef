"""The terrain contract every surface in the simulator fulfils, and the analytic surfaces.

Coordinates are those of the Site frame (docs/CONVENTIONS.md): ``x`` North and ``y`` East in
metres; heights are elevations *up* in metres (the Site frame's ``z`` is Down, so a surface
point is ``(x, y, -h)`` in Site coordinates).

The analytic ``eq22`` surface is equation 22 of Balaram 2000, the undulating terrain
of its straight-line and turn-in-place simulations. The OCR of the paper misplaces a
bracket; we read it as two Gaussian bumps and a saddle term::

    h = 0.2 * (0.25 exp(-5 (6.25 (x-0.5)^2 + 6.25 (y-0.2)^2))
             - 0.25 exp(-4 (6.25 (x-0.5)^2 + 6.25 (y+0.2)^2))
             + 0.5 sin(0.75 x y))

which gives the ~5 cm bumps and the gentle undulation of the paper's Figure 3.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Soil:
    """Bulk soil properties that drive slip and sinkage (Bekker/Wong terramechanics).

    ``friction_angle_deg`` is the internal friction angle: the steepest slope the soil
    holds a wheel on, so slip grows without bound as the slope approaches it.
    ``cohesion_kpa`` adds traction independent of load. ``sinkage_m`` is the static sinkage
    of a MER wheel on level ground. Mars values from the MER soil-mechanics results
    (Sullivan et al. 2011 and Arvidson et al. 2004): friction 30-37 deg, cohesion 0-5 kPa.

    ``embedding``: loose enough for the wheels to dig in to their hubs: sinkage may reach
    ``EMBEDDING_SINKAGE_FRACTION`` of the wheel radius instead of the slip model's usual cap,
    and where the soil cannot carry its own rolling resistance the wheels spin in place
    (slip 100 %) rather than push the rover backwards (``sim.rover.patch_slip``).
    """

    name: str
    friction_angle_deg: float
    cohesion_kpa: float
    sinkage_m: float
    embedding: bool = False


BEDROCK = Soil("bedrock", friction_angle_deg=45.0, cohesion_kpa=10.0, sinkage_m=0.0)
GUSEV_SOIL = Soil("gusev_soil", friction_angle_deg=35.0, cohesion_kpa=1.0, sinkage_m=0.005)
MERIDIANI_SAND = Soil("meridiani_sand", friction_angle_deg=30.0, cohesion_kpa=0.2, sinkage_m=0.01)
EMBEDDING_SINKAGE_FRACTION = 0.9  # wheel radii: a MER wheel sunk to its hub (Purgatory, sol 446)
# A sand trap, after the Purgatory ripple where Opportunity dug its wheels in to the hubs
# (the MER mission's sol reports, sol 446): loose, cohesionless, fluffy fines. The values are
# assumptions chosen for that behaviour, not measurements: a static sinkage of 0.45 wheel
# radii (5.85 cm) gives Bekker's compaction resistance f_r = 0.75 sqrt(z / 2r) = 0.36 of the
# weight, more than a friction angle of 18 deg can hold (tan 18 deg = 0.32), so on level
# ground the wheels spin in place; the slip-sinkage law doubles the sinkage at 100 % slip,
# to 0.9 wheel radii, the hubs.
SAND_TRAP = Soil(
    "sand_trap", friction_angle_deg=18.0, cohesion_kpa=0.0, sinkage_m=0.0585, embedding=True
)


class Terrain(Protocol):
    """What the rover, the sensors and the cameras ask of a surface. All calls vectorise."""

    name: str
    soil: Soil

    def height_m(self, x_m: ArrayLike, y_m: ArrayLike) -> FloatArray:
        """Elevation (up, m) at Site-frame North ``x_m`` and East ``y_m``; broadcasts."""
        ...

    def gradient(self, x_m: ArrayLike, y_m: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """``(dh/dx, dh/dy)``: the slope of the elevation towards North and East."""
        ...

    def albedo(self, x_m: ArrayLike, y_m: ArrayLike) -> FloatArray:
        """Surface reflectance in [0, 1] at the point, continuous down to millimetres."""
        ...


def normal_up_s(terrain: Terrain, x_m: ArrayLike, y_m: ArrayLike) -> FloatArray:
    """Unit surface normal pointing up, in Site coordinates (N, E, Down); shape (..., 3).

    For ``h(x, y)`` the upward normal is ``(-h_x, -h_y, 1)`` in (N, E, Up), so in the Down
    convention of the Site frame its third component is negative.
    """
    hx, hy = terrain.gradient(x_m, y_m)
    n = np.stack([-hx, -hy, -np.ones_like(hx)], axis=-1)
    out: FloatArray = n / np.linalg.norm(n, axis=-1, keepdims=True)
    return out


class FlatTerrain:
    """A level plane at elevation zero: the reference for exact-distance tests."""

    def __init__(self, soil: Soil = BEDROCK, albedo_value: float = 0.25) -> None:
        self.name = "flat"
        self.soil = soil
        self._albedo = albedo_value

    def height_m(self, x_m: ArrayLike, y_m: ArrayLike) -> FloatArray:
        shape = np.broadcast_shapes(np.shape(x_m), np.shape(y_m))
        return np.zeros(shape)

    def gradient(self, x_m: ArrayLike, y_m: ArrayLike) -> tuple[FloatArray, FloatArray]:
        z = self.height_m(x_m, y_m)
        return z, z.copy()

    def albedo(self, x_m: ArrayLike, y_m: ArrayLike) -> FloatArray:
        return self.height_m(x_m, y_m) + self._albedo


class PlaneTerrain:
    """A tilted plane ``h = dh_dx x + dh_dy y + h0_m``: the surface with exact answers.

    ``dh_dx`` rises towards North, ``dh_dy`` towards East (tangent of the slope).
    """

    def __init__(
        self,
        dh_dx: float,
        dh_dy: float,
        h0_m: float = 0.0,
        *,
        soil: Soil = BEDROCK,
        albedo_value: float = 0.2,
    ) -> None:
        self.name = "plane"
        self.soil = soil
        self.dh_dx, self.dh_dy, self.h0_m = dh_dx, dh_dy, h0_m
        self._albedo = albedo_value

    def height_m(self, x_m: ArrayLike, y_m: ArrayLike) -> FloatArray:
        x, y = np.broadcast_arrays(np.asarray(x_m, float), np.asarray(y_m, float))
        out: FloatArray = self.dh_dx * x + self.dh_dy * y + self.h0_m
        return out

    def gradient(self, x_m: ArrayLike, y_m: ArrayLike) -> tuple[FloatArray, FloatArray]:
        shape = np.broadcast_shapes(np.shape(x_m), np.shape(y_m))
        return np.full(shape, self.dh_dx), np.full(shape, self.dh_dy)

    def albedo(self, x_m: ArrayLike, y_m: ArrayLike) -> FloatArray:
        return np.full(np.broadcast_shapes(np.shape(x_m), np.shape(y_m)), self._albedo)


class Eq22Terrain:
    """Balaram's undulating test surface, Balaram 2000 equation 22 (see the module docstring)."""

    def __init__(self, soil: Soil = BEDROCK, albedo_value: float = 0.25) -> None:
        self.name = "eq22"
        self.soil = soil
        self._albedo = albedo_value

    @staticmethod
    def _terms(x: FloatArray, y: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        g1 = 0.25 * np.exp(-5.0 * (6.25 * (x - 0.5) ** 2 + 6.25 * (y - 0.2) ** 2))  # eq. 22
        g2 = 0.25 * np.exp(-4.0 * (6.25 * (x - 0.5) ** 2 + 6.25 * (y + 0.2) ** 2))  # eq. 22
        s = 0.5 * np.sin(0.75 * x * y)  # eq. 22
        return g1, g2, s

    def height_m(self, x_m: ArrayLike, y_m: ArrayLike) -> FloatArray:
        x, y = np.broadcast_arrays(np.asarray(x_m, float), np.asarray(y_m, float))
        g1, g2, s = self._terms(x, y)
        out: FloatArray = 0.2 * (g1 - g2 + s)  # eq. 22
        return out

    def gradient(self, x_m: ArrayLike, y_m: ArrayLike) -> tuple[FloatArray, FloatArray]:
        x, y = np.broadcast_arrays(np.asarray(x_m, float), np.asarray(y_m, float))
        g1, g2, _ = self._terms(x, y)
        c = 0.5 * 0.75 * np.cos(0.75 * x * y)
        hx = 0.2 * (g1 * (-62.5 * (x - 0.5)) - g2 * (-50.0 * (x - 0.5)) + c * y)
        hy = 0.2 * (g1 * (-62.5 * (y - 0.2)) - g2 * (-50.0 * (y + 0.2)) + c * x)
        return hx, hy

    def albedo(self, x_m: ArrayLike, y_m: ArrayLike) -> FloatArray:
        return np.zeros(np.broadcast(np.asarray(x_m), np.asarray(y_m)).shape) + self._albedo
