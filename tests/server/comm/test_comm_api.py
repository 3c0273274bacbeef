"""The comm routes (server.comm.api) on a real app: the ground's view of the link, the mode
an admin changes (audited, kept through a restart), the plan an operator changes (every
field checked, nothing changed by a bad request), and a cancel that goes up."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from server.app import ServerConfig, create_app, data_dir_url

BOOT = "comm-bootstrap-token"


def _app(path: Path, comm: str = "instant") -> Any:
    return create_app(ServerConfig(database_url=data_dir_url(path), operator_token=BOOT,
                                   validation_processes=0, comm=comm))  # fmt: skip


@pytest.fixture
def served(tmp_path: Path) -> Iterator[tuple[TestClient, dict[str, dict[str, str]], Path]]:
    app = _app(tmp_path)
    with TestClient(app) as client:
        accounts = app.state.server.accounts
        headers = {
            role: {"Authorization": f"Bearer {accounts.add_user(f'{role}1', role).token}"}
            for role in ("viewer", "operator")
        }
        headers["admin"] = {"Authorization": f"Bearer {BOOT}"}
        yield client, headers, tmp_path


def test_the_ground_sees_light_time_and_windows(served: Any) -> None:
    client, _, _ = served
    got = client.get("/api/rovers/spirit/comm").json()
    assert got["mode"] == "instant"
    assert 180.0 < got["one_way_light_time_s"] < 1_340.0  # 3 to 22.3 min
    starts = [w["start_t_s"] for w in got["windows"]]
    assert starts == sorted(starts) and got["windows"]
    assert got["next_uplink"]["kind"] == "uplink"
    assert got["next_uplink"]["end_t_s"] > got["now"]["t_s"]
    assert got["next_pass"]["kind"] in ("relay", "dte")
    assert got["store"] is None and got["uplinks"] == []


@pytest.mark.parametrize(
    "query",
    ["from_t_s=0&to_t_s=1e9", "from_t_s=nan&to_t_s=1", "from_t_s=10&to_t_s=5", "from_t_s=abc"],
)
def test_a_bad_span_of_windows_is_refused(served: Any, query: str) -> None:
    client, _, _ = served
    answer = client.get(f"/api/rovers/spirit/comm?{query}")
    assert answer.status_code == 422, answer.text


def test_only_an_admin_changes_the_mode_and_it_is_audited_and_kept(served: Any) -> None:
    client, h, path = served
    for role in ("viewer", "operator"):
        assert client.put("/api/rovers/spirit/comm/mode", json={"mode": "mission"},
                          headers=h[role]).status_code == 403  # fmt: skip
    bad = client.put("/api/rovers/spirit/comm/mode", json={"mode": "slow"}, headers=h["admin"])
    assert bad.status_code == 422
    got = client.put("/api/rovers/spirit/comm/mode", json={"mode": "mission"}, headers=h["admin"])
    assert got.status_code == 200, got.text
    assert got.json()["mode"] == "mission"
    assert client.get("/api/rovers/opportunity/comm").json()["mode"] == "instant"
    audit = client.get("/api/audit", headers=h["admin"]).json()
    rows = audit["entries"] if isinstance(audit, dict) else audit
    assert any("comm mode mission" in (r.get("action") or "") for r in rows)
    client.app.state.server.stop()  # type: ignore[attr-defined]
    with TestClient(_app(path)) as again:
        assert again.get("/api/rovers/spirit/comm").json()["mode"] == "mission"


@pytest.mark.parametrize(
    ("body", "names"),
    [
        ({"relay_rate_bps": -5}, "relay_rate_bps"),
        ({"uplink_lmst_h": 25}, "uplink_lmst_h"),
        ({"store_capacity_mbit": 1e300}, "store_capacity_mbit"),
        ({"warp_factor": 9}, "warp_factor"),
        ({"relay_rate_bps": "fast"}, "relay_rate_bps"),
    ],
)
def test_a_bad_plan_is_refused_naming_the_field_and_nothing_changes(
    served: Any, body: dict[str, Any], names: str
) -> None:
    client, h, _ = served
    before = client.get("/api/rovers/spirit/comm").json()["plan"]
    answer = client.put("/api/rovers/spirit/comm/plan", json=body, headers=h["operator"])
    assert answer.status_code == 422 and names in answer.text, answer.text
    assert client.get("/api/rovers/spirit/comm").json()["plan"] == before


def test_an_operator_changes_the_plan(served: Any) -> None:
    client, h, _ = served
    answer = client.put("/api/rovers/spirit/comm/plan",
                        json={"relay_rate_bps": 256_000, "uplink_lmst_h": 10.5},
                        headers=h["operator"])  # fmt: skip
    assert answer.status_code == 200, answer.text
    plan = answer.json()["plan"]
    assert plan["relay_rate_bps"] == 256_000 and plan["uplink_lmst_h"] == 10.5
    assert all(w["rate_bps"] == 256_000 for w in answer.json()["windows"] if w["kind"] == "relay")


def test_a_sequence_waits_on_the_ground_and_is_cancelled_there(served: Any) -> None:
    client, h, _ = served
    client.put("/api/rovers/spirit/comm/mode", json={"mode": "mission"}, headers=h["admin"])
    client.post("/api/rovers/spirit/clock", json={"action": "pause"}, headers=h["operator"])
    up = client.post("/api/rovers/spirit/sequences", content="SEQUENCE s\nNADIR_UPDATE\n",
                     headers={**h["operator"], "Content-Type": "text/plain"})  # fmt: skip
    assert up.status_code == 201, up.text
    seq_id = up.json()["id"]
    queue = client.get("/api/rovers/spirit/queue").json()["queue"]
    assert [(e["sequence_id"], e["side"], e["status"]) for e in queue] == [
        (seq_id, "ground", "waiting")
    ]
    assert queue[0]["radiate"] is not None
    state = client.get("/api/rovers/spirit/state").json()
    assert [q["sequence_id"] for q in state["queue"]] == [seq_id] and state["comm"] == "mission"
    assert [s["stage"] for s in queue[0]["stages"]] == ["accepted", "waiting"]
    moved = client.post(f"/api/rovers/spirit/queue/{seq_id}/move", json={"to": 0},
                        headers=h["operator"])  # fmt: skip
    assert moved.status_code == 409
    gone = client.delete(f"/api/sequences/{seq_id}", headers=h["operator"])
    assert gone.status_code == 200 and gone.json()["status"] == "cancelled", gone.text
    assert client.get("/api/rovers/spirit/queue").json()["queue"] == []
    assert client.get("/api/rovers/spirit/comm").json()["uplinks"] == []


def test_back_to_instant_everything_on_its_way_goes_through(served: Any) -> None:
    client, h, _ = served
    client.post("/api/rovers/spirit/clock", json={"action": "pause"}, headers=h["operator"])
    client.put("/api/rovers/spirit/comm/mode", json={"mode": "mission"}, headers=h["admin"])
    up = client.post("/api/rovers/spirit/sequences", content="SEQUENCE s\nNADIR_UPDATE\n",
                     headers={**h["operator"], "Content-Type": "text/plain"})  # fmt: skip
    seq_id = up.json()["id"]
    assert client.get("/api/rovers/spirit/queue").json()["queue"][0]["side"] == "ground"
    client.put("/api/rovers/spirit/comm/mode", json={"mode": "instant"}, headers=h["admin"])
    queue = client.get("/api/rovers/spirit/queue").json()["queue"]
    assert [(e["sequence_id"], e.get("side")) for e in queue] == [(seq_id, None)]  # one side
    got = client.get(f"/api/sequences/{seq_id}").json()
    assert [s["stage"] for s in got["stages"]][:4] == [
        "accepted",
        "waiting",
        "radiated",
        "received",
    ]


def test_a_sequence_no_window_can_hold_fails_on_the_ground(served: Any) -> None:
    client, h, _ = served
    client.post("/api/rovers/spirit/clock", json={"action": "pause"}, headers=h["operator"])
    client.put("/api/rovers/spirit/comm/mode", json={"mode": "mission"}, headers=h["admin"])
    # a window of 1 min at 100 bit/s holds 6,000 bits: this sequence is bigger
    client.put("/api/rovers/spirit/comm/plan", json={"uplink_minutes": 1, "uplink_rate_bps": 100},
               headers=h["operator"])  # fmt: skip
    text = "SEQUENCE big\n" + "NADIR_UPDATE\n" * 80
    up = client.post("/api/rovers/spirit/sequences", content=text,
                     headers={**h["operator"], "Content-Type": "text/plain"})  # fmt: skip
    seq_id = up.json()["id"]
    runtime = client.app.state.server.rovers["spirit"]  # type: ignore[attr-defined]
    runtime.comm.advance(runtime.t_s + 1.0)
    got = client.get(f"/api/sequences/{seq_id}").json()
    assert got["status"] == "failed" and "not radiated" in got["detail"], got
    assert client.get("/api/rovers/spirit/queue").json()["queue"] == []
