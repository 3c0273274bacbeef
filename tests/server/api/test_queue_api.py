"""The queue over the API (issue 14): ``GET /api/rovers/{rover}/queue`` with every step's
status, ``POST .../queue/{id}/move`` (strict body; 404, 409 and 422 change nothing and are
audited), cancel saying where the sequence stopped, the ``queue`` notice on the telemetry
WebSocket, and the order kept across a kill."""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from sequences.validate import validate
from server.app import Server, ServerConfig, create_app, data_dir_url
from server.notices import QueueNotice
from server.queue_view import QueueNotices
from server.runtime import RoverRuntime

BOOTSTRAP = "queue-api-token"
THREE = "SEQUENCE {name}\nNADIR_UPDATE\nWAIT duration_s=30\nGET_TILT_ATTITUDE\n"


@pytest.fixture
def api(tmp_path: Path) -> Iterator[tuple[TestClient, dict[str, str], RoverRuntime]]:
    """The app with its clocks stopped (the test ticks spirit's), an operator's headers."""
    config = ServerConfig(
        database_url=data_dir_url(tmp_path), operator_token=BOOTSTRAP, start_clocks=False
    )
    app = create_app(config)
    server: Server = app.state.server
    token = server.accounts.add_user("ada", "operator").token
    runtime = server.rovers["spirit"]
    runtime.set_clock(speed=math.inf)
    with TestClient(app) as client:
        yield client, {"Authorization": f"Bearer {token}"}, runtime


def _upload(client: TestClient, auth: dict[str, str], name: str, rover: str = "spirit") -> int:
    r = client.post(f"/api/rovers/{rover}/sequences", content=THREE.format(name=name), headers=auth)
    assert r.status_code == 201, r.text
    sequence_id: int = r.json()["id"]
    return sequence_id


def _order(client: TestClient) -> list[int]:
    return [q["sequence_id"] for q in client.get("/api/rovers/spirit/queue").json()["queue"]]


def _audit(client: TestClient) -> dict[str, Any]:
    rows = client.get(
        "/api/audit", params={"limit": 1}, headers={"Authorization": f"Bearer {BOOTSTRAP}"}
    ).json()
    row: dict[str, Any] = rows[0]
    return row


def test_the_queue_lists_each_sequence_with_every_step(
    api: tuple[TestClient, dict[str, str], RoverRuntime],
) -> None:
    client, auth, _ = api
    assert client.get("/api/rovers/spirit/queue").json() == {
        "rover": "spirit",
        "queue": [],
        "recent": [],
    }
    a = _upload(client, auth, "alpha")
    queue = client.get("/api/rovers/spirit/queue").json()["queue"]
    assert len(queue) == 1
    q = queue[0]
    assert {k: q[k] for k in ("position", "sequence_id", "name", "status", "movable")} == {
        "position": 0, "sequence_id": a, "name": "alpha", "status": "queued", "movable": True
    }  # fmt: skip
    assert q["submitted_by"] == "ada" and q["step_count"] == 3
    assert [(s["index"], s["line"], s["command"], s["status"]) for s in q["steps"]] == [
        (0, 2, "NADIR_UPDATE", "pending"),
        (1, 3, "WAIT duration_s=30", "pending"),
        (2, 4, "GET_TILT_ATTITUDE", "pending"),
    ]
    assert client.get("/api/rovers/nowhere/queue").status_code == 404


def test_a_move_reorders_the_queue_and_is_audited(
    api: tuple[TestClient, dict[str, str], RoverRuntime],
) -> None:
    client, auth, runtime = api
    a, b, c = (_upload(client, auth, n) for n in ("alpha", "bravo", "charlie"))
    r = client.post(f"/api/rovers/spirit/queue/{c}/move", json={"to": 0}, headers=auth)
    assert r.status_code == 200, r.text
    assert [q["sequence_id"] for q in r.json()["queue"]] == [c, a, b]
    assert _order(client) == [c, a, b] == runtime.queued_ids()
    state = client.get("/api/rovers/spirit/state").json()
    assert [q["sequence_id"] for q in state["queue"]] == [c, a, b]
    row = _audit(client)
    assert (row["username"], row["result"], row["rover"]) == ("ada", "accepted", "spirit")
    assert row["action"] == f"move sequence #{c} to position 0"


