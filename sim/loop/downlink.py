"""The downlink: what the rover itself reports in a telemetry frame, and nothing else.

Everything here is the flight software's own knowledge or a reading of its own sensors: its
estimate (attitude, Site and mission positions, the Attitude Quality Flag, NATE's mode), the
IMU integration time and gyro counter, the accelerometer tilt, the suspension and steering
angles as its encoders read them, the HGA pointing it would command now and the margin it
predicts for it, its VO status, the events it logs, the estimates of the estimators running
beside SAPP, and the command it runs. What only the simulator knows, and the scores of these
figures against it, are ``sim.scoring.truth.Truth``, a record of its own at the same ``t_s``
(docs/DESIGN.md, "Two records"). The ground (validation, the console's readouts, alarms on
rover channels, the sol summaries) reads this record only.

Angles in degrees at this edge; positions in metres; quaternions ``[x, y, z, w]``; ``p_s_*``
in the current Site, ``p_mission_*`` in the mission frame (the first Site; the chain of Site
offsets). A figure that does not exist is ``null`` in JSON.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from typing import Annotated, Any, cast

from typing_extensions import TypedDict  # pydantic validates it (tests) on Python 3.11

from estimation.events import Event
from sim.loop.records import (
    EventDict,
    Quat,
    Vec3,
    about,
    record_dict,
    record_fields,
    record_schema,
)

# The estimators a rover may run, SAPP and those beside it whose poses the downlink carries:
# what `--estimators` accepts; SAPP always runs (``sim.loop.side``).
ESTIMATORS = ("sapp", "kinematic_ekf", "radio_ekf")


@dataclass(frozen=True)
class Downlink:
    """One kept control cycle as the rover reports it (module docstring)."""

    t_s: Annotated[float, about("simulated time, TT seconds from J2000")]
    sol: Annotated[int, about("the mission's sol number at t_s")]
    lmst_h: Annotated[float, about("local mean solar time at the site, hours")]
    nate_mode: Annotated[str, about("NATE's mode (estimation.sapp.nate.NateMode)")]
    aqf: Annotated[str, about("attitude quality flag: Unknown, Tilt, Coarse or Fine")]
    q_b_ll_est: Annotated[Quat, about("estimated attitude, body in Local Level, [x, y, z, w]")]
    p_s_est: Annotated[Vec3, about("estimated position in the current Site (N, E, D), m")]
    site_index: Annotated[int, about("the current Site's index (0: the landing Site)")]
    p_mission_est: Annotated[Vec3, about("estimated position in the mission frame, m")]
    imu_integration_s: Annotated[
        float, about("IMU integration time since the attitude was last acquired, s")
    ]
    gyro_counter_s: Annotated[float, about("NATE's gyro counter (time propagated on gyros), s")]
    tilt_est_deg: Annotated[float, about("tilt of the estimated attitude, deg")]
    tilt_accel_deg: Annotated[
        float, about("tilt from this cycle's accelerometer sample, deg (null: no sample)")
    ]
    command: Annotated[str, about("the command running (empty: the clock's own wait)")]
    rocker_enc_deg: Annotated[float, about("rocker angle as its encoder reads it, deg")]
    bogie_enc_deg: Annotated[
        list[float], about("bogie angles [left, right] as their encoders read them, deg")
    ]
    steer_enc_deg: Annotated[
        list[float],
        about("corner steering (STEERED_WHEELS order) as its encoders read it, deg"),
    ]
    hga_azimuth_deg: Annotated[
        float,
        about(
            "HGA gimbal azimuth the rover would command now from its estimate and IVP's Earth "
            "(during an HGA pass: the one it commands), deg"
        ),
    ]
    hga_elevation_deg: Annotated[
        float, about("HGA gimbal elevation commanded with hga_azimuth_deg, deg")
    ]
    events: Annotated[list[Event], about("what the rover logged since the previous frame")] = field(
        default_factory=list
    )
    estimators: Annotated[
        dict[str, dict[str, Any]],
        about(
            "each side estimator's pose: p_mission (m) and q_b_ll (null for a position-only one)"
        ),
    ] = field(default_factory=dict)
    vo_failures_in_row: Annotated[
        int, about("VO steps failed since the last converged one (flight software's status)")
    ] = 0
    hga_margin_predicted_deg: Annotated[
        float,
        about(
            "the HGA margin the rover predicts from its own attitude knowledge, deg "
            "(estimation.sapp.hga_pointing; no truth)"
        ),
    ] = math.nan
    position_sigma_m: Annotated[
        float,
        about(
            "the onboard position's 1-sigma uncertainty, m (estimation.protection."
            "position_sigma: grown with distance on wheel odometry, shrunk by VO)"
        ),
    ] = math.nan
    mobility_fault: Annotated[
        str,
        about(
            "the halt that disabled mobility until CLEAR_MOBILITY_FAULT (empty: mobility enabled)"
        ),
    ] = ""

    def as_dict(self) -> DownlinkDict:
        """The record as a JSON-ready dict (``sim.loop.records.record_dict``)."""
        return cast(DownlinkDict, record_dict(self, DOWNLINK_FIELDS))


class DownlinkDict(TypedDict):
    """A ``Downlink`` as the JSON-ready dict the server stores, sends and judges
    (``Downlink.as_dict``): the same fields, a figure that does not exist ``None``
    (``tests/sim/loop/test_record_dicts.py`` keeps the two in step)."""

    t_s: float
    sol: int
    lmst_h: float
    nate_mode: str
    aqf: str
    q_b_ll_est: Quat
    p_s_est: Vec3
    site_index: int
    p_mission_est: Vec3
    imu_integration_s: float
    gyro_counter_s: float
    tilt_est_deg: float | None
    tilt_accel_deg: float | None
    command: str
    rocker_enc_deg: float
    bogie_enc_deg: list[float]
    steer_enc_deg: list[float]
    hga_azimuth_deg: float | None
    hga_elevation_deg: float | None
    events: list[EventDict]
    estimators: dict[str, dict[str, Any]]
    vo_failures_in_row: int
    hga_margin_predicted_deg: float | None
    position_sigma_m: float | None
    mobility_fault: str


DOWNLINK_FIELDS = tuple(f.name for f in fields(Downlink))


def downlink_fields() -> list[str]:
    """The downlink's field names, in order."""
    return record_fields(Downlink)


def downlink_schema() -> dict[str, Any]:
    """The JSON schema of a downlink record as the server sends it."""
    return record_schema(Downlink)
