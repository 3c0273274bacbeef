"""The rover's side of sequence validation: a ``ValidationContext`` from ``sim``.

``sequences.validate`` predicts when each command starts and asks the context for Earth's
elevation there (HGA passes: at the start and end of each). One DE421 evaluation per
question made a 40,000-line upload cost minutes of CPU; here the elevations are
interpolated between directions sampled every ``SAMPLE_S`` (10 minutes), computed lazily a
sol at a time (one vectorised ephemeris call per sol reached) and cached for the request,
so the work grows with how far ahead the sequence reaches, not with how often it asks.

Unit vectors are interpolated, not elevations: their components are smooth where an
elevation near the zenith is not, and the chord between samples 2.5 deg of Mars' rotation
apart errs by about 0.01 deg (tests/test_validation_context.py bounds it at 0.05 deg
against the direct function at both sites). The context also carries the ephemeris' last
instant, past which ``sequences.validate`` refuses a step instead of asking.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from sequences.validate import AqfName, ValidationContext
from server.runtime import RoverRuntime
from sim.ephemeris import coverage_t_s
from sim.mars_frames import earth_ll_truth, sun_ll_truth
from sim.marsclock import (
    SOL_S,
    get_mission,
    lmst_h_from_t_s,
    sol_number_t_s,
    t_s_for_sol_lmst,
)

SAMPLE_S = 600.0  # s between direction samples: 2.5 deg of Mars' rotation
CHUNK_S = SOL_S  # s sampled per ephemeris call: one mean sol (149 samples)

DirectionLL = Callable[[NDArray[np.float64]], NDArray[np.float64]]
"""Unit vectors (N, 3) in Local-Level (North, East, Down) at TT seconds ``t_s`` (N,)."""


class SampledElevation:
    """Elevation (deg, positive up) of a body, interpolated between LL unit vectors that
    ``direction_ll`` gives every ``step_s``; samples are computed ``chunk_s`` at a time from
    ``origin_t_s`` on demand and kept. ``end_t_s`` is the last instant that may be asked
    (the ephemeris' end): no sample lies beyond it and a later ``t_s`` is a ``ValueError``.
    """

    def __init__(
        self,
        direction_ll: DirectionLL,
        origin_t_s: float,
        end_t_s: float,
        step_s: float = SAMPLE_S,
        chunk_s: float = CHUNK_S,
    ) -> None:
        if not (step_s > 0.0 and chunk_s >= step_s and origin_t_s <= end_t_s):
            raise ValueError("SampledElevation: need 0 < step_s <= chunk_s, origin <= end")
        self._direction = direction_ll
        self._origin, self._end = origin_t_s, end_t_s
        self._step, self._chunk = step_s, chunk_s
        self._per_chunk = math.ceil(chunk_s / step_s)  # intervals per chunk
        self._chunks: dict[int, tuple[list[float], list[tuple[float, float, float]]]] = {}

    def __call__(self, t_s: float) -> float:
        if not t_s <= self._end:
            raise ValueError(f"t_s: {t_s} is past the end of the samples ({self._end})")
        k = math.floor((t_s - self._origin) / self._chunk)
        times, dirs = self._chunks.get(k) or self._sample(k)
        i = min(int((t_s - times[0]) / self._step), self._per_chunk - 1)
        t0, t1 = times[i], times[i + 1]
        f = (t_s - t0) / (t1 - t0) if t1 > t0 else 0.0
        (n0, e0, d0), (n1, e1, d1) = dirs[i], dirs[i + 1]
        n, e, d = n0 + f * (n1 - n0), e0 + f * (e1 - e0), d0 + f * (d1 - d0)
        return math.degrees(math.asin(max(-1.0, min(1.0, -d / math.sqrt(n * n + e * e + d * d)))))

    @property
    def chunks_sampled(self) -> int:
        """How many chunks have been computed (each one call of ``direction_ll``)."""
        return len(self._chunks)

    def _sample(self, k: int) -> tuple[list[float], list[tuple[float, float, float]]]:
        start = self._origin + k * self._chunk
        t = np.minimum(start + self._step * np.arange(self._per_chunk + 1), self._end)
        v = np.asarray(self._direction(t), dtype=float)
        chunk = (t.tolist(), [(float(a), float(b), float(c)) for a, b, c in v])
        self._chunks[k] = chunk
        return chunk


def site_context(
    mission: str,
    lat_rad: float,
    lon_east_rad: float,
    start_t_s: float,
    aqf: AqfName = "Unknown",
    imu_integration_s: float = 0.0,
    articulating: bool = False,
) -> ValidationContext:
    """A context for a rover of ``mission`` (its sol clock) at a site (planetographic
    latitude, East longitude, rad) from ``start_t_s`` (TT s since J2000), with Earth's and
    the sun's elevation sampled (``SampledElevation``) up to the end of DE421."""
    lon_west_deg = get_mission(mission).lon_west_deg
    end_t_s = coverage_t_s()[1]
    origin = min(start_t_s, end_t_s)

    def earth(t: NDArray[np.float64]) -> NDArray[np.float64]:
        return earth_ll_truth(t, lat_rad, lon_east_rad)

    def sun(t: NDArray[np.float64]) -> NDArray[np.float64]:
        return sun_ll_truth(t, lat_rad, lon_east_rad)

    return ValidationContext(
        start_t_s=start_t_s,
        lmst_h=lambda t_s: float(lmst_h_from_t_s(t_s, lon_west_deg)),
        sol=lambda t_s: int(sol_number_t_s(mission, t_s)),
        t_s_for=lambda sol, lmst_h: t_s_for_sol_lmst(mission, sol, lmst_h),
        earth_elevation_deg=SampledElevation(earth, origin, end_t_s),
        aqf=aqf,
        imu_integration_s=imu_integration_s,
        articulating=articulating,
        ephemeris_end_t_s=end_t_s,
        sun_elevation_deg=SampledElevation(sun, origin, end_t_s),
    )


def validation_context(runtime: RoverRuntime) -> ValidationContext:
    """What validation needs to know of a rover, from its state now."""
    sim = runtime.session.sim
    frame = runtime.last_frame or {}
    return site_context(
        runtime.spec.mission,
        sim.lat_rad,
        sim.lon_east_rad,
        runtime.t_s,
        aqf=frame.get("aqf", runtime.session.nate.aqf.paper_name),
        imu_integration_s=float(frame.get("imu_integration_s", 0.0)),
        articulating=runtime.session.nate.mode.value == "Articulate",
    )
