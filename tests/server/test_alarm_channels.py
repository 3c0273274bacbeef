"""The two frame fields the alarms need (sim.loop.session): VO failures in a row, from the flight
software's VO status, and the HGA margin the rover predicts from its own attitude knowledge
(estimation.sapp.hga_pointing): -178 deg with the heading unknown, 2 deg minus the
Sungaze's own 3σ after a Fine attitude, shrinking with IMU time, never reading the truth."""

from __future__ import annotations

import math
import re

import pytest

from estimation.sapp.aqf import AttitudeQuality
from estimation.sapp.hga_pointing import (
    COARSE_3SIGMA_DEG,
    DRIFT_3SIGMA_DEG_PER_S,
    PointingKnowledge,
)
from sequences import commands as cmd
from server.runtime import ROVERS
from sim.loop.session import RoverSession

FINE, COARSE = AttitudeQuality.FINE, AttitudeQuality.COARSE


def test_the_flag_and_the_sungaze_decide_the_predicted_margin() -> None:
    k = PointingKnowledge()
    assert k.update(AttitudeQuality.UNKNOWN, 0.0) == -178.0
    assert k.update(COARSE, 0.0) == 2.0 - COARSE_3SIGMA_DEG  # a Sunfind: Coarse's bound
    assert k.update(FINE, 0.0, sungaze_3sigma_deg=0.8) == pytest.approx(1.2)
    # Fine drops to Coarse by the gyro counter: the same estimate, propagated
    assert k.update(COARSE, 4000.0) == pytest.approx(1.2 - 4000.0 * DRIFT_3SIGMA_DEG_PER_S)
    assert k.update(AttitudeQuality.TILT_ONLY, 4000.0) == -178.0  # heading lost
    assert k.update(COARSE, 4000.0) == 2.0 - COARSE_3SIGMA_DEG  # a new Coarse: its bound
    assert k.update(FINE, 4000.0) == pytest.approx(0.5)  # a Fine without a Sungaze: 1.5 deg


@pytest.fixture(scope="module")
def session() -> RoverSession:
    spec = ROVERS["spirit"]
    return RoverSession(spec.site, spec.seed, spec.start_utc, frame_every_s=1.0)


def test_frames_carry_the_predicted_margin_from_the_rovers_own_knowledge(
    session: RoverSession,
) -> None:
    session.execute(cmd.Wait(1.0))
    assert session.downlinks[-1].hga_margin_predicted_deg == -178.0  # AQF Unknown
    session.execute(cmd.GetFineAttitude())
    events = [e.text for f in session.downlinks for e in f.events]
    found = next(re.search(r"Sungaze: converged, 3σ ([\d.]+) deg", e) for e in events
                 if e.startswith("Sungaze"))  # fmt: skip
    assert found is not None
    fine = session.downlinks[-1]
    assert fine.aqf == "Fine" and fine.imu_integration_s == 0.0
    assert fine.hga_margin_predicted_deg == pytest.approx(2.0 - float(found.group(1)), abs=0.006)
    session.downlinks.clear()
    session.execute(cmd.DriveStraight(distance_m=2.0))
    last = session.downlinks[-1]
    grown = last.imu_integration_s * DRIFT_3SIGMA_DEG_PER_S
    assert last.imu_integration_s > 30.0
    assert last.hga_margin_predicted_deg == pytest.approx(fine.hga_margin_predicted_deg - grown)
    assert math.isfinite(last.as_dict()["hga_margin_predicted_deg"])


def test_vo_failures_in_a_row_count_failed_steps_and_a_converged_step_resets_them(
    session: RoverSession, monkeypatch: pytest.MonkeyPatch
) -> None:
    assert session.downlinks[-1].vo_failures_in_row == 0

    def blind(*args: object, **kwargs: object) -> None:
        raise ValueError("the mast looks at nothing")

    monkeypatch.setattr(session.sim, "navcam_pair", blind)
    session.downlinks.clear()
    report = session.execute(cmd.DriveStraight(distance_m=1.4, vo=True))
    assert report.details["vo_failures"] == report.details["vo_steps"] == 2
    counts = [f.vo_failures_in_row for f in session.downlinks]
    assert counts[-1] == 2 and sorted(counts) == counts  # counted step by step
    session.execute(cmd.DriveStraight(distance_m=0.5))  # no VO: the count stands
    assert session.downlinks[-1].vo_failures_in_row == 2
    monkeypatch.undo()
    session.execute(cmd.DriveStraight(distance_m=0.5, vo=True))
    assert session.downlinks[-1].vo_failures_in_row == 0
