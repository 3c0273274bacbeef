"""``/api/rovers/{rover}/rehearsals`` (``server.rehearsal.api``): who may start and cancel,
every bad request refused with its reason, campaigns run on a real embedded Dask cluster (one
worker) with the real engine, listed, cancelled, limited per user, reported against the
executed run, and still there after a restart."""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from server.app import Server, ServerConfig, create_app, data_dir_url
from server.rehearsal.service import MAX_RUNNING_PER_USER, RehearsalService
from server.runtime import RoverRuntime

BOOTSTRAP = "rehearsal-api-admin-token"
URL = "/api/rovers/spirit/rehearsals"
SHORT = "SEQUENCE short\nDRIVE_STRAIGHT distance_m=0.5\nWAIT duration_s=2\n"
LONG = "SEQUENCE long\nDRIVE_STRAIGHT distance_m=6\n"
Auth = dict[str, str]


def tick_until_idle(runtime: RoverRuntime) -> None:
    """Run the rover's clock flat out until its queue is empty and played out."""
    runtime.set_clock(speed=math.inf)
    for _ in range(600):
        runtime._tick(0.05)
        if not runtime.queued_ids() and not runtime._playout:
            return
    raise AssertionError("the queue did not run out")


def wait_for(check: Callable[[], bool], timeout_s: float = 180.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not check():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.2)


def open_app(data: Path) -> tuple[Any, Server]:
    config = ServerConfig(database_url=data_dir_url(data), operator_token=BOOTSTRAP,
                          start_clocks=False, validation_processes=0)  # fmt: skip
    app = create_app(config)
    server: Server = app.state.server
    app.state.rehearsals = RehearsalService(server.store, n_workers=1)
    return app, server


