"""Uploads validated in a worker process (``server.validation.pool``; issue 13, the
``event_loop_stall_ms_during_upload`` figure): the same answers as the threadpool path, the
work really done in the worker, and a dead worker never the server's problem (the request
retried in a new pool, then in a thread; no worker outliving the server).

No wall-clock asserts: what the process buys (the event loop not waiting for the
interpreter lock) is a speed, measured by ``roverops bench server``."""

from __future__ import annotations

import asyncio
import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

import server.validation.pool as pool_module
from server.app import ServerConfig, create_app, data_dir_url
from server.validation.context import RoverSite
from server.validation.pool import ValidationPool, check_upload

TOKEN = "validation-pool-token"
AUTH = {"Authorization": f"Bearer {TOKEN}"}
LIMIT = 50_000
EXAMPLES = sorted((Path(__file__).resolve().parents[3] / "sequences" / "examples").iterdir())
REJECTED = "SEQUENCE rejected\n@ sol 43 10:00 LMST DRIVE_STRAIGHT distance_m=-1\nNO_SUCH\n"
WAIT_S = 30.0  # how long a process may take to end before the test calls it stuck
SPIRIT = RoverSite("spirit", -0.2555, 3.0658, 1.6e8)


def _client(data_dir: Path, processes: int) -> TestClient:
    config = ServerConfig(
        database_url=data_dir_url(data_dir),
        operator_token=TOKEN,
        max_upload_bytes=LIMIT,
        start_clocks=False,  # both servers' rovers stay where they start: the same warnings
        validation_processes=processes,
    )
    return TestClient(create_app(config), raise_server_exceptions=False)


@pytest.fixture(scope="module")
def clients(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[TestClient, TestClient]]:
    """A server validating in the threadpool, and one validating in a worker process."""
    with (
        _client(tmp_path_factory.mktemp("threads"), 0) as threads,
        _client(tmp_path_factory.mktemp("process"), 1) as process,
    ):
        yield threads, process


def _bodies() -> list[tuple[str, bytes, str]]:
    """(name, body, content type) of every example, a rejected sequence and bad bodies."""
    found = []
    for path in EXAMPLES:
        kind = "application/json" if path.suffix == ".json" else "text/plain"
        found.append((path.name, path.read_bytes(), kind))
    form = (
        b'--xyz\r\nContent-Disposition: form-data; name="file"; filename="a.seq"\r\n\r\n'
        + EXAMPLES[0].read_bytes()
        + b"\r\n--xyz--\r\n"
    )
    return [
        *found,
        ("multipart", form, "multipart/form-data; boundary=xyz"),
        ("rejected", REJECTED.encode(), "text/plain"),
        ("json text", json.dumps({"text": REJECTED}).encode(), "application/json"),
        ("bad json", b'{"steps": [', "application/json"),
        ("too deep", b"[" * 100 + b"]" * 100, "application/json"),
        ("huge integer", b'{"steps": [], "name": ' + b"1" * 5000 + b"}", "application/json"),
        ("text not a string", b'{"text": 5}', "application/json"),
        ("not utf-8", b"SEQUENCE x\n\xff\xfe\n", "text/plain"),
        ("no file part", b"--xyz\r\n\r\n--xyz--\r\n", "multipart/form-data; boundary=xyz"),
        ("too large", b"# " + b"x" * LIMIT + b"\n", "text/plain"),
    ]


def _answer(client: TestClient, path: str, body: bytes, kind: str) -> tuple[int, Any]:
    r = client.post(path, content=body, headers={"Content-Type": kind, **AUTH})
    answer = r.json()
    if isinstance(answer, dict):
        answer.pop("id", None)  # the two servers' databases number on their own
    return r.status_code, answer


@pytest.mark.parametrize(("name", "body", "kind"), _bodies(), ids=[b[0] for b in _bodies()])
@pytest.mark.parametrize(
    "path",
    [
        "/api/sequences/validate",
        "/api/sequences/validate?rover=spirit",
        "/api/rovers/spirit/sequences",
    ],
)
def test_the_worker_answers_as_the_threadpool_does(
    clients: tuple[TestClient, TestClient],
    monkeypatch: pytest.MonkeyPatch,
    path: str,
    name: str,
    body: bytes,
    kind: str,
) -> None:
    threads, process = clients
    expected = _answer(threads, path, body, kind)
    # validating in this process now fails: the process path's answers come from the worker
    monkeypatch.setattr(pool_module, "check_upload", _not_here)
    assert _answer(process, path, body, kind) == expected
    status, answer = expected
    assert status != 500
    if name == "rejected":
        assert status == (200 if "validate" in path else 422)
        assert {e["code"] for e in answer["errors"]} >= {"bad-value", "unknown-command"}
    if name == "too large":
        assert status == 413


