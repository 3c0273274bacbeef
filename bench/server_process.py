"""A real ``roverops serve`` in a subprocess, for the benches and the tests that need one.

``running_server`` starts it on a free port of 127.0.0.1 with a new SQLite database in a
directory of the caller's, waits until ``GET /api/rovers`` answers and stops it on exit;
``RunningServer`` is the client side (REST with the operator token, the WebSocket URL).
``serve_with_small_buffers`` is the same app with small socket buffers, as on a slow link
(``python -m bench.server_process``): ``running_server(buffer_bytes=...)`` starts that.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import os
import secrets
import signal
import socket
import subprocess
import sys
import time
import urllib.error
import urllib.request
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

POLL_S = 0.05  # wall seconds between status polls
START_TIMEOUT_S = 60.0


def free_port() -> int:
    """A TCP port of 127.0.0.1 free right now."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


@dataclass
class RunningServer:
    """A ``roverops serve`` subprocess: its URLs, operator token and process."""

    port: int
    token: str
    process: subprocess.Popen[bytes]
    log_path: Path
    _opener: urllib.request.OpenerDirector = field(
        default_factory=lambda: urllib.request.build_opener(urllib.request.ProxyHandler({}))
    )

    @property
    def base_url(self) -> str:
        return f"http://127.0.0.1:{self.port}"

    def ws_url(self, rover: str) -> str:
        """The live telemetry WebSocket of ``rover``."""
        return f"ws://127.0.0.1:{self.port}/ws/rovers/{rover}/telemetry"

    def request(
        self,
        method: str,
        path: str,
        body: str | dict[str, Any] | None = None,
        timeout_s: float = 30.0,
    ) -> tuple[int, Any]:
        """One REST call (with the operator token); ``(status, parsed JSON body)``. A dict
        body goes as JSON, a string as a text sequence."""
        headers = {"Authorization": f"Bearer {self.token}"}
        data: bytes | None = None
        if isinstance(body, dict):
            data = json.dumps(body).encode()
            headers["Content-Type"] = "application/json"
        elif body is not None:
            data = body.encode()
            headers["Content-Type"] = "text/plain"
        req = urllib.request.Request(self.base_url + path, data, headers, method=method)
        try:
            with self._opener.open(req, timeout=timeout_s) as response:
                return int(response.status), json.loads(response.read() or b"null")
        except urllib.error.HTTPError as error:
            text = error.read()
            try:
                return int(error.code), json.loads(text)
            except json.JSONDecodeError:
                return int(error.code), text.decode(errors="replace")

    def ok(self, method: str, path: str, body: str | dict[str, Any] | None = None) -> Any:
        """``request`` that must answer 2xx; RuntimeError naming the answer otherwise."""
        status, answer = self.request(method, path, body)
        if not 200 <= status < 300:
            raise RuntimeError(f"{method} {path}: HTTP {status}: {answer}")
        return answer

    def log_tail(self, chars: int = 3000) -> str:
        """The end of the server's stderr."""
        try:
            return self.log_path.read_text(errors="replace")[-chars:]
        except OSError:
            return ""


