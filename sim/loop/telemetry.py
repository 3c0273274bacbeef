"""The telemetry frame: the one definition of its fields, from which the server's responses,
its CSV columns and the published JSON schema (``GET /api/schema/telemetry``) all read."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any

from pydantic import TypeAdapter

from estimation.events import Event


@dataclass(frozen=True)
class TelemetryFrame:
    """One control cycle's telemetry (docs/DESIGN.md's frame, plus derived figures).

    Angles in degrees at this edge; positions in metres: ``p_s_*`` in the current Site,
    ``p_mission_*`` in the mission frame (the first Site; the chain of Site offsets).
    ``rocker_deg``, ``bogie_deg`` [left, right] and ``steer_deg`` (``STEERED_WHEELS``
    order) are the true suspension and steering (``sim.rover.truth``), for drawing the rover.
    ``sun_ll_true``, ``earth_ll_true`` and ``hga_boresight_ll_true`` are unit vectors in LL
    (truth): the sun, Earth, and where the dish really points.
    ``vo_failures_in_row``: VO steps that failed since the last converged one (the flight
    software's VO status); ``hga_margin_predicted_deg``: the HGA margin the rover predicts
    from its own attitude knowledge (``estimation.sapp.pointing_knowledge``; no truth).
    ``hga_error_deg``/``hga_margin_deg`` as the module docstring says; ``earth_up`` whether
    Earth is above the horizon (truth). ``attitude_error_deg``: angle between the estimated
    and true attitude; ``position_error_m``: between estimated and true mission positions.
    """

    t_s: float
    sol: int
    lmst_h: float
    nate_mode: str
    aqf: str
    q_b_ll_est: list[float]
    q_b_ll_true: list[float]
    p_s_est: list[float]
    p_s_true: list[float]
    site_index: int
    p_mission_est: list[float]
    p_mission_true: list[float]
    imu_integration_s: float
    gyro_counter_s: float
    tilt_est_deg: float
    tilt_accel_deg: float
    hga_error_deg: float
    hga_margin_deg: float
    earth_up: bool
    attitude_error_deg: float
    position_error_m: float
    command: str
    rocker_deg: float
    bogie_deg: list[float]
    steer_deg: list[float]
    sun_ll_true: list[float]
    earth_ll_true: list[float]
    hga_boresight_ll_true: list[float]
    events: list[Event] = field(default_factory=list)
    estimators: dict[str, dict[str, Any]] = field(default_factory=dict)
    vo_failures_in_row: int = 0
    hga_margin_predicted_deg: float = math.nan

    def as_dict(self) -> dict[str, Any]:
        """The frame as a JSON-ready dict; a figure that does not exist (NaN, e.g. the
        accelerometer tilt of a cycle without a sample) is ``None``: JSON has no NaN."""
        out = asdict(self)
        for key, value in out.items():
            if isinstance(value, float) and not math.isfinite(value):
                out[key] = None
        return out


def telemetry_schema() -> dict[str, Any]:
    """The JSON schema of a frame as the server sends it (``TelemetryFrame.as_dict``)."""
    return TypeAdapter(TelemetryFrame).json_schema(mode="serialization")
