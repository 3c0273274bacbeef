"""The audit log: every accepted or refused mutating request is a row with who, when (UTC
and the rover's sol and LMST), what and the result; admins read it, filtered, as JSON or
CSV; uploads and commands carry who submitted them."""

from __future__ import annotations

import csv
import io
from collections.abc import Iterator
from datetime import UTC, datetime, timedelta

import pytest
from fastapi.testclient import TestClient

from server.app import ServerConfig, create_app, data_dir_url

ADMIN = {"Authorization": "Bearer audit-bootstrap-token"}
SEQ = "SEQUENCE audited\nNADIR_UPDATE\n"


@pytest.fixture(scope="module")
def setup(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[TestClient, dict[str, str]]]:
    config = ServerConfig(
        database_url=data_dir_url(tmp_path_factory.mktemp("audit")),
        operator_token="audit-bootstrap-token",
        start_clocks=False,
    )
    app = create_app(config)
    accounts = app.state.server.accounts
    tokens = {
        "ada": accounts.add_user("ada", "operator").token,
        "vic": accounts.add_user("vic", "viewer").token,
    }
    with TestClient(app) as client:
        yield client, tokens


def _rows(client: TestClient, **filters: str) -> list[dict[str, object]]:
    r = client.get("/api/audit", params=filters, headers=ADMIN)
    assert r.status_code == 200, r.text
    rows: list[dict[str, object]] = r.json()
    return rows


def test_accepted_and_refused_requests_are_rows_with_who_when_what(
    setup: tuple[TestClient, dict[str, str]],
) -> None:
    client, tokens = setup
    ada = {"Authorization": f"Bearer {tokens['ada']}"}
    vic = {"Authorization": f"Bearer {tokens['vic']}"}
    start = datetime.now(UTC) - timedelta(seconds=1)
    up = client.post("/api/rovers/spirit/sequences", content=SEQ, headers=ada)
    assert up.status_code == 201
    assert client.post("/api/rovers/spirit/clock", json={"action": "pause"}).status_code == 401
    assert (
        client.post("/api/rovers/spirit/clock", json={"action": "pause"}, headers=vic).status_code
        == 403
    )
    bad = {"Authorization": "Bearer forged"}
    assert client.delete(f"/api/sequences/{up.json()['id']}", headers=bad).status_code == 403
    assert client.post("/api/sequences/validate", content=SEQ).status_code == 200  # not a change

    # the server's own start is a row too (tests/server/test_server_restart.py): not a request
    rows = [r for r in _rows(client, since=start.isoformat()) if r["username"] != "server"]
    newest_first = [(r["username"], r["method"], r["status"], r["result"]) for r in rows]
    assert newest_first == [
        ("anonymous", "DELETE", 403, "refused"),
        ("vic", "POST", 403, "refused"),
        ("anonymous", "POST", 401, "refused"),
        ("ada", "POST", 201, "accepted"),
    ]
    accepted = rows[-1]
    assert accepted["rover"] == "spirit" and accepted["role"] == "operator"
    assert accepted["action"] == f"upload sequence audited (#{up.json()['id']}): queued"
    clock = str(accepted["rover_clock"])
    assert clock.startswith("sol ") and clock.endswith(" LMST")
    assert datetime.fromisoformat(str(accepted["at"])) >= start
    assert "needs the operator role" in str(rows[1]["detail"])
    assert "token required" in str(rows[2]["detail"])
    # refused before the route looked the sequence up: its path says which one
    assert rows[0]["path"] == f"/api/sequences/{up.json()['id']}" and rows[0]["rover"] is None
    assert str(rows[0]["detail"]).startswith("wrong token")


def test_the_log_filters_and_exports_csv(setup: tuple[TestClient, dict[str, str]]) -> None:
    client, tokens = setup
    ada = {"Authorization": f"Bearer {tokens['ada']}"}
    client.post("/api/rovers/opportunity/commands", json={"command": "PLANT_SITE"}, headers=ada)
    mine = _rows(client, user="ada")
    assert mine and {r["username"] for r in mine} == {"ada"}
    assert {r["result"] for r in _rows(client, result="refused")} == {"refused"}
    assert {r["rover"] for r in _rows(client, rover="opportunity")} == {"opportunity"}
    assert len(_rows(client, limit="1")) == 1
    future = (datetime.now(UTC) + timedelta(days=1)).isoformat()
    assert _rows(client, since=future) == []
    table = client.get("/api/audit", params={"format": "csv", "user": "ada"}, headers=ADMIN)
    assert table.headers["content-type"].startswith("text/csv")
    parsed = list(csv.DictReader(io.StringIO(table.text)))
    assert len(parsed) == len(mine) and parsed[0]["username"] == "ada"
    for bad in ({"limit": "0"}, {"result": "maybe"}, {"since": "yesterday"}, {"user": "x" * 65}):
        assert client.get("/api/audit", params=bad, headers=ADMIN).status_code == 422


def test_sequences_and_commands_say_who_sent_them(
    setup: tuple[TestClient, dict[str, str]],
) -> None:
    client, tokens = setup
    ada = {"Authorization": f"Bearer {tokens['ada']}"}
    sent = client.post("/api/rovers/spirit/commands", json={"command": "PLANT_SITE"}, headers=ada)
    assert sent.status_code == 201
    listed = client.get("/api/rovers/spirit/sequences").json()
    assert {s["id"]: s["submitted_by"] for s in listed}[sent.json()["id"]] == "ada"
    assert client.get(f"/api/sequences/{sent.json()['id']}").json()["submitted_by"] == "ada"


def test_user_management_over_the_api_is_audited(
    setup: tuple[TestClient, dict[str, str]],
) -> None:
    client, _ = setup
    made = client.post("/api/users", json={"name": "newbie", "role": "viewer"}, headers=ADMIN)
    assert made.status_code == 201 and len(made.json()["token"]) >= 43
    newbie = {"Authorization": f"Bearer {made.json()['token']}"}
    assert client.get("/api/me", headers=newbie).json()["role"] == "viewer"
    assert client.post("/api/users", json={"name": "newbie", "role": "viewer"},
                       headers=ADMIN).status_code == 409  # fmt: skip
    for body in ({"name": "x y", "role": "viewer"}, {"name": "ok", "role": "god"},
                 {"name": "ok", "role": "viewer", "expires_days": -1},
                 {"name": "ok", "role": "viewer", "expires_days": True}):  # fmt: skip
        assert client.post("/api/users", json=body, headers=ADMIN).status_code == 422
    assert client.delete("/api/users/newbie/tokens", headers=ADMIN).json()["revoked"] == 1
    assert client.get("/api/me", headers=newbie).status_code == 403
    assert client.delete("/api/users/ghost/tokens", headers=ADMIN).status_code == 404
    actions = [r["action"] for r in _rows(client, user="bootstrap")]
    assert "add user newbie as viewer" in actions and "revoke the tokens of newbie" in actions
