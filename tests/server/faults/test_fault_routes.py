"""The conductor's fault routes (server.faults) on a real app in training mode
(``--truth-view conductor``): inject, list, reveal; validation naming the problem; the audit
rows; the timeline showing a fault to the conductor at once and to the others only once
revealed; and the fault plan kept by a checkpoint through a restart."""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from server.app import ServerConfig, create_app, data_dir_url

BOOT = "faults-bootstrap-token"
ROVER = "spirit"


def _wait(predicate: Any, what: str, timeout_s: float = 60.0) -> Any:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(0.05)
    raise AssertionError(f"timed out waiting for {what}")


def _app(path: Path) -> Any:
    config = ServerConfig(
        database_url=data_dir_url(path),
        operator_token=BOOT,
        truth_view="conductor",
        validation_processes=0,
    )
    return create_app(config)


@pytest.fixture(scope="module")
def data_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("faults")


@pytest.fixture(scope="module")
def served(data_dir: Path) -> Iterator[tuple[TestClient, dict[str, dict[str, str]]]]:
    app = _app(data_dir)
    with TestClient(app) as client:
        accounts = app.state.server.accounts
        headers = {
            role: {"Authorization": f"Bearer {accounts.add_user(f'{role}1', role).token}"}
            for role in ("viewer", "operator", "conductor")
        }
        yield client, headers


def test_only_a_conductor_injects_lists_and_reveals(served: Any) -> None:
    client, h = served
    for role in ("viewer", "operator"):
        assert client.get(f"/api/rovers/{ROVER}/faults", headers=h[role]).status_code == 403
        body = {"kind": "navcam"}
        got = client.post(f"/api/rovers/{ROVER}/faults", json=body, headers=h[role])
        assert got.status_code == 403
        got = client.post(f"/api/rovers/{ROVER}/faults/reveal", headers=h[role])
        assert got.status_code == 403
    assert not client.get(f"/api/rovers/{ROVER}/faults", headers=h["conductor"]).json()["faults"]


@pytest.mark.parametrize(
    ("body", "loc", "words"),
    [
        ({"kind": "meteor"}, ["body", "kind"], "wheel"),
        ({"kind": "gyro_bias", "parameters": {"axis": "q", "bias_deg_per_h": 1}},
         ["body", "parameters", "axis"], "one of x, y, z"),
        ({"kind": "gyro_bias", "parameters": {"axis": "z"}},
         ["body", "parameters", "bias_deg_per_h"], "required"),
        ({"kind": "pancam_dust", "parameters": {"tau": 11}}, ["body", "parameters", "tau"],
         "[0, 10]"),
        ({"kind": "navcam", "parameters": {"tau": 1}}, ["body", "parameters", "tau"],
         "not a parameter"),
        ({"kind": "navcam", "at_utc": "yesterday"}, ["body", "at_utc"], "ISO 8601"),
        ({"kind": "navcam", "at_utc": "2004-01-01T00:00:00Z"}, ["body", "at_utc"],
         "before the rover's clock"),
        ({"kind": "navcam", "at_sol": 200}, ["body", "at_lmst_h"], "go together"),
        ({"kind": "navcam", "at_lmst_h": 25.0}, ["body", "at_lmst_h"], "24"),
    ],
)  # fmt: skip
def test_a_bad_fault_is_a_422_naming_the_problem(
    served: Any, body: dict[str, Any], loc: list[str], words: str
) -> None:
    client, h = served
    got = client.post(f"/api/rovers/{ROVER}/faults", json=body, headers=h["conductor"])
    assert got.status_code == 422, got.text
    (problem,) = [p for p in got.json()["detail"] if p["loc"] == loc]
    assert words in problem["msg"], problem


