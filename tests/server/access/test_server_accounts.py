"""Accounts end to end, as an operator meets them: ``roverops serve`` on a new data
directory creates a local admin and prints its token once; a restart prints none and keeps
the token working; ``roverops users`` manages users beside the running server."""

from __future__ import annotations

import json
import os
import re
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest

from tests.cli.test_cli import _run


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


def _serve(data_dir: Path, port: int, log_name: str, *flags: str) -> subprocess.Popen[bytes]:
    env = {k: v for k, v in os.environ.items() if not k.startswith("ROVEROPS_")}
    cmd = [sys.executable, "-m", "cli.main", "serve", "--port", str(port),
           "--data-dir", str(data_dir), "--no-3d", *flags]  # fmt: skip
    with open(data_dir.parent / log_name, "wb") as log:
        return subprocess.Popen(cmd, env=env, stdout=log, stderr=subprocess.STDOUT)


def _up(client: httpx.Client, proc: subprocess.Popen[bytes]) -> None:
    deadline = time.monotonic() + 60.0
    while time.monotonic() < deadline:
        assert proc.poll() is None, "the server exited"
        try:
            if client.get("/openapi.json").status_code == 200:
                return
        except httpx.HTTPError:
            pass
        time.sleep(0.1)
    raise AssertionError("the server did not start")


@pytest.fixture
def procs() -> Iterator[list[subprocess.Popen[bytes]]]:
    started: list[subprocess.Popen[bytes]] = []
    yield started
    for proc in started:
        if proc.poll() is None:
            proc.terminate()
        try:
            proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            proc.kill()


def test_a_new_data_directory_prints_an_admin_token_once_and_keeps_it(
    tmp_path: Path, procs: list[subprocess.Popen[bytes]], capsys: pytest.CaptureFixture[str]
) -> None:
    data = tmp_path / "data"
    port = _free_port()
    client = httpx.Client(base_url=f"http://127.0.0.1:{port}", timeout=10.0)
    procs.append(_serve(data, port, "first.log", "--public-read", "off"))
    _up(client, procs[-1])
    procs[-1].terminate()
    procs[-1].wait(timeout=30)
    first = (tmp_path / "first.log").read_text()
    found = re.search(r"admin token \(user admin.*\): (\S+)", first)
    assert found, first
    token = found.group(1)
    assert "reading without a token: off" in first

    procs.append(_serve(data, port, "second.log", "--public-read", "off"))
    _up(client, procs[-1])
    second = (tmp_path / "second.log").read_text()
    assert "admin token" not in second and token not in second
    auth = {"Authorization": f"Bearer {token}"}
    assert client.get("/api/me", headers=auth).json()["role"] == "admin"
    assert client.get("/api/rovers").status_code == 401  # --public-read off

    # users managed on the command line take effect on the running server
    code, out, _ = _run(capsys, "users", "add", "ada", "--role", "viewer",
                        "--data-dir", str(data), "--json")  # fmt: skip
    assert code == 0
    ada = json.loads(out)["token"]
    assert client.get("/api/rovers", headers={"Authorization": f"Bearer {ada}"}).status_code == 200
    assert _run(capsys, "users", "revoke", "ada", "--data-dir", str(data))[0] == 0
    assert client.get("/api/rovers", headers={"Authorization": f"Bearer {ada}"}).status_code == 403
    assert (
        "wrong token: token revoked"
        in client.get("/api/rovers", headers={"Authorization": f"Bearer {ada}"}).text
    )


def test_users_on_the_command_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    data = str(tmp_path / "data")
    code, out, _ = _run(capsys, "users", "add", "grace", "--role", "operator", "--data-dir", data)
    assert code == 0 and "token:" in out and "shown this once" in out
    code, out, _ = _run(
        capsys, "users", "token", "grace", "--expires-days", "7", "--data-dir", data
    )
    assert code == 0 and "token:" in out
    code, out, _ = _run(capsys, "users", "list", "--data-dir", data)
    assert code == 0 and re.search(r"grace\s+operator\s+2\s", out), out
    code, out, _ = _run(capsys, "users", "role", "grace", "--role", "admin", "--data-dir", data)
    assert code == 0
    code, out, _ = _run(capsys, "users", "revoke", "grace", "--data-dir", data, "--json")
    assert code == 0 and '"revoked_tokens": 2' in out
    # every mistake: one line naming it, exit 2, nothing stored
    for argv, says in (
        (["users", "add", "grace", "--role", "viewer"], "exists already"),
        (["users", "add", "bob"], "--role"),
        (["users", "add", "bad name", "--role", "viewer"], "user name"),
        (["users", "token", "nobody"], "no user 'nobody'"),
        (["users", "revoke"], "needs a user name"),
        (["users", "add", "bob", "--role", "viewer", "--expires-days", "-1"], "expires_days"),
        (["users", "add", "bob", "--role", "viewer", "--expires-days", "1e9"], "at most"),
    ):
        code, out, err = _run(capsys, *argv, "--data-dir", data)
        assert code == 2 and says in err and "Traceback" not in err, (argv, err)
    code, _, err = _run(capsys, "users", "add", "bob", "--role", "root", "--data-dir", data)
    assert code == 2 and "invalid choice" in err
    code, out, _ = _run(capsys, "users", "list", "--data-dir", data, "--json")
    assert [u["name"] for u in json.loads(out)["users"]] == ["grace"]
