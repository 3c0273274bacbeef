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
    alarms = {a["channel"]: a for a in _alarms(client)}
    assert set(alarms) == {"aqf", "hga_margin_predicted_deg", "hga_margin_deg"}
    aqf = alarms["aqf"]
    assert (aqf["level"], aqf["value"], aqf["limit"], aqf["truth"]) == (
        "critical", "Unknown", "Unknown", False,
    )  # fmt: skip
    assert alarms["hga_margin_deg"]["truth"] and not alarms["hga_margin_predicted_deg"]["truth"]
    raised = aqf["raised"]
    assert raised["sol"] == 100 and raised["utc"].startswith("2004-04-14T15:00")
    assert 8.5 < raised["lmst_h"] < 8.6
    assert set(aqf) == {"id", "rover", "channel", "level", "truth", "value", "limit", "units",
                        "message", "violations", "raised", "acknowledged", "cleared"}  # fmt: skip
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
    # the rover is still Unknown: a TiltOnly-at-warning AQF limit moved to "none" clears
    # nothing (critical still Unknown); the predicted margin loosened below -178 clears it
    r = client.put("/api/rovers/spirit/limits/hga_margin_predicted_deg", headers=AUTH,
                   json={"warning": -179.0, "critical": -200.0, "hysteresis": 0.5})  # fmt: skip
    assert r.status_code == 200, r.text
    body = r.json()
    assert (body["warning"], body["critical"], body["hysteresis"], body["edited_by"]) == (
        -179.0, -200.0, 0.5, "bootstrap",
    )  # fmt: skip
    assert body["default"] == {"warning": 0.1, "critical": 0.0, "hysteresis": 0.05}
    predicted = next(a for a in _alarms(client) if a["channel"] == "hga_margin_predicted_deg")
    assert predicted["cleared"] is not None  # -178 is 1 deg inside -179 (hysteresis 0.5)
    rows = client.get("/api/audit", headers=AUTH, params={"method": "PUT"}).json()
    assert rows[0]["action"].startswith("set limits of hga_margin_predicted_deg")
    reset = client.delete("/api/rovers/spirit/limits/hga_margin_predicted_deg", headers=AUTH)
    assert reset.status_code == 200 and reset.json()["warning"] == 0.1
    assert reset.json()["edited_by"] is None
    assert client.delete("/api/rovers/spirit/limits/nope", headers=AUTH).status_code == 404
    # judged again at once under the default: raised again (a cleared, unacknowledged alarm)
    again = next(a for a in _alarms(client) if a["id"] == predicted["id"])
    assert again["cleared"] is None and again["violations"] == 2


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