def test_a_fault_shows_on_the_timeline_to_the_conductor_then_once_revealed_to_all(
    served: Any,
) -> None:
    client, h = served
    url = f"/api/rovers/{ROVER}"
    body = {"kind": "gyro_bias", "parameters": {"axis": "z", "bias_deg_per_h": 12.5}}
    got = client.post(f"{url}/faults", json=body, headers=h["conductor"])
    assert got.status_code == 201, got.text
    fault = got.json()
    assert fault["state"] == "pending" and fault["description"] == "gyro z bias step +12.5 deg/h"
    assert client.post(f"{url}/clock", json={"speed": "max"}, headers=h["operator"]).is_success
    command = {"command": "WAIT", "args": {"duration_s": 30.0}}
    assert client.post(f"{url}/commands", json=command, headers=h["operator"]).status_code == 201

    def applied() -> dict[str, Any] | None:
        faults = client.get(f"{url}/faults", headers=h["conductor"]).json()["faults"]
        done = [f for f in faults if f["fault_id"] == fault["fault_id"] and f["applied"]]
        return done[0] if done else None

    entry = _wait(applied, "the fault applied")
    assert entry["state"] == "applied" and not entry["revealed"]
    sol = entry["applied"]["sol"]

    def timeline(role: str) -> dict[str, Any]:
        answer = client.get(f"{url}/sols/{sol}/timeline", headers=h[role])
        assert answer.status_code == 200, answer.text
        return dict(answer.json())

    def fault_event(role: str) -> bool:
        events = timeline(role).get("truth", {}).get("events", [])
        return any("gyro z bias step" in e["text"] for e in events)

    _wait(lambda: fault_event("conductor"), "the fault's truth event")
    assert [f["fault_id"] for f in timeline("conductor")["faults"]] == [fault["fault_id"]]
    for role in ("viewer", "operator"):
        seen = timeline(role)
        assert seen["faults"] == [] and "gyro z bias" not in str(seen)
    revealed = client.post(f"{url}/faults/reveal", headers=h["conductor"])
    assert revealed.status_code == 200 and revealed.json()["revealed"] >= 1
    for role in ("viewer", "operator"):
        shown = timeline(role)["faults"]
        assert [(f["fault_id"], f["revealed"]) for f in shown] == [(fault["fault_id"], True)]
        assert "truth" not in timeline(role)  # a revealed fault, not the truth record
    audit = client.app.state.server.audit.query(username="conductor1")  # type: ignore[attr-defined]
    actions = [r["action"] for r in audit]
    assert any(a.startswith(f"inject fault #{fault['fault_id']}: gyro z bias") for a in actions)
    assert any(a.startswith("reveal the faults") for a in actions)


def test_an_injected_fault_survives_a_restart(tmp_path: Path) -> None:
    url = f"/api/rovers/{ROVER}"
    body = {"kind": "pancam_dust", "parameters": {"tau": 2.0}, "at_sol": 900, "at_lmst_h": 12.0}
    boot = {"Authorization": f"Bearer {BOOT}"}
    app = _app(tmp_path)
    with TestClient(app) as client:
        token = app.state.server.accounts.add_user("conductor2", "conductor").token
        conductor = {"Authorization": f"Bearer {token}"}
        assert client.post(f"{url}/clock", json={"action": "pause"}, headers=boot).is_success
        got = client.post(f"{url}/faults", json=body, headers=conductor)
        assert got.status_code == 201, got.text
        runtime = app.state.server.rover(ROVER)

        def stored() -> bool:  # the paused rover checkpointed for the change
            return bool(((runtime._last_state or {}).get("session") or {}).get("faults"))

        _wait(stored, "a checkpoint with the fault")
    again = _app(tmp_path)
    with TestClient(again) as client:
        listed = client.get(f"{url}/faults", headers=conductor).json()["faults"]
    assert [(f["kind"], f["parameters"], f["state"]) for f in listed] == [
        ("pancam_dust", {"tau": 2.0}, "pending")
    ]
    assert listed[0]["at"]["t_s"] == pytest.approx(got.json()["at"]["t_s"])
    assert listed[0]["at"]["sol"] == 900


def test_a_sand_trap_is_laid_where_the_conductor_says(served: Any) -> None:
    client, h = served
    body = {"kind": "sand_trap", "parameters": {"x_m": 3.0, "y_m": 0.0, "radius_m": 1.0}}
    got = client.post(f"/api/rovers/{ROVER}/faults", json=body, headers=h["conductor"])
    assert got.status_code == 201, got.text  # (last: the timeline test counts the faults)
