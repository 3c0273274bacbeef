"""The operations server's REST and WebSocket API against a real app on a temporary SQLite
database: every route, the operator token, bad input (422 with every error at once, 413),
and a sequence run at full speed through to its sol timeline."""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from server.app import ServerConfig, create_app, data_dir_url
from server.state import MAX_UPLOAD_BYTES
from server.validation.uploads import too_large

TOKEN = "test-operator-token"
AUTH = {"Authorization": f"Bearer {TOKEN}"}
EXAMPLES = Path(__file__).resolve().parents[3] / "sequences" / "examples"
GOOD = "SEQUENCE api_test\nNADIR_UPDATE\nDRIVE_STRAIGHT distance_m=1.5\n"
BAD = (
    "SEQUENCE broken\n"
    "DRIVE_STRAIGHT distance_m=-3\n"
    "FLY_AWAY speed=3\n"
    "TURN_IN_PLACE angle_deg=0\n"
    "NADIR_UPDATE window_s=abc\n"
)


@pytest.fixture(scope="module")
def client(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    url = data_dir_url(tmp_path_factory.mktemp("api"))
    app = create_app(ServerConfig(database_url=url, operator_token=TOKEN, max_upload_bytes=20_000))
    with TestClient(app) as c:
        yield c


def _wait(predicate: Any, timeout_s: float = 60.0) -> Any:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(0.1)
    raise AssertionError("timed out")


def test_rovers_and_state(client: TestClient) -> None:
    rovers = client.get("/api/rovers").json()
    assert {r["rover"] for r in rovers} == {"spirit", "opportunity"}
    assert {r["site"] for r in rovers} == {"gusev", "meridiani"}
    state = client.get("/api/rovers/spirit/state").json()
    assert {"t_s", "utc", "sol", "lmst_h", "clock", "queue", "executing", "frame"} <= set(state)
    assert client.get("/api/rovers/curiosity/state").status_code == 404


def test_the_command_dictionary_lists_every_command(client: TestClient) -> None:
    names = {c["command"] for c in client.get("/api/commands").json()}
    assert {"DRIVE_STRAIGHT", "GET_FINE_ATTITUDE", "SUNCHECK_SUNGAZE", "HGA_PASS"} <= names


def test_the_command_dictionary_publishes_units_ranges_and_notes(client: TestClient) -> None:
    """Each argument's kind, unit, range, default and note (tests/sequences/test_command_specs.py
    checks every published range against the validation)."""
    dictionary = client.get("/api/commands").json()
    published = {c["command"]: {a["name"]: a for a in c["args"]} for c in dictionary}
    keys = {"name", "type", "unit", "min", "max", "min_exclusive", "range", "default",
            "required", "note"}  # fmt: skip
    assert all(set(a) == keys for args in published.values() for a in args.values())
    assert published["DRIVE_STRAIGHT"]["distance_m"] == {
        "name": "distance_m", "type": "number", "unit": "m", "min": 0.0, "max": 100.0,
        "min_exclusive": True, "range": "(0, 100] m", "default": None, "required": True,
        "note": None,
    }  # fmt: skip
    radius = published["DRIVE_ARC"]["radius_m"]
    assert (radius["min"], radius["max"], radius["min_exclusive"]) == (-1000.0, 1000.0, False)
    assert "0.6 m" in radius["note"] and "100 m" in published["DRIVE_ARC"]["angle_deg"]["note"]
    assert "not zero" in published["TURN_IN_PLACE"]["angle_deg"]["note"]
    hga = published["HGA_PASS"]["duration_min"]
    assert (hga["unit"], hga["default"], hga["required"]) == ("min", 15.0, False)
    window = published["NADIR_UPDATE"]["window_s"]
    assert (window["default"], window["required"], window["unit"]) == (None, False, "s")
    gravity = published["SUNGAZE"]["use_gravity"]
    assert (gravity["type"], gravity["unit"], gravity["min"], gravity["range"]) == (
        "boolean", None, None, None
    )  # fmt: skip
    assert published["SET_PARAM"]["param"]["type"] == "string"
    assert published["SET_PARAM"]["value"]["type"] == "number_or_boolean"
    assert all(a["required"] for a in published["SET_PARAM"].values())
    assert published["PLANT_SITE"] == {}


@pytest.mark.parametrize(
    ("headers", "status"),
    [({}, 401), ({"Authorization": "Bearer wrong-token"}, 403), ({"X-Operator-Token": "x"}, 403)],
)
def test_operator_routes_need_the_token_and_change_nothing(
    client: TestClient, headers: dict[str, str], status: int
) -> None:
    before = client.get("/api/rovers/spirit/sequences").json()
    clock = client.get("/api/rovers/spirit/state").json()["clock"]
    assert (
        client.post("/api/rovers/spirit/sequences", content=GOOD, headers=headers).status_code
        == status
    )
    cmd_body = {"command": "NADIR_UPDATE", "args": {}}
    assert (
        client.post("/api/rovers/spirit/commands", json=cmd_body, headers=headers).status_code
        == status
    )
    r = client.post("/api/rovers/spirit/clock", json={"action": "pause"}, headers=headers)
    assert r.status_code == status
    assert client.get("/api/rovers/spirit/sequences").json() == before
    assert client.get("/api/rovers/spirit/state").json()["clock"] == clock


def test_a_sequence_with_many_errors_is_rejected_with_all_of_them(client: TestClient) -> None:
    r = client.post("/api/rovers/opportunity/sequences", content=BAD, headers=AUTH)
    assert r.status_code == 422
    body = r.json()
    assert body["status"] == "rejected"
    assert [e["line"] for e in body["errors"]] == [2, 3, 4, 5]
    stored = client.get(f"/api/sequences/{body['id']}").json()
    assert stored["status"] == "rejected" and len(stored["errors"]) == 4
    assert stored["name"] == "broken"  # its SEQUENCE line, though other lines have errors
    assert client.get("/api/rovers/opportunity/state").json()["queue"] == []


def test_validate_only_stores_nothing(client: TestClient) -> None:
    before = client.get("/api/rovers/spirit/sequences").json()
    r = client.post("/api/sequences/validate", content=BAD)
    assert r.status_code == 200 and r.json()["valid"] is False and len(r.json()["errors"]) == 4
    ok = client.post("/api/sequences/validate?rover=spirit", json={"text": GOOD}).json()
    assert ok["valid"] is True
    assert client.get("/api/rovers/spirit/sequences").json() == before


def test_oversized_upload_413_and_bad_bodies_422(client: TestClient) -> None:
    big = "WAIT duration_s=1\n" * 2000  # 36 kB > the 20 kB limit of this server
    r = client.post("/api/rovers/spirit/sequences", content=big, headers=AUTH)
    assert r.status_code == 413
    # the message names the limit (issue 21), as README and docs/sequences.md give it
    assert r.json()["detail"] == "body over the upload limit of 0.02 MB (20000 bytes)"
    assert too_large(MAX_UPLOAD_BYTES).detail == (
        "body over the upload limit of 1 MB (1000000 bytes)"
    )
    r = client.post("/api/rovers/spirit/clock", json={"speed": 0.5}, headers=AUTH)
    assert r.status_code == 422 and "speed" in r.text
    r = client.post("/api/rovers/spirit/clock", json={"warp": 9}, headers=AUTH)
    assert r.status_code == 422
    r = client.post(
        "/api/rovers/spirit/commands",
        json={"command": "DRIVE_STRAIGHT", "args": {"distance_m": 1e6}},
        headers=AUTH,
    )
    assert r.status_code == 422 and "distance_m" in r.text
    assert client.get("/api/rovers/spirit/telemetry?every=-1").status_code == 422


def test_cancel_a_queued_sequence(client: TestClient) -> None:
    assert (
        client.post(
            "/api/rovers/opportunity/clock", json={"action": "pause"}, headers=AUTH
        ).status_code
        == 200
    )
    r = client.post("/api/rovers/opportunity/sequences", content=GOOD, headers=AUTH)
    assert r.status_code == 201
    seq_id = r.json()["id"]
    assert seq_id in [
        q["sequence_id"] for q in client.get("/api/rovers/opportunity/state").json()["queue"]
    ]
    assert client.delete(f"/api/sequences/{seq_id}").status_code == 401
    assert client.delete(f"/api/sequences/{seq_id}", headers=AUTH).json()["status"] == "cancelled"
    assert client.get(f"/api/sequences/{seq_id}").json()["status"] == "cancelled"
    assert client.delete(f"/api/sequences/{seq_id}", headers=AUTH).status_code == 409
    assert client.get("/api/rovers/opportunity/state").json()["queue"] == []
    client.post("/api/rovers/opportunity/clock", json={"action": "resume"}, headers=AUTH)


def test_a_sequence_runs_at_max_speed_and_shows_on_the_timeline(client: TestClient) -> None:
    files = {"file": ("fine.seq", (EXAMPLES / "fine_attitude_then_drive.seq").read_bytes())}
    r = client.post("/api/rovers/spirit/sequences", files=files, headers=AUTH)
    assert r.status_code == 201, r.text
    seq_id = r.json()["id"]
    assert (
        client.post("/api/rovers/spirit/clock", json={"speed": "max"}, headers=AUTH).json()["speed"]
        == "max"
    )
    _wait(lambda: client.get(f"/api/sequences/{seq_id}").json()["status"] == "completed")
    state = _wait(
        lambda: (
            (s := client.get("/api/rovers/spirit/state").json())["frame"]
            and not s["executing"]
            and s
        )
    )
    frame = state["frame"]
    assert frame["aqf"] == "Fine" and frame["p_s_est"][0] ** 2 + frame["p_s_est"][1] ** 2 > 50.0
    sols = client.get("/api/rovers/spirit/sols").json()
    timeline = client.get(f"/api/rovers/spirit/sols/{sols[-1]}/timeline").json()
    names = [c["command"] for c in timeline["commands"]]
    # who sent it: the bootstrap admin token of this server acts as "bootstrap"
    assert {c["submitted_by"] for c in timeline["commands"] if c["sequence_id"] == seq_id} == {
        "bootstrap"
    }
    assert client.get(f"/api/sequences/{seq_id}").json()["submitted_by"] == "bootstrap"
    assert "SUNCHECK_SUNGAZE" in names and any(n.startswith("DRIVE_STRAIGHT") for n in names)
    assert "Fine" in [a["value"] for a in timeline["aqf"]]
    assert timeline["distance_m"] > 9.0
    csv_text = client.get(
        "/api/rovers/spirit/telemetry?every=60", headers={"Accept": "text/csv"}
    ).text
    header, first = csv_text.splitlines()[:2]
    assert header.startswith("t_s,sol,lmst_h,nate_mode,aqf") and len(first.split(",")) == len(
        header.split(",")
    )
    frames = client.get("/api/rovers/spirit/telemetry").json()
    assert [f["t_s"] for f in frames] == sorted(f["t_s"] for f in frames)


def test_immediate_command_runs(client: TestClient) -> None:
    r = client.post(
        "/api/rovers/spirit/commands", json={"command": "PLANT_SITE", "args": {}}, headers=AUTH
    )
    assert r.status_code == 201
    seq_id = r.json()["id"]
    _wait(lambda: client.get(f"/api/sequences/{seq_id}").json()["status"] == "completed")
    frame = _wait(lambda: client.get("/api/rovers/spirit/state").json()["frame"])
    assert frame["site_index"] >= 1


def test_websocket_streams_frames(client: TestClient) -> None:
    client.post("/api/rovers/opportunity/clock", json={"speed": 1000}, headers=AUTH)
    with client.websocket_connect("/ws/rovers/opportunity/telemetry") as ws:
        frames = (m for m in iter(ws.receive_json, None) if "type" not in m)  # notices aside
        first, second = next(frames), next(frames)
    assert {"t_s", "aqf", "nate_mode", "hga_margin_deg", "events", "dropped"} <= set(first)
    assert second["t_s"] > first["t_s"]


def test_a_refused_step_stops_its_sequence(client: TestClient) -> None:
    client.post("/api/rovers/opportunity/clock", json={"speed": "max"}, headers=AUTH)
    text = "SEQUENCE too_far\nDRIVE_TO x_m=500 y_m=0\nPLANT_SITE\n"
    r = client.post("/api/rovers/opportunity/sequences", content=text, headers=AUTH)
    assert r.status_code == 201, r.text
    seq_id = r.json()["id"]
    done = _wait(
        lambda: (s := client.get(f"/api/sequences/{seq_id}").json())["status"] == "failed" and s
    )
    assert "step 1 refused" in done["detail"] and "500" in done["detail"]
    frame = _wait(lambda: client.get("/api/rovers/opportunity/state").json()["frame"])
    assert frame["site_index"] == 0  # PLANT_SITE never ran


def test_unknown_sequences_and_rovers_are_404(client: TestClient) -> None:
    assert client.get("/api/sequences/999999").status_code == 404
    assert client.delete("/api/sequences/999999", headers=AUTH).status_code == 404
    assert client.get("/api/rovers/curiosity/sequences").status_code == 404
    assert client.get("/api/rovers/curiosity/sols").status_code == 404
    assert client.get("/api/rovers/spirit/sols/99999/timeline").status_code == 404
    r = client.post("/api/rovers/curiosity/clock", json={"action": "pause"}, headers=AUTH)
    assert r.status_code == 404
