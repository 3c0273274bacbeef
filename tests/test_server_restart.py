"""A server killed with SIGKILL mid-drive and restarted on the same database loses at most
the last second: every accepted sequence and every frame stored a second before the kill
are still there, and the rover resumes and finishes its drive (issue 4, item 5)."""

from __future__ import annotations

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

TOKEN = "restart-test-token"
AUTH = {"Authorization": f"Bearer {TOKEN}"}
DRIVE = "SEQUENCE long_drive\nDRIVE_STRAIGHT distance_m=20\n"


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


def _start(
    data_dir: Path, port: int, token: str = TOKEN, estimators: str = "sapp"
) -> subprocess.Popen[bytes]:
    """``roverops serve`` as its own process (the real server, as an operator runs it,
    with ``--estimators``); its output goes to ``server.log`` in ``data_dir`` (a pipe nobody
    reads would fill up and stall the server)."""
    env = dict(os.environ, ROVEROPS_OPERATOR_TOKEN=token)
    cmd = [
        sys.executable,
        "-m",
        "server.cli",
        "serve",
        "--port",
        str(port),
        "--data-dir",
        str(data_dir),
        "--estimators",
        estimators,
    ]
    with open(data_dir / "server.log", "ab") as log:
        return subprocess.Popen(cmd, env=env, stdout=log, stderr=subprocess.STDOUT)


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
    after = c.get("/api/rovers/spirit/telemetry").json()
    times = [f["t_s"] for f in after]
    assert stored_before <= set(times)
    assert len(times) == len(set(times)) and times == sorted(times)  # no frame stored twice
    c.post("/api/rovers/spirit/clock", json={"speed": "max"}, headers=AUTH).raise_for_status()
    _wait(lambda: c.get(f"/api/sequences/{seq_id}").json()["status"] == "completed")
    frame = _wait(
        lambda: (s := c.get("/api/rovers/spirit/state").json())["executing"] == "" and s["frame"]
    )
    assert 19.0 < frame["p_s_est"][0] < 21.5  # resumed and finished the 20 m
