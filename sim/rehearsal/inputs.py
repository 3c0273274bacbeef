"""What a rehearsal may know: the rover's last report, the ground's map, priors. Plain data.

A rehearsal (``sim.rehearsal.run``) builds its worlds and its flight software from a
``RehearsalInputs`` and from nothing else: no session, no simulator, no checkpoint (a
checkpoint holds the truth). Every field here is something the ground has: what the rover
reported in its last frame that came down and in its events (``ReportedStart``), the ground's
terrain map and its per-cell uncertainty (``GroundMapData``), and the priors the team holds on
what no one has measured (``Priors``). All of it pickles, so a campaign ships it to Dask
workers as it is.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from estimation.protection.keepout import KeepOutZone

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

AQF_NAMES = ("Unknown", "TiltOnly", "Coarse", "Fine")


def _finite(name: str, value: float) -> None:
    if not isinstance(value, int | float) or not math.isfinite(value):
        raise ValueError(f"{name}: must be a finite number, got {value!r}")


def _tuple3(v: Any) -> tuple[float, float, float]:
    return (float(v[0]), float(v[1]), float(v[2]))


def _tuple4(v: Any) -> tuple[float, float, float, float]:
    return (float(v[0]), float(v[1]), float(v[2]), float(v[3]))


@dataclass(frozen=True)
class ReportedStart:
    """The rover as its last frame and its events reported it: the state a rehearsal starts
    from. ``site`` is the landing site's name (``sim.world.sites``: its latitude and the
    statistics of its ground), ``t_s`` the frame's time (TT s since J2000); ``q_b_ll_est``
    [x, y, z, w], ``p_s_est`` (N, E, D; m in Site ``site_index``) and ``p_mission_est`` the
    estimate; ``aqf``, ``imu_integration_s`` and ``position_sigma_m`` (1σ, m; 0 unknown)
    as reported; ``keepout_zones``, ``params`` (NATE parameters, SI, as
    ``server.validation.reported`` rebuilds them) and ``mobility_fault`` from its events;
    ``vo_rig`` the width of its VO Navcam pairs (256 or 1024); ``gyro_counter_s`` NATE's
    gyro counter as reported (the downlink's; 0 if unknown)."""

    site: str
    mission: str
    t_s: float
    q_b_ll_est: tuple[float, float, float, float]
    p_s_est: tuple[float, float, float]
    p_mission_est: tuple[float, float, float]
    site_index: int = 0
    aqf: str = "Unknown"
    imu_integration_s: float = 0.0
    position_sigma_m: float = 0.0
    keepout_zones: tuple[KeepOutZone, ...] = ()
    params: dict[str, float] = field(default_factory=dict)
    mobility_fault: str | None = None
    vo_rig: int = 256
    gyro_counter_s: float = 0.0

    def __post_init__(self) -> None:
        _finite("t_s", self.t_s)
        _finite("gyro_counter_s", self.gyro_counter_s)
        q = np.asarray(self.q_b_ll_est, dtype=np.float64)
        if q.shape != (4,) or not np.all(np.isfinite(q)) or abs(np.linalg.norm(q) - 1.0) > 1e-6:
            raise ValueError(f"q_b_ll_est: must be a unit quaternion, got {self.q_b_ll_est!r}")
        for name in ("p_s_est", "p_mission_est"):
            p = np.asarray(getattr(self, name), dtype=np.float64)
            if p.shape != (3,) or not np.all(np.isfinite(p)):
                raise ValueError(f"{name}: must be 3 finite numbers, got {getattr(self, name)!r}")
        if self.aqf not in AQF_NAMES:
            raise ValueError(f"aqf: must be one of {', '.join(AQF_NAMES)}, got {self.aqf!r}")
        _finite("imu_integration_s", self.imu_integration_s)
        _finite("position_sigma_m", self.position_sigma_m)
        if self.position_sigma_m < 0.0:
            raise ValueError(f"position_sigma_m: must be >= 0, got {self.position_sigma_m}")
        if self.vo_rig not in (256, 1024):
            raise ValueError(f"vo_rig: must be 256 or 1024, got {self.vo_rig!r}")

    @classmethod
    def from_downlink(
        cls,
        frame: Mapping[str, Any],
        site: str,
        mission: str,
        *,
        keepout_zones: tuple[KeepOutZone, ...] = (),
        params: Mapping[str, float] | None = None,
        mobility_fault: str | None = None,
        vo_rig: int = 256,
    ) -> ReportedStart:
        """From a downlink record (``sim.loop.downlink.DownlinkDict``: what came down) and
        what the rover's events reported (zones, parameters, fault)."""
        sigma = frame.get("position_sigma_m")
        return cls(
            site=site,
            mission=mission,
            t_s=float(frame["t_s"]),
            q_b_ll_est=_tuple4(frame["q_b_ll_est"]),
            p_s_est=_tuple3(frame["p_s_est"]),
            p_mission_est=_tuple3(frame["p_mission_est"]),
            site_index=int(frame["site_index"]),
            aqf=str(frame["aqf"]),
            imu_integration_s=float(frame["imu_integration_s"]),
            position_sigma_m=float(sigma) if sigma is not None and math.isfinite(sigma) else 0.0,
            keepout_zones=tuple(keepout_zones),
            params=dict(params or {}),
            mobility_fault=mobility_fault or frame.get("mobility_fault") or None,
            vo_rig=vo_rig,
            gyro_counter_s=float(frame.get("gyro_counter_s", 0.0) or 0.0),
        )

    @property
    def site_origin_mission_m(self) -> tuple[float, float]:
        """The current Site's origin (North, East) in the mission frame, as the estimate
        implies it: ``p_mission_est - p_s_est``."""
        return (
            float(self.p_mission_est[0] - self.p_s_est[0]),
            float(self.p_mission_est[1] - self.p_s_est[1]),
        )


@dataclass(frozen=True)
class GroundMapData:
    """The ground's terrain map as plain arrays (``server.terrain.ground_map.GroundMap``):
    a grid in the mission frame, cell ``(i, j)`` centred at ``(north0_m + i cell_m,
    east0_m + j cell_m)``; ``height_m`` (up) and its 1σ ``sigma_m``; ``albedo`` the ground's
    reflectance estimate; ``imaged`` the cells some stereo pair measured."""

    north0_m: float
    east0_m: float
    cell_m: float
    height_m: FloatArray
    sigma_m: FloatArray
    albedo: FloatArray
    imaged: BoolArray

    def __post_init__(self) -> None:
        for name in ("north0_m", "east0_m", "cell_m"):
            _finite(name, getattr(self, name))
        if not self.cell_m > 0.0:
            raise ValueError(f"cell_m: must be positive, got {self.cell_m}")
        shape = np.shape(self.height_m)
        if len(shape) != 2 or min(shape) < 2:
            raise ValueError(f"height_m: must be a 2-D grid of at least 2 x 2, got {shape}")
        for name in ("sigma_m", "albedo", "imaged"):
            if np.shape(getattr(self, name)) != shape:
                raise ValueError(f"{name}: must have height_m's shape {shape}")
        if not (np.all(np.isfinite(self.height_m)) and np.all(np.isfinite(self.sigma_m))):
            raise ValueError("height_m/sigma_m: must be finite")
        if np.any(np.asarray(self.sigma_m) <= 0.0):
            raise ValueError("sigma_m: must be positive")


@dataclass(frozen=True)
class Priors:
    """What the team assumes of what no one has measured, each drawn once per run.

    ``friction_sigma_deg`` and ``cohesion_sigma_kpa``: 1σ of the soil's friction angle and
    cohesion around the site's nominal soil; ``mast_bias_sigma_deg``: the mast's pointing
    bias per axis (the simulator's default, from the actuator's calibration); the IMU's
    biases and noise come from the LN-200's datasheet model (``sim.sensors.imu``), slip
    from the slip model's own randomness. ``heading_sigma_deg_by_aqf``: 1σ of the start
    heading around the reported one, per Attitude Quality Flag (the downlink's spelling;
    approximate: Fine is good enough to point the HGA, Coarse complete but crude, TiltOnly and
    Unknown know nothing of heading: Ali et al. 2005, sec. 2.1). ``position_sigma_scale``:
    the start position's 1σ per axis as a multiple of the reported one (the onboard
    uncertainty is a budget along its worst direction, ``estimation.protection.position_sigma``,
    not a measured spread). ``odometry_error_by_site``: per site, the reported position's
    true error as wheel odometry leaves it, in units of the reported 1σ: the mean and 1σ
    along the reported heading, the 1σ across it. Wheel odometry counts the slip as
    progress, so the rover stands behind its estimate, more on Meridiani's sand than on
    Gusev's soil; measured on 24 drives of 1-3 m after a Fine attitude, 12 per site, on
    seeds no benchmark uses (a team learns the same from its rover's earlier drives). A site
    not listed keeps the onboard budget: zero mean, 1σ along, ``min(1, σ_ψ / f)`` across
    (``sim.rehearsal.start``)."""

    friction_sigma_deg: float = 2.0
    cohesion_sigma_kpa: float = 0.3
    mast_bias_sigma_deg: float = 0.05
    position_sigma_scale: float = 1.0
    heading_sigma_deg_by_aqf: tuple[tuple[str, float], ...] = (
        ("Fine", 0.35),
        ("Coarse", 1.0),
        ("TiltOnly", 180.0),
        ("Unknown", 180.0),
    )
    odometry_error_by_site: tuple[tuple[str, float, float, float], ...] = (
        ("gusev", -0.58, 0.70, 0.66),
        ("meridiani", -1.45, 0.50, 0.27),
    )

    def __post_init__(self) -> None:
        for name in (
            "friction_sigma_deg",
            "cohesion_sigma_kpa",
            "mast_bias_sigma_deg",
            "position_sigma_scale",
        ):
            value = getattr(self, name)
            _finite(name, value)
            if value < 0.0:
                raise ValueError(f"{name}: must be >= 0, got {value}")
        for entry in self.odometry_error_by_site:
            if len(entry) != 4 or not all(math.isfinite(v) for v in entry[1:]):
                raise ValueError(
                    f"odometry_error_by_site: (site, mean, along, across), got {entry}"
                )
            if entry[2] < 0.0 or entry[3] < 0.0:
                raise ValueError(f"odometry_error_by_site: 1σ must be >= 0, got {entry}")

    def odometry_error(self, site: str) -> tuple[float, float, float] | None:
        """``odometry_error_by_site``'s (along mean, along 1σ, across 1σ) for ``site`` (a
        scenario place by the site it lies in: ``meridiani:...``), None if not listed."""
        base = site.split(":", 1)[0]
        for name, mean, along, across in self.odometry_error_by_site:
            if name == base:
                return mean, along, across
        return None

    def heading_sigma_rad(self, aqf: str) -> float:
        """The start heading's 1σ for a rover reporting ``aqf``, rad."""
        return math.radians(dict(self.heading_sigma_deg_by_aqf).get(aqf, 180.0))


@dataclass(frozen=True)
class RehearsalInputs:
    """Everything a rehearsal knows (module docstring): the report it starts from, the
    ground's map, the sequence's text and the priors."""

    start: ReportedStart
    ground_map: GroundMapData
    sequence_text: str
    priors: Priors = field(default_factory=Priors)
