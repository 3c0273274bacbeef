"""The ``rehearsals`` table (``server.storage.rehearsals``): an older database gains it when
opened, a campaign's outcomes come back as they went in, and the campaigns a stopped server
left unfinished are stored as cancelled."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from sqlalchemy import inspect, text

from server.rehearsal.outcomes import outcomes_from_dicts
from server.storage import Store
from server.storage import rehearsals as stored
from sim.rehearsal.outcome import RunOutcome, StepOutcome


def _outcome(index: int) -> RunOutcome:
    step = StepOutcome(
        line=2, command="DRIVE_STRAIGHT distance_m=1", status="halted", reason="tilt 31 deg",
        start_t_s=1.0e8, end_t_s=1.0e8 + 40.5, p_mission_true_m=(1.25, -0.5),
        p_mission_est_m=(1.2, -0.45), heading_true_rad=0.1, heading_est_rad=0.11,
        max_tilt_true_deg=31.2, aqf="Coarse", imu_integration_s=120.0, position_sigma_m=0.08,
        keepouts_entered=("rock",), path_true_m=((0.0, 0.0), (0.6, -0.2), (1.25, -0.5)),
    )  # fmt: skip
    return RunOutcome(run_index=index, seed=7, steps=(step,), wall_s=1.5, worker="tcp://w")


def test_an_older_database_gains_the_table(tmp_path: Path) -> None:
    url = f"sqlite:///{tmp_path / 'old.db'}"
    store = Store(url)
    with store.engine.begin() as conn:
        conn.execute(text("DROP TABLE rehearsals"))
    store.close()
    again = Store(url)
    try:
        assert "rehearsals" in inspect(again.engine).get_table_names()
        found = stored.add_rehearsal(again, "spirit", "ada", 10, 2**63 - 1, None, "SEQUENCE s\n")
        assert found["seed"] == 2**63 - 1 and found["state"] == "queued"
    finally:
        again.close()


def test_outcomes_and_risk_come_back_as_stored() -> None:
    store = Store("sqlite://")
    try:
        rid = stored.add_rehearsal(store, "spirit", "ada", 2, 3, 12, "SEQUENCE s\n")["id"]
        outcomes = [_outcome(0), _outcome(1)]
        risk = {"runs": 2, "lines": [{"line": 2, "halts": {"tilt": 1.0}}]}
        stored.update_rehearsal(store, rid, state="done", done=2, risk=risk, warmup_s=4.5,
                                outcomes=[o.as_dict() for o in outcomes])  # fmt: skip
        found = stored.get_rehearsal(store, rid, with_outcomes=True)
        assert found is not None and found["risk"] == risk and found["state"] == "done"
        assert found["finished_t_utc"] is not None and found["warmup_s"] == 4.5
        back = outcomes_from_dicts(found["outcomes"])
        assert back == outcomes  # NaN margins back as NaN, tuples as tuples
        assert math.isnan(back[0].steps[0].hga_margin_deg)
        assert [s["id"] for s in stored.list_rehearsals(store, "spirit")] == [rid]
        assert stored.list_rehearsals(store, "opportunity") == []
        with pytest.raises(ValueError, match="state"):
            stored.update_rehearsal(store, rid, state="finished")
        with pytest.raises(KeyError):
            stored.update_rehearsal(store, rid + 1, done=1)
    finally:
        store.close()


def test_unfinished_campaigns_are_cancelled_as_server_stopped() -> None:
    store = Store("sqlite://")
    try:
        ids = [stored.add_rehearsal(store, "spirit", "ada", 5, 0, None, "S\n")["id"]
               for _ in range(3)]  # fmt: skip
        stored.update_rehearsal(store, ids[1], state="running", done=2)
        stored.update_rehearsal(store, ids[2], state="done", done=5)
        assert stored.stop_unfinished(store) == ids[:2]
        states = {
            s["id"]: (s["state"], s["error"]) for s in stored.list_rehearsals(store, "spirit")
        }
        stopped = ("cancelled", "server stopped")
        assert states == {ids[0]: stopped, ids[1]: stopped, ids[2]: ("done", None)}
    finally:
        store.close()
