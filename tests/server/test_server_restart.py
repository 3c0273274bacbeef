"""A server killed with SIGKILL mid-drive and restarted on the same database loses at most
the last second: every accepted sequence and every frame stored a second before the kill
are still there, and the rover resumes and finishes its drive (issue 4, item 5).

The clock survives restarts too (issue 13, defect 7): a paused rover comes back paused
after SIGKILL (a clock change is stored when the request answers) and after SIGTERM, and a
graceful stop checkpoints each rover where its clock stopped, so the rover resumes at the
``t_s`` it had, not at its last periodic checkpoint."""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest

from server.runtime import FRAME_EVERY_S, ROVERS, RoverRuntime
from server.storage import Store

TOKEN = "restart-test-token"
AUTH = {"Authorization": f"Bearer {TOKEN}"}
DRIVE = "SEQUENCE long_drive\nDRIVE_STRAIGHT distance_m=20\n"


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


def _start(
    data_dir: Path,
    port: int,
    token: str = TOKEN,
    estimators: str = "sapp",
    three_d: bool = True,
    env_extra: dict[str, str] | None = None,
) -> subprocess.Popen[bytes]:
    """``roverops serve`` as its own process (the real server, as an operator runs it,
    with ``--estimators``, ``--no-3d`` unless ``three_d``, and ``env_extra`` for other
    ROVEROPS_* settings); its output goes to
    ``server.log`` in ``data_dir`` (a pipe nobody reads would fill up and stall the server)."""
    env = dict(os.environ, ROVEROPS_OPERATOR_TOKEN=token, **(env_extra or {}))
    cmd = [
        sys.executable,
        "-m",
        "cli.main",
        "serve",
        "--port",
        str(port),
        "--data-dir",
        str(data_dir),
        "--estimators",
        estimators,
        *([] if three_d else ["--no-3d"]),
    ]
    with open(data_dir / "server.log", "ab") as log:
        return subprocess.Popen(cmd, env=env, stdout=log, stderr=subprocess.STDOUT)


@contextlib.contextmanager
def serving(
    data_dir: Path, token: str = TOKEN, ready: str = "/api/rovers", **start: Any
) -> Iterator[str]:
    """A real server (``_start``'s options) on a free port, its base URL once ``ready``
    answers 200 (with the token); killed when the block ends. The browser tests' server."""
    port = _free_port()
    proc = _start(data_dir, port, token, **start)
    base = f"http://127.0.0.1:{port}"
    auth = {"Authorization": f"Bearer {token}"}

    def answers() -> bool:
        if proc.poll() is not None:  # it will never answer: say why at once
            log = (data_dir / "server.log").read_text(errors="replace")
            raise AssertionError(f"the server exited with status {proc.returncode}:\n{log}")
        return httpx.get(f"{base}{ready}", headers=auth).status_code == 200

    try:
        _wait(answers, timeout_s=ready_deadline_s())
        yield base
    finally:
        proc.kill()
        proc.wait(timeout=10)


READY_DEADLINE_S = 120.0  # an idle machine's generous bound on a start (a few s here)


def ready_deadline_s(load: float | None = None, cores: int | None = None) -> float:
    """How long ``serving`` waits for a server to answer: ``READY_DEADLINE_S`` times the
    machine's load per core (the 1-minute load average) when that is above 1, so a busy CI
    machine is given the time its queue of processes takes. A server that exits fails at
    once instead (``serving``)."""
    load = os.getloadavg()[0] if load is None else load
    cores = (os.cpu_count() or 1) if cores is None else cores
    return READY_DEADLINE_S * max(1.0, load / cores)


def _wait(predicate: Any, timeout_s: float = 60.0) -> Any:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            value = predicate()
        except httpx.HTTPError:
            value = None
        if value:
            return value
        time.sleep(0.1)
    raise AssertionError("timed out")


@pytest.fixture
def servers(tmp_path: Path) -> Iterator[list[subprocess.Popen[bytes]]]:
    started: list[subprocess.Popen[bytes]] = []
    yield started
    for proc in started:
        if proc.poll() is None:
            proc.kill()
        proc.wait(timeout=10)


