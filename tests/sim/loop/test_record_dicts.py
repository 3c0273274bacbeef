"""The typed dicts of the two records (``DownlinkDict``, ``TruthDict``: what the server's
frame batches, storage and sinks are typed with) hold every field of their record, in order,
with the types the records' dicts really have: each real record of a short session, from
no attitude to an HGA pass, validates against its typed dict in pydantic's strict mode."""

from __future__ import annotations

from dataclasses import fields
from datetime import UTC, datetime
from typing import Any

import pytest
from pydantic import TypeAdapter, ValidationError

from estimation.sapp.aqf import AttitudeQuality
from sequences import commands as cmd
from sim.loop.downlink import Downlink, DownlinkDict
from sim.loop.session import RoverSession
from sim.scoring.truth import Truth, TruthDict


@pytest.mark.parametrize(("record", "typed"), [(Downlink, DownlinkDict), (Truth, TruthDict)])
def test_a_typed_dict_has_its_record_s_fields_in_order(record: type, typed: type) -> None:
    assert list(typed.__annotations__) == [f.name for f in fields(record)]


@pytest.fixture(scope="module")
def records() -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    session = RoverSession("gusev", 3, datetime(2004, 4, 14, 16, 30, tzinfo=UTC), frame_every_s=1.0)
    session.run([cmd.Wait(20.0)])  # no attitude yet: the figures that need one are null
    session.nate.load_attitude(session.q_b_ll_true(), AttitudeQuality.FINE)
    session.run([cmd.DriveStraight(1.5), cmd.HgaPass(1.0)])
    downlinks = [dict(d.as_dict()) for d in session.downlinks]
    truths = [dict(t.as_dict()) for t in session.truths]
    return downlinks, truths


def test_every_record_validates_against_its_typed_dict(
    records: tuple[list[dict[str, Any]], list[dict[str, Any]]],
) -> None:
    downlinks, truths = records
    for typed, dicts in ((DownlinkDict, downlinks), (TruthDict, truths)):
        adapter = TypeAdapter(typed)
        for record in dicts:
            adapter.validate_python(record, strict=True)
    # both kinds of figure are there: the session saw the null ones and the numbers
    assert {d["tilt_accel_deg"] is None for d in downlinks} == {True, False}


def test_the_check_catches_a_null_where_the_type_says_a_number(
    records: tuple[list[dict[str, Any]], list[dict[str, Any]]],
) -> None:
    wrong = {**records[0][-1], "imu_integration_s": None}
    with pytest.raises(ValidationError, match="imu_integration_s"):
        TypeAdapter(DownlinkDict).validate_python(wrong, strict=True)
