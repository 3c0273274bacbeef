"""One frame per moment: a rover's frames have strictly increasing ``t_s`` (issue 21), also
where commands that take no time follow one another (PLANT_SITE after a drive wrote two
CSV rows with the drive's last ``t_s``), and what such a command reports is in the next
frame, a control cycle later, with its events in its command report."""

from __future__ import annotations

import csv
import io
import itertools
from datetime import UTC, datetime

import pytest

from estimation.sapp.nate_io import CONTROL_DT_S
from sequences import commands as cmd
from server.api.telemetry_csv import frames_csv
from sim.loop.session import RoverSession


@pytest.fixture(scope="module")
def session() -> RoverSession:
    s = RoverSession("gusev", 7, datetime(2004, 4, 14, 16, 30, tzinfo=UTC), frame_every_s=1.0)
    s.run(
        [
            cmd.DriveStraight(3.0),
            cmd.PlantSite(),
            cmd.SetParam(param="sungaze.timer_s", value=300),
            cmd.Wait(5.0),
            cmd.ArticulateStart(),
            cmd.ArticulateStop(),
            cmd.PlantSite(),
            cmd.DriveStraight(1.0),
        ]
    )
    return s


def test_frames_have_strictly_increasing_t_s(session: RoverSession) -> None:
    times = [f.t_s for f in session.downlinks]
    repeated = [(a, b) for a, b in itertools.pairwise(times) if b <= a]
    assert repeated == []


def test_the_csv_has_one_row_per_moment(session: RoverSession) -> None:
    rows = list(csv.DictReader(io.StringIO(frames_csv([f.as_dict() for f in session.downlinks]))))
    t_s = [row["t_s"] for row in rows]
    assert len(rows) == len(session.downlinks) and len(set(t_s)) == len(t_s)


def test_plant_site_is_reported_a_control_cycle_after_the_drive(session: RoverSession) -> None:
    drive, plant = session.reports[0], session.reports[1]
    assert [e.text for e in plant.events] == ["Site 1 planted"]
    carrying = [f for f in session.downlinks if any(e.text == "Site 1 planted" for e in f.events)]
    assert len(carrying) == 1
    frame = carrying[0]
    assert frame.t_s == pytest.approx(drive.end_t_s + CONTROL_DT_S, abs=1e-6)
    assert frame.site_index == 1 and frame.p_s_est == pytest.approx([0.0, 0.0, 0.0], abs=1e-9)
    setting = session.reports[2]
    assert [e.text for e in setting.events] == ["parameter sungaze.timer_s = 300"]