def test_sigkill_mid_drive_then_restart_loses_at_most_a_second(
    tmp_path: Path, servers: list[subprocess.Popen[bytes]]
) -> None:
    port = _free_port()
    base = f"http://127.0.0.1:{port}"
    servers.append(_start(tmp_path, port))
    c = httpx.Client(base_url=base, timeout=10.0)
    _wait(lambda: c.get("/api/rovers").status_code == 200)
    c.post("/api/rovers/spirit/clock", json={"speed": 20}, headers=AUTH).raise_for_status()
    r = c.post("/api/rovers/spirit/sequences", content=DRIVE, headers=AUTH)
    assert r.status_code == 201, r.text
    seq_id = r.json()["id"]
    # mid-drive: the rover has moved but not arrived (20 m take 533 s, 27 s of wall here)
    _wait(
        lambda: (
            (f := c.get("/api/rovers/spirit/state").json()["frame"])
            and 2.0 < f["p_s_est"][0] < 15.0
        )
    )
    stored_before = {f["t_s"] for f in c.get("/api/rovers/spirit/telemetry").json()}
    time.sleep(1.2)  # what was stored a second ago must survive
    servers[0].send_signal(signal.SIGKILL)
    servers[0].wait(timeout=10)

    servers.append(_start(tmp_path, port))
    _wait(lambda: c.get("/api/rovers").status_code == 200)
    assert c.get(f"/api/sequences/{seq_id}").json()["status"] in ("queued", "running", "completed")
    # up to the last frame stored before the kill: the restored clock may still be behind
    # it (frames after the last checkpoint are stored, and the default ``to`` is the clock)
    after = c.get("/api/rovers/spirit/telemetry", params={"to": max(stored_before)}).json()
    times = [f["t_s"] for f in after]
    assert stored_before <= set(times)
    assert len(times) == len(set(times)) and times == sorted(times)  # no frame stored twice
    c.post("/api/rovers/spirit/clock", json={"speed": "max"}, headers=AUTH).raise_for_status()
    _wait(lambda: c.get(f"/api/sequences/{seq_id}").json()["status"] == "completed")
    frame = _wait(
        lambda: (s := c.get("/api/rovers/spirit/state").json())["executing"] == "" and s["frame"]
    )
    assert 19.0 < frame["p_s_est"][0] < 21.5  # resumed and finished the 20 m


def _up(tmp_path: Path, port: int, servers: list[subprocess.Popen[bytes]]) -> httpx.Client:
    """A server (no 3D view) on ``port`` over ``tmp_path``'s database, answering."""
    servers.append(_start(tmp_path, port, three_d=False))
    c = httpx.Client(base_url=f"http://127.0.0.1:{port}", timeout=10.0)
    _wait(lambda: c.get("/api/rovers").status_code == 200)
    return c


def _end(servers: list[subprocess.Popen[bytes]], sig: int) -> None:
    servers[-1].send_signal(sig)
    # SIGTERM stops the server cleanly, exit 0 (cli.serve); SIGKILL cannot be caught
    assert servers[-1].wait(timeout=30) == (0 if sig == signal.SIGTERM else -sig)


def _clock(c: httpx.Client, body: dict[str, Any]) -> dict[str, Any]:
    r = c.post("/api/rovers/spirit/clock", json=body, headers=AUTH)
    r.raise_for_status()
    clock: dict[str, Any] = r.json()
    return clock


def _stopped_t_s(c: httpx.Client) -> float:
    """Spirit's ``t_s`` once a pause has taken effect (two reads apart agree)."""

    def settled() -> float | None:
        first = float(c.get("/api/rovers/spirit/state").json()["t_s"])
        time.sleep(0.3)
        second = float(c.get("/api/rovers/spirit/state").json()["t_s"])
        return first if first == second else None

    t_s: float = _wait(settled)
    return t_s


def test_a_paused_rover_stays_paused_after_sigkill(
    tmp_path: Path, servers: list[subprocess.Popen[bytes]]
) -> None:
    port = _free_port()
    c = _up(tmp_path, port, servers)
    _clock(c, {"speed": 20})
    assert _clock(c, {"action": "pause"})["running"] is False
    _end(servers, signal.SIGKILL)  # at once: a clock change is stored when it answers

    c = _up(tmp_path, port, servers)
    rovers = {r["rover"]: r["clock"] for r in c.get("/api/rovers").json()}
    assert rovers["spirit"] == {"running": False, "speed": 20}
    assert rovers["opportunity"]["running"] is True  # only the rover that was paused
    t_s = c.get("/api/rovers/spirit/state").json()["t_s"]
    time.sleep(0.5)
    assert c.get("/api/rovers/spirit/state").json()["t_s"] == t_s  # and its clock stands


def test_a_paused_rover_stays_paused_where_it_was_after_sigterm(
    tmp_path: Path, servers: list[subprocess.Popen[bytes]]
) -> None:
    port = _free_port()
    c = _up(tmp_path, port, servers)
    _clock(c, {"speed": 20})
    _clock(c, {"action": "pause"})
    paused_t_s = _stopped_t_s(c)
    _end(servers, signal.SIGTERM)

    c = _up(tmp_path, port, servers)
    state = c.get("/api/rovers/spirit/state").json()
    assert state["clock"] == {"running": False, "speed": 20}
    assert abs(state["t_s"] - paused_t_s) <= FRAME_EVERY_S  # not rewound
    assert state["t_s"] == paused_t_s  # indeed not moved at all


