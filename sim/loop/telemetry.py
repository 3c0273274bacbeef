"""The telemetry frame: the one definition of its fields, with each field's unit and meaning,
from which the server's responses, its CSV columns, the published JSON schema
(``GET /api/schema/telemetry``) and the tests all read.

``TelemetryFrame`` is a plain dataclass whose fields carry pydantic metadata
(``Annotated[..., Field(description=...)]``): the schema reads the descriptions, and a
frame, built once per control cycle, pays no validation on construction.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from typing import Annotated, Any

from pydantic import Field, TypeAdapter

from estimation.events import Event

Vec3 = list[float]
Quat = list[float]


def _about(text: str) -> Any:
    """A field's meaning and unit, for the schema."""
    return Field(description=text)


@dataclass(frozen=True)
class TelemetryFrame:
    """One control cycle's telemetry: the flight software's estimate beside the truth, with
    the derived figures (docs/DESIGN.md, "One control cycle").

    Angles in degrees at this edge; positions in metres; quaternions ``[x, y, z, w]``;
    ``p_s_*`` in the current Site, ``p_mission_*`` in the mission frame (the first Site; the
    chain of Site offsets). ``*_true`` is the simulator's truth, which a rover would not know.
    """

    t_s: Annotated[float, _about("simulated time, TT seconds from J2000")]
    sol: Annotated[int, _about("the mission's sol number at t_s")]
    lmst_h: Annotated[float, _about("local mean solar time at the site, hours")]
    nate_mode: Annotated[str, _about("NATE's mode (estimation.sapp.nate.NateMode)")]
    aqf: Annotated[str, _about("attitude quality flag: Unknown, Tilt, Coarse or Fine")]
    q_b_ll_est: Annotated[Quat, _about("estimated attitude, body in Local Level, [x, y, z, w]")]
    q_b_ll_true: Annotated[Quat, _about("true attitude, body in Local Level, [x, y, z, w]")]
    p_s_est: Annotated[Vec3, _about("estimated position in the current Site (N, E, D), m")]
    p_s_true: Annotated[Vec3, _about("true position in the current Site (N, E, D), m")]
    site_index: Annotated[int, _about("the current Site's index (0: the landing Site)")]
    p_mission_est: Annotated[Vec3, _about("estimated position in the mission frame, m")]
    p_mission_true: Annotated[Vec3, _about("true position in the mission frame, m")]
    imu_integration_s: Annotated[
        float, _about("IMU integration time since the attitude was last acquired, s")
    ]
    gyro_counter_s: Annotated[float, _about("NATE's gyro counter (time propagated on gyros), s")]
    tilt_est_deg: Annotated[float, _about("tilt of the estimated attitude, deg")]
    tilt_accel_deg: Annotated[
        float, _about("tilt from this cycle's accelerometer sample, deg (null: no sample)")
    ]
    hga_error_deg: Annotated[
        float,
        _about(
            "error of an HGA pointed now from the estimate and IVP's Earth, against the "
            "truth, deg (the real error during an HGA pass, the error it would have otherwise)"
        ),
    ]
    hga_margin_deg: Annotated[float, _about("HGA pointing requirement minus hga_error_deg, deg")]
    earth_up: Annotated[bool, _about("Earth is above the horizon (truth)")]
    attitude_error_deg: Annotated[
        float, _about("angle between the estimated and true attitude, deg")
    ]
    position_error_m: Annotated[
        float, _about("distance between the estimated and true mission positions, m")
    ]
    command: Annotated[str, _about("the command running (empty: the clock's own wait)")]
    rocker_deg: Annotated[float, _about("true rocker angle, deg")]
    bogie_deg: Annotated[list[float], _about("true bogie angles [left, right], deg")]
    steer_deg: Annotated[list[float], _about("true corner steering (STEERED_WHEELS order), deg")]
    sun_ll_true: Annotated[Vec3, _about("true sun direction in Local Level, unit vector")]
    earth_ll_true: Annotated[Vec3, _about("true Earth direction in Local Level, unit vector")]
    hga_boresight_ll_true: Annotated[
        Vec3, _about("where the HGA pointed now really points, Local Level, unit vector")
    ]
    events: Annotated[list[Event], _about("what happened since the previous frame")] = field(
        default_factory=list
    )
    estimators: Annotated[
        dict[str, dict[str, Any]],
        _about(
            "each side estimator's pose and errors: p_mission (m), q_b_ll (null for a "
            "position-only one), position_error_m, attitude_error_deg"
        ),
    ] = field(default_factory=dict)
    vo_failures_in_row: Annotated[
        int, _about("VO steps failed since the last converged one (flight software's status)")
    ] = 0
    hga_margin_predicted_deg: Annotated[
        float,
        _about(
            "the HGA margin the rover predicts from its own attitude knowledge, deg "
            "(estimation.sapp.hga_pointing; no truth)"
        ),
    ] = math.nan

    def as_dict(self) -> dict[str, Any]:
        """The frame as a JSON-ready dict (what ``dataclasses.asdict`` gives, built without
        its deep copy: the server turns every stored frame into one); a figure that does
        not exist (NaN, e.g. the accelerometer tilt of a cycle without a sample) is
        ``None``: JSON has no NaN."""
        out: dict[str, Any] = {}
        for name in _FIELD_NAMES:
            value = getattr(self, name)
            if type(value) is float:
                out[name] = value if math.isfinite(value) else None
            else:
                out[name] = _plain(value)
        return out


def _plain(value: Any) -> Any:
    """``value`` as ``dataclasses.asdict`` copies it: lists, tuples and dicts anew, an
    ``Event`` as its dict, numbers and strings as they are."""
    kind = type(value)
    if kind is list or kind is tuple:
        return kind(v if type(v) in _ATOMS else _plain(v) for v in value)
    if kind is dict:
        return {k: v if type(v) in _ATOMS else _plain(v) for k, v in value.items()}
    if kind is Event:
        return {"text": value.text, "kind": value.kind, "severity": value.severity}
    return value


_ATOMS = (float, int, str, bool, type(None))
_FIELD_NAMES = tuple(f.name for f in fields(TelemetryFrame))


def telemetry_fields() -> list[str]:
    """The frame's field names, in order (the CSV columns, the tests' keys)."""
    return [f.name for f in fields(TelemetryFrame)]


def telemetry_schema() -> dict[str, Any]:
    """The JSON schema of a frame as the server sends it (``TelemetryFrame.as_dict``)."""
    return TypeAdapter(TelemetryFrame).json_schema(mode="serialization")