@pytest.fixture(scope="module")
def data(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return Path(tmp_path_factory.mktemp("rehearsal-api"))


@pytest.fixture(scope="module")
def api(data: Path) -> Iterator[tuple[TestClient, Server, Auth, Auth, Auth]]:
    app, server = open_app(data)
    ada = {"Authorization": f"Bearer {server.accounts.add_user('ada', 'operator').token}"}
    bob = {"Authorization": f"Bearer {server.accounts.add_user('bob', 'operator').token}"}
    vic = {"Authorization": f"Bearer {server.accounts.add_user('vic', 'viewer').token}"}
    with TestClient(app) as client:
        r = client.post("/api/rovers/spirit/commands", headers=ada,
                        json={"command": "WAIT", "args": {"duration_s": 1}})  # fmt: skip
        assert r.status_code == 201, r.text
        tick_until_idle(server.rovers["spirit"])
        yield client, server, ada, bob, vic


def test_bad_requests_are_refused_with_the_reason(
    api: tuple[TestClient, Server, Auth, Auth, Auth],
) -> None:
    client, server, ada, _, vic = api
    good = {"sequence_text": SHORT, "runs": 2}
    assert client.post(URL, json=good).status_code == 401  # no token
    assert client.post(URL, json=good, headers=vic).status_code == 403  # a viewer
    cases: list[tuple[Any, int, str]] = [
        ({"sequence_text": SHORT, "runs": 0}, 422, "greater than or equal to 1"),
        ({"sequence_text": SHORT, "runs": 1001}, 422, "less than or equal to 1000"),
        ({"sequence_text": SHORT, "runs": "5"}, 422, "integer"),
        ({"sequence_text": SHORT, "runs": 2.5}, 422, "integer"),
        ({"sequence_text": SHORT, "seed": -1}, 422, "greater than or equal to 0"),
        ({"sequence_text": SHORT, "seed": 2**63}, 422, "less than or equal to"),
        ({"sequence_text": SHORT, "sequence_id": 1}, 422, "exactly one"),
        ({"runs": 3}, 422, "exactly one"),
        ({"sequence_text": SHORT, "extra": 1}, 422, "xtra"),
        ({"sequence_text": 5}, 422, "string"),
        ({"sequence_text": ""}, 422, "at least 1 character"),
        ({"sequence_id": 0}, 422, "greater than or equal to 1"),
        ([SHORT], 422, "dictionary"),
        ({"sequence_id": 999_999}, 404, "no sequence 999999"),
    ]
    for body, status, words in cases:
        r = client.post(URL, json=body, headers=ada)
        assert r.status_code == status, (body, r.text)
        assert words in r.text, (body, r.text)
    hostile = [
        ("[" * 100_000 + "]" * 100_000, 422, "nested"),
        ('{"sequence_text": "x", "runs": NaN}', 422, "NaN"),
        ('{"sequence_text": ', 422, "not JSON"),
        ('{"sequence_text": "x", "seed": ' + "9" * 5000 + "}", 422, "4300 digits"),
        ("x" * 2_000_000, 413, "upload limit"),
    ]
    for raw, status, words in hostile:
        r = client.post(URL, content=raw, headers={**ada, "content-type": "application/json"})
        assert r.status_code == status, (raw[:40], r.text[:200])
        assert words in r.text, (raw[:40], r.text[:200])
    r = client.post("/api/rovers/curiosity/rehearsals", json=good, headers=ada)
    assert r.status_code == 404 and "unknown rover" in r.text
    other = server.store.add_sequence("opportunity", "x", SHORT, "text", "queued", [], [], [])
    r = client.post(URL, json={"sequence_id": other}, headers=ada)
    assert r.status_code == 404 and f"no sequence {other} of spirit" in r.text
    # a sequence with errors: 400, each error with its line (as an upload's)
    bad = "SEQUENCE bad\nDRIVE_STRAIGHT distance_m=oops\nWAIT duration_s=1\nFLY\n"
    r = client.post(URL, json={"sequence_text": bad}, headers=ada)
    assert r.status_code == 400, r.text
    assert [e["line"] for e in r.json()["errors"]] == [2, 4]
    assert r.json()["detail"].startswith("the sequence has 2 errors: line 2: ")
    for path in (f"{URL}/999", f"{URL}/0", f"{URL}/abc", "/api/rovers/nope/rehearsals/1"):
        assert client.get(path).status_code in (404, 422), path
    assert client.post(f"{URL}/999/cancel", headers=ada).status_code == 404
    assert client.post(f"{URL}/999/cancel", headers=vic).status_code == 403
    assert client.get(URL).json() == []  # nothing was started


def _detail(client: TestClient, rid: int) -> dict[str, Any]:
    r = client.get(f"{URL}/{rid}")
    assert r.status_code == 200, r.text
    found: dict[str, Any] = r.json()
    return found


def test_campaigns_run_list_cancel_limit_report_and_survive_a_restart(
    api: tuple[TestClient, Server, Auth, Auth, Auth], data: Path
) -> None:
    client, server, ada, bob, vic = api
    r = client.post(URL, json={"sequence_text": SHORT, "runs": 2, "seed": 11}, headers=ada)
    assert r.status_code == 202, r.text
    first = r.json()
    assert (first["state"], first["user"], first["runs"], first["seed"]) == ("queued", "ada", 2, 11)
    wait_for(lambda: _detail(client, first["id"])["state"] not in ("queued", "running"))
    done = _detail(client, first["id"])
    assert done["state"] == "done", done["error"]
    assert done["done"] == 2 and done["warmup_s"] > 0.0 and done["finished_t_utc"]
    risk = done["risk"]
    assert risk["runs"] == 2 and [e["line"] for e in risk["lines"]] == [2, 3]
    assert risk["lines"][0]["command"].startswith("DRIVE_STRAIGHT")
    assert client.post(f"{URL}/{first['id']}/cancel", headers=ada).status_code == 409
    # the report: 404 until the sequence has run, then the executed figures placed
    r = client.get(f"{URL}/{first['id']}/report")
    assert r.status_code == 404 and "has not run" in r.text
    up = client.post("/api/rovers/spirit/sequences", content=SHORT, headers=ada)
    assert up.status_code == 201, up.text
    tick_until_idle(server.rovers["spirit"])
    server.writer.flush()
    report = client.get(f"{URL}/{first['id']}/report")
    assert report.status_code == 200, report.text
    body = report.json()
    assert body["sequence_id"] == up.json()["id"] and [x["line"] for x in body["lines"]] == [2, 3]
    names = {f["name"] for f in body["lines"][0]["figures"]}
    assert {"status", "end_est", "end_t_s"} <= names, names
    assert body["truth"] is not None  # truth view: everyone
    server.config.truth_view = "conductor"
    try:
        assert client.get(f"{URL}/{first['id']}/report", headers=ada).json()["truth"] is None
        assert client.get(f"{URL}/{first['id']}/report", headers=bob).json()["truth"] is None
    finally:
        server.config.truth_view = "everyone"
    # the limit per user, and cancel
    started = []
    for _ in range(MAX_RUNNING_PER_USER):
        r = client.post(URL, json={"sequence_text": LONG, "runs": 1000}, headers=ada)
        assert r.status_code == 202, r.text
        started.append(r.json()["id"])
    r = client.post(URL, json={"sequence_text": LONG, "runs": 5}, headers=ada)
    assert r.status_code == 429 and f"at most {MAX_RUNNING_PER_USER} at once" in r.text
    r = client.post(URL, json={"sequence_text": LONG, "runs": 1000}, headers=bob)  # another user
    assert r.status_code == 202, r.text
    running = r.json()["id"]
    wait_for(lambda: _detail(client, started[0])["state"] == "running")
    assert client.post(f"{URL}/{started[0]}/cancel", headers=vic).status_code == 403
    r = client.post(f"{URL}/{started[0]}/cancel", headers=ada)
    assert r.status_code == 200 and r.json()["state"] == "cancelled", r.text
    r = client.post(f"{URL}/{started[1]}/cancel", headers=bob)  # an operator cancels any
    assert r.status_code == 200 and r.json()["state"] == "cancelled", r.text
    listed = client.get(URL).json()
    assert [s["id"] for s in listed] == [running, *reversed(started), first["id"]]
    assert client.get(f"{URL}/{first['id']}", headers=vic).json()["risk"] == risk
    # a restart: the finished campaigns and their tables are there; the one running when
    # the server stopped is cancelled, "server stopped"; no worker process outlives it
    service: RehearsalService = client.app.state.rehearsals  # type: ignore[attr-defined]
    pids = service.running_pids()
    assert len(pids) == 1
    client.__exit__(None, None, None)
    for pid in pids:
        wait_for(lambda pid=pid: not Path(f"/proc/{pid}").exists(), 30.0)  # type: ignore[misc]
    app, _ = open_app(data)
    with TestClient(app) as again:
        after = {s["id"]: s for s in again.get(URL).json()}
        assert after[first["id"]]["state"] == "done"
        assert (
            after[running]["state"] == "cancelled" and after[running]["error"] == "server stopped"
        )
        assert after[started[0]]["state"] == "cancelled" and after[started[0]]["error"] is None
        assert again.get(f"{URL}/{first['id']}").json()["risk"] == risk
        assert again.get(f"{URL}/{first['id']}/report").status_code == 200