@pytest.mark.parametrize(
    "body",
    [{}, {"to": "1"}, {"to": -1}, {"to": 1.5}, {"to": True}, {"to": None}, {"to": 0, "by": 1},
     [0], "to=0"],
    ids=str,
)  # fmt: skip
def test_a_bad_body_is_a_422_naming_it_and_nothing_moves(
    api: tuple[TestClient, dict[str, str], RoverRuntime], body: Any
) -> None:
    client, auth, _ = api
    a, b = _upload(client, auth, "alpha"), _upload(client, auth, "bravo")
    kwargs: dict[str, Any] = {"content": body} if isinstance(body, str) else {"json": body}
    r = client.post(f"/api/rovers/spirit/queue/{b}/move", headers=auth, **kwargs)
    assert r.status_code == 422, r.text
    assert all(d["loc"][0] == "body" and d["msg"] for d in r.json()["detail"])
    assert _order(client) == [a, b]
    assert _audit(client)["result"] == "refused"


def test_refused_moves_say_why_change_nothing_and_are_audited(
    api: tuple[TestClient, dict[str, str], RoverRuntime],
) -> None:
    client, auth, runtime = api
    a, b, c = (_upload(client, auth, n) for n in ("alpha", "bravo", "charlie"))
    other = _upload(client, auth, "elsewhere", rover="opportunity")
    runtime._tick(0.05)  # alpha runs its first step: it has started
    started = f"sequence {a} has started (at step 2 of 3)"
    cases = [
        (f"/api/rovers/spirit/queue/{a}/move", 2, 409, started),
        (f"/api/rovers/spirit/queue/{c}/move", 0, 409, f"position 0 is in front of sequence {a}"),
        (f"/api/rovers/spirit/queue/{c}/move", 3, 409, "position 3 is past the end"),
        (f"/api/rovers/spirit/queue/{other}/move", 0, 404, f"no sequence {other} for rover"),
        ("/api/rovers/spirit/queue/999/move", 0, 404, "no sequence 999"),
        (f"/api/rovers/nowhere/queue/{c}/move", 0, 404, "unknown rover 'nowhere'"),
    ]  # fmt: skip
    for path, to, status, why in cases:
        r = client.post(path, json={"to": to}, headers=auth)
        assert r.status_code == status, (path, r.text)
        assert why in r.json()["detail"], r.text
        assert _order(client) == [a, b, c]
        row = _audit(client)
        assert row["result"] == "refused" and why in (row["detail"] or ""), row
    assert client.delete(f"/api/sequences/{b}", headers=auth).status_code == 200
    r = client.post(f"/api/rovers/spirit/queue/{b}/move", json={"to": 1}, headers=auth)
    assert r.status_code == 409 and "it is cancelled" in r.json()["detail"], r.text
    assert runtime.queued_ids() == [a, c]


def test_cancel_says_where_the_sequence_stopped_and_the_queue_shows_its_steps(
    api: tuple[TestClient, dict[str, str], RoverRuntime],
) -> None:
    client, auth, runtime = api
    a, b = _upload(client, auth, "alpha"), _upload(client, auth, "bravo")
    runtime._tick(0.05)  # alpha's first step
    runtime._tick(0.05)  # its frames played out: between steps 1 and 2
    running = client.get("/api/rovers/spirit/queue").json()["queue"][0]
    assert running["status"] == "running" and running["movable"] is False
    assert "has started" in running["pinned"]
    first = running["steps"][0]
    assert first["status"] == "completed" and first["end"]["t_s"] > first["start"]["t_s"]
    assert 0.0 <= first["end"]["lmst_h"] < 24.0 and first["end"]["utc"].startswith("2004-")
    assert [s["status"] for s in running["steps"][1:]] == ["pending", "pending"]

    r = client.delete(f"/api/sequences/{a}", headers=auth)
    assert r.status_code == 200, r.text
    expected = "cancelled by ada after step 1 of 3 (2 not run)"
    assert r.json()["detail"] == expected
    assert client.get(f"/api/sequences/{a}").json()["detail"] == expected
    body = client.get("/api/rovers/spirit/queue").json()
    assert [q["sequence_id"] for q in body["queue"]] == [b]
    (gone,) = body["recent"]
    assert (gone["sequence_id"], gone["status"], gone["detail"]) == (a, "cancelled", expected)
    assert [s["status"] for s in gone["steps"]] == ["completed", "skipped", "skipped"]
    assert gone["steps"][1]["command"] == "WAIT duration_s=30"
    assert _audit(client)["action"] == f"cancel sequence #{a}"


