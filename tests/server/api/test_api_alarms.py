"""Limits and alarms over REST and the WebSocket, against the real app (no clock thread: the
rover is played out by hand): a new rover's frames raise its alarms through the frame hook,
they reach the sol timeline, an acknowledgement is a notice to every console and a row of
the audit log, every bad limit is a 4xx naming the problem with nothing stored, and a
database from before alarms opens with their tables added and its data kept."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import text

from server.app import ServerConfig, create_app, data_dir_url
from server.storage import Store

TOKEN = "alarms-api-token"
AUTH = {"Authorization": f"Bearer {TOKEN}"}


@pytest.fixture(scope="module")
def client(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    url = data_dir_url(tmp_path_factory.mktemp("alarms_api"))
    app = create_app(ServerConfig(database_url=url, operator_token=TOKEN, start_clocks=False))
    with TestClient(app) as c:
        runtime = app.state.server.rovers["spirit"]
        runtime._idle(30.0)  # the rover's first frames, played out through the sinks
        yield c


def _alarms(client: TestClient, **params: Any) -> list[dict[str, Any]]:
    r = client.get("/api/rovers/spirit/alarms", params=params)
    assert r.status_code == 200, r.text
    alarms: list[dict[str, Any]] = r.json()
    return alarms


def test_a_new_rover_raises_its_alarms_and_the_timeline_shows_them(client: TestClient) -> None:
    # issue 21: a fresh rover opens with its attitude Unknown and nothing else to alarm: not
    # the predicted HGA margin (meaningless without a heading), nor the true one (truth)
    alarms = {a["channel"]: a for a in _alarms(client)}
    assert set(alarms) == {"aqf"}
    aqf = alarms["aqf"]
    assert (aqf["level"], aqf["value"], aqf["limit"], aqf["truth"]) == (
        "critical", "Unknown", "Unknown", False,
    )  # fmt: skip
    raised = aqf["raised"]
    assert raised["sol"] == 100 and raised["utc"].startswith("2004-04-14T15:00")
    assert 8.5 < raised["lmst_h"] < 8.6
    assert set(aqf) == {"id", "rover", "channel", "level", "truth", "value", "limit", "units",
                        "message", "violations", "raised", "acknowledged", "cleared", "latest",
                        "spans", "shelved", "received"}  # fmt: skip
    assert aqf["received"] is None  # the link is instant: the data came down as it was made
    assert aqf["latest"]["value"] == "Unknown" and aqf["latest"]["t_s"] >= raised["t_s"]
    assert aqf["spans"] == [{"from_t_s": raised["t_s"], "to_t_s": None}]
    assert opportunity_is_quiet(client)
    timeline = client.get(f"/api/rovers/spirit/sols/{raised['sol']}/timeline").json()
    assert {a["channel"] for a in timeline["alarms"]} == set(alarms)
    assert client.get("/api/rovers/spirit/alarms", params={"limit": 0}).status_code == 422
    assert client.get("/api/rovers/mars2020/alarms").status_code == 404


def opportunity_is_quiet(client: TestClient) -> bool:
    return client.get("/api/rovers/opportunity/alarms").json() == []


def test_an_acknowledgement_is_a_notice_and_audited(client: TestClient) -> None:
    aqf = next(a for a in _alarms(client) if a["channel"] == "aqf")
    with client.websocket_connect("/ws/rovers/spirit/telemetry") as ws:
        r = client.post(f"/api/alarms/{aqf['id']}/acknowledge", headers=AUTH)
        assert r.status_code == 200, r.text
        notice = ws.receive_json()
    assert notice["type"] == "alarm" and notice["alarm"]["id"] == aqf["id"]
    assert notice["alarm"]["acknowledged"]["by"] == "bootstrap"
    assert r.json()["acknowledged"] == notice["alarm"]["acknowledged"]
    again = client.post(f"/api/alarms/{aqf['id']}/acknowledge", headers=AUTH)
    assert again.status_code == 409 and "bootstrap" in again.json()["detail"]
    assert client.post("/api/alarms/99999/acknowledge", headers=AUTH).status_code == 404
    assert client.post("/api/alarms/0/acknowledge", headers=AUTH).status_code == 422
    # still listed: acknowledged but not cleared
    assert aqf["id"] in {a["id"] for a in _alarms(client, active=True)}
    rows = client.get("/api/audit", headers=AUTH, params={"rover": "spirit"}).json()
    assert any(r["action"] == f"acknowledge alarm #{aqf['id']} (aqf)" for r in rows)


@pytest.mark.parametrize(
    ("channel", "body", "status", "problem"),
    [
        ("tilt_accel_deg", '{"warning": 35, "critical": 30}', 422, "must be at or above warning"),
        ("tilt_accel_deg", '{"warning": NaN, "critical": 30}', 422, "NaN is not a JSON number"),
        ("tilt_accel_deg", '{"warning": 1e999, "critical": 30}', 422, "out of range"),
        ("tilt_accel_deg", '{"warning": true, "critical": 30}', 422, "valid number"),
        ("tilt_accel_deg", '{"warning": 20}', 422, "critical"),
        ("tilt_accel_deg", '{"warning": 20, "critical": 30, "colour": 1}', 422, "colour"),
        ("tilt_accel_deg", '{"warning": 20, "critical": 30, "hysteresis": -1}', 422, "hysteresis"),
        ("aqf", '{"warning": "Superb", "critical": null}', 422, "must be one of"),
        ("aqf", '{"warning": "Coarse", "critical": null, "hysteresis": 1}', 422, "numeric"),
        ("nate_mode", '{"warning": "Idle", "critical": []}', 422, "list of states"),
        ("warp_core", '{"warning": 1, "critical": 2}', 404, "unknown channel 'warp_core'"),
        ("tilt_accel_deg", "[1, 2]", 422, "valid dictionary"),
    ],
)
def test_a_bad_limit_is_refused_naming_the_problem_and_nothing_is_stored(
    client: TestClient, channel: str, body: str, status: int, problem: str
) -> None:
    before = client.get("/api/rovers/spirit/limits").json()
    r = client.put(f"/api/rovers/spirit/limits/{channel}", content=body,
                   headers={**AUTH, "Content-Type": "application/json"})  # fmt: skip
    assert r.status_code == status, r.text
    assert problem in r.text
    assert client.get("/api/rovers/spirit/limits").json() == before
    assert client.app.state.server.store.stored_limits("spirit") == {}  # type: ignore[attr-defined]


def test_a_limit_is_changed_judged_at_once_stored_audited_and_reset(client: TestClient) -> None:
    r = client.put("/api/rovers/spirit/limits/hga_margin_predicted_deg", headers=AUTH,
                   json={"warning": -179.0, "critical": -200.0, "hysteresis": 0.5})  # fmt: skip
    assert r.status_code == 200, r.text
    body = r.json()
    assert (body["warning"], body["critical"], body["hysteresis"], body["edited_by"]) == (
        -179.0, -200.0, 0.5, "bootstrap",
    )  # fmt: skip
    assert body["default"] == {"warning": 0.1, "critical": 0.0, "hysteresis": 0.05}
    rows = client.get("/api/audit", headers=AUTH, params={"method": "PUT"}).json()
    assert rows[0]["action"].startswith("set limits of hga_margin_predicted_deg")
    reset = client.delete("/api/rovers/spirit/limits/hga_margin_predicted_deg", headers=AUTH)
    assert reset.status_code == 200 and reset.json()["warning"] == 0.1
    assert reset.json()["edited_by"] is None
    assert client.delete("/api/rovers/spirit/limits/nope", headers=AUTH).status_code == 404
    # the rover is still Unknown: the AQF without levels clears its (acknowledged) alarm at
    # once; back to the default, a new one is raised at once
    aqf = next(a for a in _alarms(client) if a["channel"] == "aqf")
    r = client.put("/api/rovers/spirit/limits/aqf", headers=AUTH,
                   json={"warning": None, "critical": None})  # fmt: skip
    assert r.status_code == 200, r.text
    cleared = next(a for a in _alarms(client) if a["id"] == aqf["id"])
    assert cleared["cleared"] is not None
    assert client.delete("/api/rovers/spirit/limits/aqf", headers=AUTH).status_code == 200
    (again,) = [a for a in _alarms(client, active=True) if a["channel"] == "aqf"]
    assert again["cleared"] is None and again["value"] == "Unknown"


@pytest.mark.parametrize(
    ("body", "problem"),
    [
        ('{"duration_s": 0}', "greater than 0"),
        ('{"duration_s": -60}', "greater than 0"),
        ('{"duration_s": NaN}', "NaN is not a JSON number"),
        ('{"duration_s": 1e999}', "out of range"),
        ('{"duration_s": 200000}', "less than or equal to 177550"),
        ('{"duration_s": "600"}', "valid number"),
        ('{"duration_s": 600, "until": 1}', "until"),
        ('{"reason": "no duration"}', "duration_s"),
        ('{"duration_s": 600, "reason": "' + "x" * 300 + '"}', "at most 200 characters"),
    ],
)
def test_a_bad_shelve_is_refused_naming_the_problem_and_nothing_is_stored(
    client: TestClient, body: str, problem: str
) -> None:
    aqf = next(a for a in _alarms(client, active=True) if a["channel"] == "aqf")
    r = client.post(f"/api/alarms/{aqf['id']}/shelve", content=body,
                    headers={**AUTH, "Content-Type": "application/json"})  # fmt: skip
    assert r.status_code == 422, r.text
    assert problem in r.text
    assert next(a for a in _alarms(client) if a["id"] == aqf["id"])["shelved"] is None


def test_an_operator_shelves_and_unshelves_an_alarm_audited(client: TestClient) -> None:
    aqf = next(a for a in _alarms(client, active=True) if a["channel"] == "aqf")
    url = f"/api/alarms/{aqf['id']}/shelve"
    assert client.post(url, json={"duration_s": 600}).status_code == 401  # operators only
    now_t_s = client.get("/api/rovers/spirit/state").json()["frame"]["t_s"]
    with client.websocket_connect("/ws/rovers/spirit/telemetry") as ws:
        r = client.post(url, headers=AUTH, json={"duration_s": 600, "reason": "rehearsal"})
        assert r.status_code == 200, r.text
        notice = ws.receive_json()
    shelved = r.json()["shelved"]
    assert notice["alarm"]["shelved"] == shelved
    assert (shelved["by"], shelved["reason"]) == ("bootstrap", "rehearsal")
    assert shelved["until"]["t_s"] == pytest.approx(now_t_s + 600.0)
    rows = client.get("/api/audit", headers=AUTH, params={"rover": "spirit"}).json()
    assert any(
        row["action"] == f"shelve alarm #{aqf['id']} (aqf) for 600 s: rehearsal" for row in rows
    )
    assert client.post("/api/alarms/99999/shelve", headers=AUTH,
                       json={"duration_s": 60}).status_code == 404  # fmt: skip
    off = client.post(f"/api/alarms/{aqf['id']}/unshelve", headers=AUTH)
    assert off.status_code == 200 and off.json()["shelved"] is None
    twice = client.post(f"/api/alarms/{aqf['id']}/unshelve", headers=AUTH)
    assert twice.status_code == 409 and "not shelved" in twice.json()["detail"]


def test_a_database_from_before_alarms_gains_their_tables_and_keeps_its_data(
    tmp_path: Path,
) -> None:
    url = f"sqlite:///{tmp_path / 'old.db'}"
    store = Store(url)
    seq = store.add_sequence("spirit", "old", "NADIR_UPDATE", "text", "queued", [], [], [])
    with store.engine.begin() as conn:  # the schema before this version
        conn.execute(text("DROP TABLE alarms"))
        conn.execute(text("DROP TABLE alarm_limits"))
    store.close()
    upgraded = Store(url)
    try:
        assert upgraded.get_sequence(seq) is not None
        assert upgraded.alarms("spirit") == [] and upgraded.stored_limits("spirit") == {}
        upgraded.set_limits("spirit", "aqf", {"warning": None, "critical": "Unknown"}, "ada")
        assert upgraded.stored_limits("spirit")["aqf"]["updated_by"] == "ada"
    finally:
        upgraded.close()


def test_a_database_from_before_latest_values_spans_and_shelves_gains_their_columns(
    tmp_path: Path,
) -> None:
    from server.alarms import alarm_json

    url = f"sqlite:///{tmp_path / 'old.db'}"
    store = Store(url)
    with store.engine.begin() as conn:  # the alarms table of the release before issue 21
        for column in ("latest", "spans", "shelved"):
            conn.execute(text(f"ALTER TABLE alarms DROP COLUMN {column}"))
        conn.execute(text(
            "INSERT INTO alarms (rover, channel, level, truth, value, limit_value, units, "
            "message, violations, raised_t_s, raised_utc, raised_lmst_h, raised_sol, "
            "cleared_t_s, cleared_utc, cleared_lmst_h) VALUES ('spirit', 'aqf', 'critical', "
            "0, '\"Unknown\"', '\"Unknown\"', '', 'aqf Unknown', 1, 10.0, 'u10', 8.5, 100, "
            "20.0, 'u20', 8.6)"
        ))  # fmt: skip
    store.close()
    upgraded = Store(url)
    try:
        (old,) = [alarm_json(row) for row in upgraded.alarms("spirit")]
        # what the old row knew: its raising value is its latest, one span
        assert old["latest"] == {"value": "Unknown", "t_s": 10.0, "utc": "u10", "lmst_h": 8.5,
                                 "sol": 100}  # fmt: skip
        assert old["spans"] == [{"from_t_s": 10.0, "to_t_s": 20.0}] and old["shelved"] is None
    finally:
        upgraded.close()
