"""The alarm engine (server.alarms) on made-up frames: one alarm per violation however long
the value hovers at the limit, escalation, clear only past the hysteresis, listed until
both acknowledged and cleared, a re-raise of an unacknowledged cleared alarm, truth-view
channels marked, Earth below the horizon judged as no value, limits edited and judged at
once, and everything as it was after a restart (a new engine on the same database)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from server.alarms import AlarmConflictError, AlarmEngine, UnknownAlarmError
from server.limits import LimitsError
from server.sinks import FrameBatch
from server.storage import Store
from tests.frame_batches import batch


class Rig:
    """An engine on a database, recording its notices."""

    def __init__(self, url: str) -> None:
        self.store = Store(url)
        self.notices: list[dict[str, Any]] = []
        self.engine = self.new_engine()

    def new_engine(self) -> AlarmEngine:
        def when(rover: str, t_s: float) -> dict[str, Any]:
            return {"t_s": t_s, "utc": f"utc-{t_s:g}", "lmst_h": t_s / 3600.0, "sol": 7}

        return AlarmEngine(self.store, when, lambda rover, n: self.notices.append(n.message()))

    def feed(self, t_s: float, **values: Any) -> None:
        frame = {"t_s": t_s, "aqf": "Fine", "earth_up": True, "hga_margin_deg": 1.9,
                 "hga_margin_predicted_deg": 0.5, "command": "", **values}  # fmt: skip
        self.engine.publish("spirit", batch([frame]))

    def alarms(self, **kwargs: Any) -> list[dict[str, Any]]:
        return self.engine.listed("spirit", kwargs.get("listed"), 100)


@pytest.fixture
def rig(tmp_path: Path) -> Iterator[Rig]:
    r = Rig(f"sqlite:///{tmp_path / 'alarms.db'}")
    yield r
    r.store.close()


def test_a_value_hovering_at_the_limit_raises_one_alarm_and_clears_past_the_hysteresis(
    rig: Rig,
) -> None:
    # imu_integration_s: warning above 8000 s, hysteresis 0 -> use tilt (hysteresis 1 deg)
    for k, tilt in enumerate([24.0, 25.5, 24.6, 25.2, 24.5, 25.9, 24.1]):
        rig.feed(100.0 + k, tilt_accel_deg=tilt)
    alarms = rig.alarms()
    assert len(alarms) == 1
    (alarm,) = alarms
    assert (alarm["channel"], alarm["level"], alarm["value"], alarm["limit"]) == (
        "tilt_accel_deg", "warning", 25.5, 25.0,
    )  # fmt: skip
    assert alarm["raised"] == {"t_s": 101.0, "utc": "utc-101", "lmst_h": 101.0 / 3600, "sol": 7}
    assert alarm["cleared"] is None  # 24.1 is not 1 deg inside 25
    rig.feed(200.0, tilt_accel_deg=23.9)
    cleared = rig.alarms()[0]["cleared"]
    assert cleared == {"t_s": 200.0, "utc": "utc-200", "lmst_h": 200.0 / 3600}
    # one raise, one clear (between them notices of its latest value)
    cleared_flags = [n["alarm"]["cleared"] is not None for n in rig.notices]
    assert cleared_flags[0] is False and cleared_flags[-1] is True and sum(cleared_flags) == 1
    assert all(n["type"] == "alarm" for n in rig.notices)


def test_a_warning_escalates_to_critical_and_keeps_its_worst_level(rig: Rig) -> None:
    rig.feed(1.0, tilt_accel_deg=26.0)
    rig.feed(2.0, tilt_accel_deg=31.0)
    rig.feed(3.0, tilt_accel_deg=26.0)  # back to warning: still critical
    (alarm,) = rig.alarms()
    assert (alarm["level"], alarm["value"], alarm["limit"]) == ("critical", 31.0, 30.0)
    assert "above the critical limit 30 deg" in alarm["message"]
    assert alarm["raised"]["t_s"] == 1.0
    levels = [n["alarm"]["level"] for n in rig.notices]
    assert sorted(set(levels)) == ["critical", "warning"] and levels.index("critical") == 1
    assert rig.notices[-1]["alarm"]["latest"]["value"] == 26.0  # back to a warning's value


def test_listed_until_acknowledged_and_cleared_in_either_order(rig: Rig) -> None:
    rig.feed(1.0, tilt_accel_deg=26.0)
    rig.feed(2.0, vo_failures_in_row=3)
    tilt, vo = sorted(rig.alarms(), key=lambda a: a["channel"])
    assert vo["level"] == "critical" and vo["channel"] == "vo_failures_in_row"
    # tilt: acknowledged first, then cleared
    acked = rig.engine.acknowledge(tilt["id"], "ada")
    assert acked["acknowledged"]["by"] == "ada" and acked["cleared"] is None
    assert {a["id"] for a in rig.alarms(listed=True)} == {tilt["id"], vo["id"]}
    rig.feed(3.0, tilt_accel_deg=10.0, vo_failures_in_row=0)  # both clear
    assert {a["id"] for a in rig.alarms(listed=True)} == {vo["id"]}  # vo unacknowledged
    assert rig.engine.acknowledge(vo["id"], "bob")["cleared"]["t_s"] == 3.0
    assert rig.alarms(listed=True) == []
    assert {a["id"] for a in rig.alarms(listed=False)} == {tilt["id"], vo["id"]}
    with pytest.raises(AlarmConflictError, match="bob"):
        rig.engine.acknowledge(vo["id"], "carl")
    with pytest.raises(UnknownAlarmError):
        rig.engine.acknowledge(999, "carl")
    # a new violation after both: a new alarm
    rig.feed(4.0, tilt_accel_deg=27.0)
    assert len(rig.alarms()) == 3


def test_a_cleared_unacknowledged_alarm_is_raised_again_not_doubled(rig: Rig) -> None:
    rig.feed(1.0, tilt_accel_deg=26.0)
    rig.feed(2.0, tilt_accel_deg=20.0)
    rig.feed(3.0, tilt_accel_deg=31.0)
    (alarm,) = rig.alarms()
    assert alarm["cleared"] is None and alarm["violations"] == 2
    assert (alarm["level"], alarm["value"]) == ("critical", 31.0)


def test_truth_view_channels_are_marked_and_earth_below_the_horizon_is_no_value(
    rig: Rig,
) -> None:
    # the true margin has no default levels (issue 21): an operator sets some
    rig.engine.set_limits("spirit", "hga_margin_deg", {"warning": 0.5, "critical": 0.0},
                          "ada", None)  # fmt: skip
    rig.feed(1.0, hga_margin_deg=-1.0, earth_up=False)
    assert rig.alarms() == []
    rig.feed(2.0, hga_margin_deg=0.3, hga_margin_predicted_deg=0.05, aqf="Coarse")
    by_channel = {a["channel"]: a for a in rig.alarms()}
    assert set(by_channel) == {"hga_margin_deg", "hga_margin_predicted_deg"}
    truth = by_channel["hga_margin_deg"]
    assert truth["truth"] and truth["message"].endswith("(truth view)")
    assert not by_channel["hga_margin_predicted_deg"]["truth"]
    rig.feed(2.5, hga_margin_deg=0.3, aqf="TiltOnly")
    aqf = {a["channel"]: a for a in rig.alarms()}["aqf"]
    assert not aqf["truth"] and aqf["level"] == "warning"
    assert aqf["value"] == "TiltOnly" and aqf["limit"] == "TiltOnly"
    rig.feed(3.0, hga_margin_deg=1.9, earth_up=False)  # no value: not a clear
    assert {a["channel"]: a for a in rig.alarms()}["hga_margin_deg"]["cleared"] is None
    rig.feed(4.0, hga_margin_deg=1.9)
    assert {a["channel"]: a for a in rig.alarms()}["hga_margin_deg"]["cleared"]["t_s"] == 4.0


def test_a_state_channel_alarms_only_where_an_operator_listed_states(rig: Rig) -> None:
    rig.feed(1.0, nate_mode="Gyrocompass")
    assert rig.alarms() == []  # no state alarms by default
    rig.engine.set_limits("spirit", "nate_mode", {"warning": ["Gyrocompass"], "critical": []},
                          "ada", {"t_s": 2.0, "nate_mode": "Gyrocompass"})  # fmt: skip
    (alarm,) = rig.alarms()
    assert (alarm["channel"], alarm["level"], alarm["limit"]) == (
        "nate_mode", "warning", ["Gyrocompass"],
    )  # fmt: skip


def test_editing_a_limit_judges_the_latest_frame_at_once_and_survives_a_restart(
    rig: Rig,
) -> None:
    latest = {"t_s": 5.0, "aqf": "Fine", "earth_up": True, "hga_margin_deg": 1.8}
    rig.engine.publish("spirit", batch([latest]))
    assert rig.alarms() == []
    rig.engine.set_limits("spirit", "hga_margin_deg", {"warning": 1.85, "critical": 0.0},
                          "ada", latest)  # fmt: skip
    (alarm,) = rig.alarms()
    assert alarm["limit"] == 1.85 and alarm["truth"]
    channels = {c["channel"]: c for c in rig.engine.limits("spirit")}
    edited = channels["hga_margin_deg"]
    assert (edited["warning"], edited["edited_by"], edited["default"]["warning"]) == (
        1.85,
        "ada",
        None,  # the truth view has no default levels
    )
    assert channels["aqf"]["edited_by"] is None
    # bad levels: refused, nothing stored
    with pytest.raises(LimitsError, match=r"critical .* must be at or below warning"):
        rig.engine.set_limits(
            "spirit", "hga_margin_deg", {"warning": 0.0, "critical": 1.0}, "x", None
        )
    with pytest.raises(KeyError):
        rig.engine.set_limits("spirit", "warp_core", {"warning": 1, "critical": 2}, "x", None)
    assert set(rig.store.stored_limits("spirit")) == {"hga_margin_deg"}
    # restart: a new engine on the same database keeps the limit and the listed alarm
    rig.engine = rig.new_engine()
    rig.engine.publish("spirit", batch([{**latest, "t_s": 6.0, "hga_margin_deg": 1.7}]))
    assert len(rig.alarms()) == 1  # the same alarm, not a second one
    after = {c["channel"]: c for c in rig.engine.limits("spirit")}["hga_margin_deg"]
    assert after["warning"] == 1.85
    # back to the default: judged at once, cleared
    rig.engine.reset_limits("spirit", "hga_margin_deg", {**latest, "t_s": 7.0})
    assert rig.alarms()[0]["cleared"]["t_s"] == 7.0
    assert rig.store.stored_limits("spirit") == {}
    assert rig.engine.limits("opportunity")[0]["edited_by"] is None  # per rover


# ---- issue 21: nuisance and stale alarms ---------------------------------------------


def test_no_attitude_raises_the_aqf_alarm_only_not_the_predicted_margin(rig: Rig) -> None:
    # A fresh rover: AQF Unknown and the predicted margin -178 deg (heading unknown,
    # estimation.sapp.hga_pointing): one fact, one alarm (the AQF's).
    rig.feed(1.0, aqf="Unknown", hga_margin_predicted_deg=-178.0, hga_margin_deg=-150.0)
    rig.feed(2.0, aqf="TiltOnly", hga_margin_predicted_deg=-178.0, hga_margin_deg=-150.0)
    assert [(a["channel"], a["level"]) for a in rig.alarms()] == [("aqf", "critical")]
    # with a heading the predicted margin is a figure again, and judged
    rig.feed(3.0, aqf="Coarse", hga_margin_predicted_deg=-6.0)
    channels = {a["channel"]: a for a in rig.alarms()}
    assert channels["hga_margin_predicted_deg"]["value"] == -6.0


def test_an_attitude_acquisition_is_expected_the_aqf_alarm_is_shelved_while_it_runs(
    rig: Rig,
) -> None:
    # GET_FINE_ATTITUDE (sequences.commands: it declares the AQF it leaves) passes through
    # Unknown, TiltOnly and Coarse (a -6 deg predicted margin) before Fine.
    passage = [("Fine", 0.5), ("Unknown", -178.0), ("TiltOnly", -178.0), ("Coarse", -6.0),
               ("Fine", 0.56)]  # fmt: skip
    for k, (aqf, margin) in enumerate(passage):
        rig.feed(10.0 + k, aqf=aqf, hga_margin_predicted_deg=margin, command="GET_FINE_ATTITUDE")
    assert rig.alarms() == []
    # a drive is no acquisition: losing the attitude there is an alarm
    rig.feed(20.0, aqf="TiltOnly", hga_margin_predicted_deg=-178.0, command="DRIVE_STRAIGHT "
             "distance_m=2.0")  # fmt: skip
    assert [a["channel"] for a in rig.alarms()] == ["aqf"]
    # an acquisition that failed: judged again once the command is over
    rig.feed(30.0, aqf="Unknown", command="NADIR_UPDATE")
    (aqf_alarm,) = rig.alarms()
    assert (aqf_alarm["level"], aqf_alarm["violations"]) == ("warning", 1)
    rig.feed(31.0, aqf="Unknown", command="")
    assert rig.alarms()[0]["level"] == "critical"


def test_an_alarm_raised_again_carries_its_latest_value_and_time_stored(rig: Rig) -> None:
    rig.feed(1.0, aqf="Unknown")
    rig.feed(2.0, aqf="Fine")  # cleared, not acknowledged
    rig.feed(3.0, aqf="TiltOnly")  # raised again (after a NADIR_UPDATE)
    (alarm,) = rig.alarms()
    assert (alarm["level"], alarm["value"], alarm["violations"]) == ("critical", "Unknown", 2)
    assert alarm["latest"] == {"value": "TiltOnly", "t_s": 3.0, "utc": "utc-3",
                               "lmst_h": 3.0 / 3600, "sol": 7}  # fmt: skip
    assert rig.notices[-1]["alarm"]["latest"]["value"] == "TiltOnly"
    rig.engine = rig.new_engine()  # stored: a restarted server says the same
    assert rig.alarms()[0]["latest"]["value"] == "TiltOnly"
    # a number's latest value follows it (stored at least once a minute of the rover's clock)
    rig.feed(4.0, tilt_accel_deg=26.0)
    rig.feed(100.0, tilt_accel_deg=27.5)
    tilt = next(a for a in rig.alarms() if a["channel"] == "tilt_accel_deg")
    assert (tilt["value"], tilt["latest"]["value"], tilt["latest"]["t_s"]) == (26.0, 27.5, 100.0)


def test_an_alarm_keeps_its_active_spans_raised_to_cleared(rig: Rig) -> None:
    rig.feed(1.0, aqf="Unknown")
    rig.feed(2.0, aqf="Fine")
    rig.feed(3.0, aqf="TiltOnly")
    rig.feed(4.0, aqf="Coarse")
    rig.feed(5.0, aqf="Unknown")
    (alarm,) = rig.alarms()
    assert alarm["spans"] == [{"from_t_s": 1.0, "to_t_s": 2.0}, {"from_t_s": 3.0, "to_t_s": 4.0},
                              {"from_t_s": 5.0, "to_t_s": None}]  # fmt: skip


def test_an_operator_shelves_an_alarm_for_a_duration_of_the_rovers_clock(rig: Rig) -> None:
    rig.feed(1.0, tilt_accel_deg=26.0)
    rig.feed(2.0, tilt_accel_deg=20.0)  # cleared, unacknowledged
    (alarm,) = rig.alarms()
    shelved = rig.engine.shelve(alarm["id"], 100.0, "ada", "driving up the slope", now_t_s=2.0)
    assert shelved["shelved"] == {"by": "ada", "reason": "driving up the slope", "until": {
        "t_s": 102.0, "utc": "utc-102", "lmst_h": 102.0 / 3600, "sol": 7}}  # fmt: skip
    rig.feed(50.0, tilt_accel_deg=31.0)  # shelved: neither raised again nor escalated
    (during,) = rig.alarms()
    assert (during["level"], during["violations"], during["cleared"]) == ("warning", 1, {
        "t_s": 2.0, "utc": "utc-2", "lmst_h": 2.0 / 3600})  # fmt: skip
    assert during["latest"]["value"] == 31.0  # but its latest value is kept
    rig.engine = rig.new_engine()  # the shelf is stored
    rig.feed(101.0, tilt_accel_deg=31.0)
    assert rig.alarms()[0]["violations"] == 1
    rig.feed(103.0, tilt_accel_deg=31.0)  # the shelf is over: judged again
    (after,) = rig.alarms()
    assert (after["level"], after["violations"], after["shelved"]) == ("critical", 2, None)
    with pytest.raises(UnknownAlarmError):
        rig.engine.shelve(999, 10.0, "ada", "", now_t_s=103.0)
    rig.engine.shelve(after["id"], 10.0, "ada", "", now_t_s=103.0)
    assert rig.engine.unshelve(after["id"], "bob")["shelved"] is None
    with pytest.raises(AlarmConflictError):
        rig.engine.unshelve(after["id"], "bob")


def test_data_that_comes_down_late_is_judged_with_its_own_time_and_arrival(rig: Rig) -> None:
    """Across light time: the downlink alone, when it reaches the ground (``received_t_s``).
    An alarm names the data's time and its arrival; data older than the newest judged (a pass
    filling in what it sent decimated) never raises an alarm as if it were now."""

    def arrive(received_t_s: float, *frames: dict[str, Any]) -> None:
        whole = batch([{"aqf": "Fine", "command": "", **f} for f in frames])
        rig.engine.publish("spirit", FrameBatch(whole.downlink, [], received_t_s))

    arrive(5_000.0, {"t_s": 100.0, "tilt_accel_deg": 10.0}, {"t_s": 400.0, "tilt_accel_deg": 27.0})
    (alarm,) = rig.alarms()
    assert alarm["raised"]["t_s"] == 400.0  # the data's own time, not the arrival
    assert alarm["received"]["t_s"] == 5_000.0
    assert "received" in rig.notices[-1]["alarm"] and rig.notices[-1]["alarm"]["received"]
    # a pass fills in a frame from before the newest judged: not judged, however bad
    arrive(6_000.0, {"t_s": 200.0, "imu_integration_s": 99_999.0})
    assert [a["channel"] for a in rig.alarms()] == ["tilt_accel_deg"]
    # newer data is judged, and clears with its own time
    arrive(7_000.0, {"t_s": 500.0, "tilt_accel_deg": 10.0})
    assert rig.alarms()[0]["cleared"]["t_s"] == 500.0


def test_the_live_truth_alone_judges_only_the_truth_channels(rig: Rig) -> None:
    rig.engine.set_limits("spirit", "hga_margin_deg", {"warning": 0.5, "critical": 0.0}, "op", None)
    whole = batch([{"t_s": 10.0, "aqf": "Fine", "command": "", "tilt_accel_deg": 40.0,
                    "earth_up": True, "hga_margin_deg": -5.0}])  # fmt: skip
    rig.engine.publish("spirit", FrameBatch([], whole.truth))
    alarms = rig.alarms()
    # the truth channel judged on the truth alone; the rover's own tilt is not in it
    assert [(a["channel"], a["truth"], a["level"]) for a in alarms] == [
        ("hga_margin_deg", True, "critical")
    ]