def test_every_queue_change_is_a_notice_on_the_telemetry_websocket(
    api: tuple[TestClient, dict[str, str], RoverRuntime],
) -> None:
    client, auth, runtime = api
    a, b = _upload(client, auth, "alpha"), _upload(client, auth, "bravo")
    hub = client.app.state.server.hub  # type: ignore[attr-defined]
    with client.websocket_connect("/ws/rovers/spirit/telemetry") as ws:
        _wait_for(lambda: hub.count("spirit") == 1)  # subscribed (just after the accept)

        def until(holds: Any) -> list[dict[str, Any]]:
            """Queue notices until one ``holds``: each is a snapshot, so a change made
            before this client subscribed may still come first (the clock is stopped: no
            frames, only notices)."""
            for _ in range(20):
                message = ws.receive_json()
                if message.get("type") == "queue":
                    assert message["rover"] == "spirit"
                    queue: list[dict[str, Any]] = message["queue"]
                    if holds(queue):
                        return queue
            raise AssertionError("no such notice")

        def ids(queue: list[dict[str, Any]]) -> list[int]:
            return [q["sequence_id"] for q in queue]

        client.post(f"/api/rovers/spirit/queue/{b}/move", json={"to": 0}, headers=auth)
        until(lambda queue: ids(queue) == [b, a])
        client.delete(f"/api/sequences/{a}", headers=auth)
        until(lambda queue: ids(queue) == [b])
        runtime._tick(0.05)  # bravo's first step runs
        runtime._tick(0.05)  # and its frames play out (notices coalesce: the last says so)
        queue = until(lambda queue: queue[0]["steps"][0]["status"] == "completed")
        assert queue[0]["status"] == "running" and queue[0]["steps"][1]["status"] == "pending"


def _wait_for(predicate: Any, timeout_s: float = 10.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not predicate():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.01)


def test_the_order_survives_a_kill_and_a_cancelled_sequence_stays_cancelled(
    tmp_path: Path,
) -> None:
    """Moved and cancelled after the last periodic checkpoint, then killed (no graceful
    stop): the restarted server has the order the operators set, and does not run the
    cancelled sequence again (its record says cancelled; it used to come back from the
    checkpoint)."""
    url = f"sqlite:///{tmp_path / 'roverops.db'}"
    first = Server.open(ServerConfig(database_url=url, operator_token="x", start_clocks=False))
    runtime = first.rovers["spirit"]
    ids = []
    for name in ("alpha", "bravo", "charlie"):
        sequence = validate(THREE.format(name=name)).sequence
        assert sequence is not None
        ids.append(first.store.add_sequence("spirit", name, "", "text", "queued", [], [], []))
        runtime.enqueue(ids[-1], sequence)
    runtime.checkpoint()
    first.writer.flush()
    a, b, c = ids
    runtime.move(c, 0)
    assert runtime.cancel(a) is not None
    first.store.set_sequence_status(a, "cancelled", "cancelled by test")
    first.store.close()  # killed: no final checkpoint

    second = Server.open(ServerConfig(database_url=url, operator_token="x", start_clocks=False))
    assert second.rovers["spirit"].queued_ids() == [c, b]
    second.stop()


def test_notices_are_snapshots_built_once_for_many_changes_and_only_for_followed_rovers() -> None:
    builds: list[str] = []
    sent: list[dict[str, Any]] = []

    def build(rover: str) -> QueueNotice:
        builds.append(rover)
        return QueueNotice(rover, [])

    notices = QueueNotices(
        build, lambda _rover, notice: sent.append(notice.message()), "spirit".__eq__
    )
    for _ in range(5):  # five changes before the thread's next turn: one snapshot says all
        notices.changed("spirit")
    notices.changed("opportunity")  # nobody follows it: nothing built
    notices.send_pending()
    assert builds == ["spirit"] and sent == [{"type": "queue", "rover": "spirit", "queue": []}]
    notices.send_pending()
    assert builds == ["spirit"]  # nothing changed since
