"""Stopping ``roverops serve`` (``make run``'s Ctrl-C or a SIGTERM) is a clean stop: exit
status 0, a one-line "stopped", no traceback (issue 21: uvicorn re-raised the signal, so
the server died of it and make printed "Terminated")."""

import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import httpx
import pytest


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


def _answers(url: str) -> bool:
    try:
        return httpx.get(url).status_code == 200
    except httpx.HTTPError:
        return False


@pytest.mark.parametrize("stop", [signal.SIGTERM, signal.SIGINT])
def test_a_stopped_server_exits_0_and_says_stopped(tmp_path: Path, stop: signal.Signals) -> None:
    port = _free_port()
    log_path = tmp_path / "server.log"
    cmd = [sys.executable, "-m", "cli.main", "serve", "--port", str(port)]
    cmd += ["--data-dir", str(tmp_path / "data"), "--no-3d"]
    env = dict(os.environ, ROVEROPS_OPERATOR_TOKEN="stop-test-token")
    with open(log_path, "wb") as log:
        proc = subprocess.Popen(cmd, env=env, stdout=log, stderr=subprocess.STDOUT)
    try:
        deadline = time.monotonic() + 180.0  # a condition, not a fixed wait
        while not _answers(f"http://127.0.0.1:{port}/api/rovers"):
            assert proc.poll() is None and time.monotonic() < deadline, log_path.read_text()
            time.sleep(0.2)
        proc.send_signal(stop)
        code = proc.wait(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(timeout=10)
    output = log_path.read_text()
    assert code == 0, output
    assert "Traceback" not in output
    assert output.strip().splitlines()[-1] == "roverops serve: stopped"