def _not_here(*_: Any) -> Any:
    raise AssertionError("validated in the server's process")


def test_the_server_starts_its_worker_and_ends_it(tmp_path: Path) -> None:
    with _client(tmp_path, 1) as client:
        pool = client.app.state.server.validation  # type: ignore[attr-defined]
        [pid] = pool.worker_pids()  # started with the server (and warmed)
    _wait_gone(pid)


def test_a_killed_worker_does_not_break_the_next_upload(tmp_path: Path) -> None:
    with _client(tmp_path, 1) as client:
        pool = client.app.state.server.validation  # type: ignore[attr-defined]
        [killed] = pool.worker_pids()
        os.kill(killed, signal.SIGKILL)
        _wait_gone(killed)
        r = client.post(
            "/api/rovers/spirit/sequences", content=EXAMPLES[0].read_bytes(), headers=AUTH
        )
        assert r.status_code == 201, r.text
        [pid] = pool.worker_pids()
        assert pid != killed


def _check(pool: ValidationPool, text: str) -> Any:
    return pool.check(text.encode(), "text/plain", SPIRIT, True)


def test_an_upload_whose_worker_dies_is_answered_from_a_new_one() -> None:
    text = EXAMPLES[1].read_text()
    expected = check_upload(text.encode(), "text/plain", SPIRIT.context(), True)
    pool = ValidationPool(1)
    pool.start(SPIRIT)
    try:
        [killed] = pool.worker_pids()

        async def killed_midway() -> Any:
            os.kill(killed, signal.SIGSTOP)  # the upload waits for it...
            upload = asyncio.create_task(_check(pool, text))
            await asyncio.sleep(0)  # ...submitted to it...
            os.kill(killed, signal.SIGKILL)  # ...when it dies
            return await upload

        assert asyncio.run(killed_midway()) == expected
        assert pool.worker_pids() and killed not in pool.worker_pids()
    finally:
        pool.stop()


def test_ctrl_c_is_left_to_the_server() -> None:
    """SIGINT reaches the whole process group: the worker lives on, the server ends it."""
    text = EXAMPLES[0].read_text()
    pool = ValidationPool(1)
    # as under a terminal (a background job inherits SIGINT ignored, and so would the worker)
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        pool.start(SPIRIT)
    finally:
        signal.signal(signal.SIGINT, previous)
    try:
        first = asyncio.run(_check(pool, text))  # the worker has started (and warmed)
        [pid] = pool.worker_pids()
        os.kill(pid, signal.SIGINT)
        assert asyncio.run(_check(pool, text)) == first
        assert pool.worker_pids() == [pid]
    finally:
        pool.stop()
    _wait_gone(pid)


def test_workers_that_keep_dying_leave_the_upload_to_a_thread(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Each new pool's worker exits as it starts: the request is still answered."""
    from concurrent.futures import ProcessPoolExecutor
    from multiprocessing import get_context

    def dying_pool() -> ProcessPoolExecutor:
        return ProcessPoolExecutor(
            1, mp_context=get_context("spawn"), initializer=os._exit, initargs=(3,)
        )

    text = EXAMPLES[0].read_text()
    expected = check_upload(text.encode(), "text/plain", SPIRIT.context(), True)
    pool = ValidationPool(1)
    monkeypatch.setattr(pool, "_new_pool", dying_pool)
    pool.start(SPIRIT)
    try:
        assert asyncio.run(_check(pool, text)) == expected
    finally:
        pool.stop()


def test_a_worker_ends_when_the_server_is_killed() -> None:
    """A worker waits on a queue it holds both ends of: without its watch it would live on."""
    program = (
        "import time\n"
        "from server.validation.pool import ValidationPool\n"
        "pool = ValidationPool(1)\n"
        "pool.start()\n"
        "print(pool.worker_pids()[0], flush=True)\n"
        "time.sleep(600)\n"
    )
    server = subprocess.Popen(
        [sys.executable, "-c", program], stdout=subprocess.PIPE, text=True, cwd=Path.cwd()
    )
    try:
        assert server.stdout is not None
        worker = int(server.stdout.readline())
        assert _alive(worker)
    finally:
        server.kill()
        server.wait(WAIT_S)
    _wait_gone(worker)


def _alive(pid: int) -> bool:
    """A process that runs (not ended, not a zombie waiting for its reaper)."""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except FileNotFoundError:
        return False
    return "\nState:\tZ" not in status


def _wait_gone(pid: int) -> None:
    deadline = time.monotonic() + WAIT_S
    while _alive(pid):
        assert time.monotonic() < deadline, f"process {pid} still runs"
        time.sleep(0.05)
