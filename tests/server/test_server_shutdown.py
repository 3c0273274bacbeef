"""``roverops serve`` stops promptly on SIGTERM (and Ctrl-C), also after a browser has
watched a resting rover's telemetry and gone away: a telemetry socket whose browser left
while nothing was sent must not hold the server's graceful shutdown."""

from __future__ import annotations

import signal
import time
from pathlib import Path

import httpx
import pytest
from websockets.sync.client import connect

from tests.server.test_server_restart import _free_port, _start, _wait

TOKEN = "shutdown-test-token"
AUTH = {"Authorization": f"Bearer {TOKEN}"}


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_the_server_stops_after_a_telemetry_viewer_left(tmp_path: Path, sig: int) -> None:
    port = _free_port()
    proc = _start(tmp_path, port, TOKEN)
    try:
        base = f"http://127.0.0.1:{port}"
        _wait(lambda: httpx.get(f"{base}/api/rovers").status_code == 200)
        httpx.post(f"{base}/api/rovers/spirit/clock", json={"action": "pause"}, headers=AUTH)
        with connect(f"ws://127.0.0.1:{port}/ws/rovers/spirit/telemetry", open_timeout=10):
            time.sleep(0.5)  # subscribed; paused, the rover sends nothing
        time.sleep(0.5)
        started = time.monotonic()
        proc.send_signal(sig)
        proc.wait(timeout=15.0)
        # well inside uvicorn's 10 s graceful-shutdown timeout: nothing waited for it
        assert time.monotonic() - started < 5.0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(timeout=10)
            pytest.fail("the server did not stop within 15 s")
