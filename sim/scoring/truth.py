"""The truth record: what only the simulator knows at a telemetry frame's time, and the
scores of the rover's downlink (``sim.loop.downlink.Downlink``) against it.

The true pose and suspension, the true sun, Earth and HGA boresight directions, whether Earth
is really above the horizon, the attitude and position errors of the estimate, the true error
and margin of the HGA pointed from it, the side estimators' errors, and the events that are
scores (the HGA pass's worst true error). A real ground system never has any of it: the
server shows it only to those the truth view allows (docs/DESIGN.md, "Two records").

``merged`` puts a downlink record and its truth record back together, as the single frame
the loop made before the two were apart.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Annotated, Any, cast

from typing_extensions import TypedDict  # pydantic validates it (tests) on Python 3.11

from estimation.events import Event
from sim.loop.downlink import DownlinkDict
from sim.loop.records import (
    EventDict,
    Quat,
    Vec3,
    about,
    record_dict,
    record_fields,
    record_schema,
)


@dataclass(frozen=True)
class Truth:
    """One kept control cycle's truth and scores (module docstring)."""

    t_s: Annotated[float, about("simulated time, TT seconds from J2000 (the downlink's)")]
    q_b_ll_true: Annotated[Quat, about("true attitude, body in Local Level, [x, y, z, w]")]
    p_s_true: Annotated[Vec3, about("true position in the current Site (N, E, D), m")]
    p_mission_true: Annotated[Vec3, about("true position in the mission frame, m")]
    hga_error_deg: Annotated[
        float,
        about(
            "error of the HGA pointed now from the estimate and IVP's Earth, against the "
            "truth, deg (the real error during an HGA pass, the error it would have otherwise)"
        ),
    ]
    hga_margin_deg: Annotated[float, about("HGA pointing requirement minus hga_error_deg, deg")]
    earth_up: Annotated[bool, about("Earth is above the horizon (truth)")]
    attitude_error_deg: Annotated[
        float, about("angle between the estimated and true attitude, deg")
    ]
    position_error_m: Annotated[
        float, about("distance between the estimated and true mission positions, m")
    ]
    rocker_deg: Annotated[float, about("true rocker angle, deg")]
    bogie_deg: Annotated[list[float], about("true bogie angles [left, right], deg")]
    steer_deg: Annotated[list[float], about("true corner steering (STEERED_WHEELS order), deg")]
    sun_ll_true: Annotated[Vec3, about("true sun direction in Local Level, unit vector")]
    earth_ll_true: Annotated[Vec3, about("true Earth direction in Local Level, unit vector")]
    hga_boresight_ll_true: Annotated[
        Vec3, about("where the HGA pointed now really points, Local Level, unit vector")
    ]
    events: Annotated[
        list[Event], about("scores since the previous frame (e.g. an HGA pass's true error)")
    ] = field(default_factory=list)
    estimators: Annotated[
        dict[str, dict[str, Any]],
        about(
            "each side estimator's errors: position_error_m (m), attitude_error_deg (null "
            "for a position-only one)"
        ),
    ] = field(default_factory=dict)

    def as_dict(self) -> TruthDict:
        """The record as a JSON-ready dict (``sim.loop.records.record_dict``)."""
        return cast(TruthDict, record_dict(self, TRUTH_FIELDS))


class TruthDict(TypedDict):
    """A ``Truth`` as the JSON-ready dict the server stores and sends to the truth view
    (``Truth.as_dict``): the same fields, a figure that does not exist ``None``
    (``tests/sim/loop/test_record_dicts.py`` keeps the two in step)."""

    t_s: float
    q_b_ll_true: Quat
    p_s_true: Vec3
    p_mission_true: Vec3
    hga_error_deg: float | None
    hga_margin_deg: float | None
    earth_up: bool
    attitude_error_deg: float | None
    position_error_m: float | None
    rocker_deg: float
    bogie_deg: list[float]
    steer_deg: list[float]
    sun_ll_true: Vec3
    earth_ll_true: Vec3
    hga_boresight_ll_true: Vec3
    events: list[EventDict]
    estimators: dict[str, dict[str, Any]]


TRUTH_FIELDS = tuple(f.name for f in fields(Truth))


def truth_fields() -> list[str]:
    """The truth record's field names, in order."""
    return record_fields(Truth)


def truth_schema() -> dict[str, Any]:
    """The JSON schema of a truth record as the server sends it."""
    return record_schema(Truth)


def merged(downlink: DownlinkDict, truth: TruthDict) -> dict[str, Any]:
    """A downlink record and its truth record (``as_dict``, the same ``t_s``) as one frame:
    every field of both; the events are the downlink's then the truth's, and each side
    estimator's entry holds its pose and its errors."""
    if downlink["t_s"] != truth["t_s"]:
        raise ValueError(f"records of {downlink['t_s']} and {truth['t_s']} do not pair")
    out = {**downlink, **{k: v for k, v in truth.items() if k not in ("events", "estimators")}}
    out["events"] = [*downlink["events"], *truth["events"]]
    names = [*downlink["estimators"]]
    names += [n for n in truth["estimators"] if n not in downlink["estimators"]]
    out["estimators"] = {
        n: {**downlink["estimators"].get(n, {}), **truth["estimators"].get(n, {})} for n in names
    }
    return out