def test_a_running_rover_resumes_where_sigterm_stopped_it(
    tmp_path: Path, servers: list[subprocess.Popen[bytes]]
) -> None:
    """Mid-drive at speed 100 (5 simulated s a tick): the checkpoint a graceful stop leaves
    is at or after the last frame it stored, where a periodic checkpoint lags by a tick or
    more; and the restarted rover goes on from there with its drive."""
    port = _free_port()
    c = _up(tmp_path, port, servers)
    _clock(c, {"speed": 100})
    r = c.post("/api/rovers/spirit/sequences", content=DRIVE, headers=AUTH)
    assert r.status_code == 201, r.text
    _wait(
        lambda: (
            (f := c.get("/api/rovers/spirit/state").json()["frame"])
            and 2.0 < f["p_s_est"][0] < 15.0
        )
    )
    _end(servers, signal.SIGTERM)

    store = Store(f"sqlite:///{tmp_path / 'roverops.db'}")
    try:
        last = store.last_frame("spirit")
        saved = store.load_checkpoint("spirit")
    finally:
        store.close()
    assert last is not None and saved is not None
    resumed = RoverRuntime.restore(ROVERS["spirit"], saved[1])
    assert resumed.t_s >= last["t_s"]  # nothing stored lies beyond where it resumes
    assert resumed.t_s - last["t_s"] <= FRAME_EVERY_S  # nor does it skip ahead
    assert resumed.executing.startswith("DRIVE_STRAIGHT")

    c = _up(tmp_path, port, servers)
    state = c.get("/api/rovers/spirit/state").json()
    assert state["t_s"] >= resumed.t_s and state["clock"]["speed"] == 100


def test_a_server_that_exits_is_reported_at_once_with_its_log(tmp_path: Path) -> None:
    """The fixture waits for readiness, not a fixed time: a server that exits (here on a
    bad ``--estimators``) fails the fixture with its exit status and its log."""
    with pytest.raises(AssertionError) as failed, serving(tmp_path, estimators="sapp,bogus"):
        pass
    assert "exited with status 2" in str(failed.value)
    assert "--estimators must list sapp" in str(failed.value)


def test_the_readiness_deadline_grows_with_the_machines_load() -> None:
    idle, busy = ready_deadline_s(load=0.0, cores=2), ready_deadline_s(load=8.0, cores=2)
    assert idle >= 120.0 and busy == pytest.approx(4 * idle)


def _server_events(c: httpx.Client, rover: str) -> list[dict[str, Any]]:
    r = c.get(f"/api/rovers/{rover}/events", params={"kind": "server"})
    assert r.status_code == 200, r.text
    events: list[dict[str, Any]] = r.json()["events"]
    return events


def test_each_start_is_recorded_as_an_event_on_every_rover_and_an_audit_row(
    tmp_path: Path, servers: list[subprocess.Popen[bytes]]
) -> None:
    """Issue 21, a dead server looks alive: when it comes back, the operators learn that it
    went away. Each start of the server is an event of kind ``server`` on every rover's log,
    at that rover's clock then, and a row of the audit log; after SIGKILL as after a first
    start."""
    port = _free_port()
    c = _up(tmp_path, port, servers)
    first = {rover: _server_events(c, rover) for rover in ROVERS}
    assert all(len(events) == 1 for events in first.values()), first
    _clock(c, {"speed": 100})
    _wait(lambda: c.get("/api/rovers/spirit/state").json()["t_s"] > first["spirit"][0]["t_s"] + 300)
    time.sleep(1.5)  # a checkpoint a wall second: one is past those 300 s
    _end(servers, signal.SIGKILL)

    c = _up(tmp_path, port, servers)
    for rover in ROVERS:
        events = _server_events(c, rover)
        assert len(events) == 2, events
        restart = max(events, key=lambda e: e["t_s"])
        assert "restarted" in restart["text"] and restart["kind"] == "server"
        now = c.get(f"/api/rovers/{rover}/state").json()["t_s"]
        assert first[rover][0]["t_s"] <= restart["t_s"] <= now
    spirit = max(_server_events(c, "spirit"), key=lambda e: e["t_s"])
    assert spirit["t_s"] > first["spirit"][0]["t_s"] + 300  # at the rover's resumed clock
    rows = c.get("/api/audit", params={"user": "server"}, headers=AUTH).json()
    assert [r["action"] for r in rows] == ["server restarted", "server started"], rows
    assert all(r["result"] == "accepted" for r in rows)