@contextlib.contextmanager
def running_server(
    data_dir: Path,
    token: str | None = None,
    buffer_bytes: int = 0,
    env: Mapping[str, str] | None = None,
) -> Iterator[RunningServer]:
    """``roverops serve`` on a free port with its SQLite database in ``data_dir``, ready
    (``GET /api/rovers`` answers) when entered; stopped (SIGTERM, then SIGKILL) on exit.
    ``buffer_bytes``: run it instead through ``serve_with_small_buffers`` (the same app
    and uvicorn, each WebSocket's send buffers that small). ``env``: environment variables
    for the server over this process's own, e.g. ``{"ROVEROPS_NO_3D": "1"}``."""
    token = token or secrets.token_urlsafe(18)
    port = free_port()
    log_path = data_dir / "server.log"
    process_env = {**os.environ, **(env or {}), "ROVEROPS_OPERATOR_TOKEN": token}
    command = [
        sys.executable, "-m", "cli.main", "serve", "--host", "127.0.0.1",
        "--port", str(port), "--data-dir", str(data_dir),
    ]  # fmt: skip
    if buffer_bytes:
        command = [
            sys.executable, "-m", "bench.server_process", "--port", str(port),
            "--data-dir", str(data_dir), "--buffer-bytes", str(buffer_bytes),
        ]  # fmt: skip
    with log_path.open("wb") as log:
        process = subprocess.Popen(command, env=process_env, stdout=subprocess.DEVNULL, stderr=log)
    server = RunningServer(port, token, process, log_path)
    try:
        deadline = time.monotonic() + START_TIMEOUT_S
        while True:
            if process.poll() is not None:
                raise RuntimeError(
                    f"the server exited ({process.returncode}):\n{server.log_tail()}"
                )
            with contextlib.suppress(OSError):
                if server.request("GET", "/api/rovers")[0] == 200:
                    break
            if time.monotonic() > deadline:
                raise RuntimeError(f"the server did not start:\n{server.log_tail()}")
            time.sleep(0.05)
        yield server
    finally:
        if process.poll() is None:
            process.send_signal(signal.SIGTERM)
            try:
                process.wait(timeout=15.0)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait(timeout=10.0)


def wait_for(predicate: Callable[[], Any], timeout_s: float, what: str) -> Any:
    """Poll ``predicate`` every ``POLL_S`` until it is truthy; RuntimeError after
    ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    while True:
        value = predicate()
        if value:
            return value
        if time.monotonic() > deadline:
            raise RuntimeError(f"timed out after {timeout_s:g} s waiting for {what}")
        time.sleep(POLL_S)


def upload(server: RunningServer, rover: str, text: str) -> int:
    """Upload a text sequence; its id (RuntimeError if it was not accepted)."""
    answer = server.ok("POST", f"/api/rovers/{rover}/sequences", text)
    sequence_id: int = answer["id"]
    return sequence_id


# ---- a server with small socket buffers (tests) ---------------------------------------------


def serve_with_small_buffers(port: int, data_dir: Path, token: str, buffer_bytes: int) -> None:
    """The app of ``roverops serve`` under uvicorn on 127.0.0.1:``port``, with the buffers
    between a WebSocket sender and the network made small, as on a slow link: the kernel's
    send buffer of each connection (``SO_SNDBUF`` on the listening socket, which accepted
    connections inherit; it also stops autotuning) and the asyncio transport's write
    buffer of each WebSocket (its high-water mark, 64 KiB by default). On loopback a client
    that stops reading otherwise has a few hundred kB of buffers before its sender in the
    server blocks: a minute of frames at 10 a second."""
    import uvicorn
    from uvicorn.protocols.websockets.websockets_sansio_impl import WebSocketsSansIOProtocol

    from server.app import ServerConfig, create_app, data_dir_url

    class SmallWriteBuffer(WebSocketsSansIOProtocol):
        def connection_made(self, transport: asyncio.BaseTransport) -> None:
            if isinstance(transport, asyncio.WriteTransport):
                transport.set_write_buffer_limits(high=buffer_bytes)
            super().connection_made(transport)

    app = create_app(ServerConfig(database_url=data_dir_url(data_dir), operator_token=token))
    sock = socket.socket()
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, buffer_bytes)
    sock.bind(("127.0.0.1", port))
    config = uvicorn.Config(app, ws=SmallWriteBuffer, log_level="warning")
    uvicorn.Server(config).run(sockets=[sock])


def _main(argv: list[str]) -> None:
    import argparse

    parser = argparse.ArgumentParser(description=serve_with_small_buffers.__doc__)
    parser.add_argument("--port", type=int, required=True)
    parser.add_argument("--data-dir", type=Path, required=True)
    parser.add_argument("--buffer-bytes", type=int, required=True)
    args = parser.parse_args(argv)
    token = os.environ.get("ROVEROPS_OPERATOR_TOKEN") or secrets.token_urlsafe(18)
    serve_with_small_buffers(args.port, args.data_dir, token, args.buffer_bytes)


if __name__ == "__main__":
    _main(sys.argv[1:])
