"""A deliberately slow WebSocket client loses frames; the other clients keep their rate and
the simulation its clock (issue 4, item 4 and its acceptance test).

A real server in a subprocess (the app of ``roverops serve`` under uvicorn on a free port,
a temporary SQLite database). Spirit articulates at speed 40, so it publishes 40 frames
per wall second (one per simulated second), more than the hub's cap of ``MAX_RATE_HZ`` per
client. Three clients read all along; a fourth reads like them, then stops reading for
``STALL_S`` and reads again. Its frames fill the buffers between its sender and itself,
the sender blocks, and its bounded queue drops the oldest frames: when it reads again it is
told how many (``dropped``). Meanwhile the others receive as before.

The buffers are made small on both ends (``bench.server_process.serve_with_small_buffers``;
the slow client asks for a small receive buffer and no compression), as on a slow link: on
loopback the kernel and asyncio would otherwise buffer a few hundred kB, a minute of frames.

The rates are compared as ratios measured in the same run (TESTING.md), with wide margins:
the point is "keeps its rate" against "stalls with the slow client", not a speed figure.
"""

from __future__ import annotations

import asyncio
import contextlib
import socket
import statistics
import time
from typing import Any

import pytest
from websockets.asyncio.client import connect

from bench.server import WS_SEQUENCE, Received, listen
from bench.server_process import running_server, upload
from server.hub import MAX_RATE_HZ
from server.runtime import FRAME_EVERY_S

SPEED = 40.0  # simulated s per wall s: 40 frames per wall second
BASELINE_S = 2.0  # all four clients reading
STALL_S = 8.0  # the slow client not reading
CLIENT_RECEIVE_BUFFER_BYTES = 4096
SERVER_BUFFER_BYTES = 4096


async def _until(predicate: Any, timeout_s: float, what: str) -> None:
    deadline = time.monotonic() + timeout_s
    while not predicate():
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        await asyncio.sleep(0.05)


def _playing(r: Received) -> bool:
    return bool(r.commands) and r.commands[-1].startswith("WAIT")


async def _scenario(url: str) -> dict[str, Any]:
    normal = [Received() for _ in range(3)]
    slow = Received()
    host, port = url.split("/")[2].split(":")
    sock = socket.socket()
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, CLIENT_RECEIVE_BUFFER_BYTES)
    sock.connect((host, int(port)))
    async with contextlib.AsyncExitStack() as stack:
        normal_ws = [await stack.enter_async_context(connect(url, proxy=None)) for _ in normal]
        slow_ws = await stack.enter_async_context(
            connect(url, proxy=None, sock=sock, compression=None, max_queue=1)
        )
        tasks = [
            asyncio.create_task(listen(ws, r)) for ws, r in zip(normal_ws, normal, strict=True)
        ]
        slow_task = asyncio.create_task(listen(slow_ws, slow))
        await _until(lambda: all(_playing(r) for r in [*normal, slow]), 60.0, "the play-out")
        baseline_from = time.time()
        await asyncio.sleep(BASELINE_S)
        stall_from = time.time()
        slow_task.cancel()  # the slow client stops reading (recv is cancellation-safe)
        await asyncio.gather(slow_task, return_exceptions=True)
        slow_told_before = slow.dropped
        normal_told_before = [r.dropped for r in normal]
        await asyncio.sleep(STALL_S)
        stall_to = time.time()
        normal_told_after = [r.dropped for r in normal]
        # reading again: the frames buffered before its sender blocked, then the news
        read_again = 0
        deadline = time.monotonic() + 5.0
        while slow.dropped == slow_told_before and time.monotonic() < deadline:
            slow.add(await asyncio.wait_for(slow_ws.recv(), timeout=5.0))
            read_again += 1
        for task in tasks:
            task.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)
    return {
        "baseline_hz": [len(r.between(baseline_from, stall_from)) / BASELINE_S for r in normal],
        "stall_hz": [len(r.between(stall_from, stall_to)) / STALL_S for r in normal],
        "sim_speed_x": statistics.median(r.sim_speed_x(stall_from, stall_to) for r in normal),
        "normal_dropped_during_stall": [
            a - b for a, b in zip(normal_told_after, normal_told_before, strict=True)
        ],
        "slow_dropped_during_stall": slow.dropped - slow_told_before,
        "slow_read_again": read_again,
    }


@pytest.fixture(scope="module")
def seen(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """One run of the scenario, shared by the tests below."""
    with running_server(tmp_path_factory.mktemp("ws"), buffer_bytes=SERVER_BUFFER_BYTES) as server:
        server.ok("POST", "/api/rovers/spirit/clock", {"speed": SPEED})
        upload(server, "spirit", WS_SEQUENCE.format(wait_s=SPEED * (STALL_S + 12.0)))
        return asyncio.run(_scenario(server.ws_url("spirit")))


def test_the_others_keep_their_rate_and_the_clock_its_speed(seen: dict[str, Any]) -> None:
    expected_hz = min(seen["sim_speed_x"] / FRAME_EVERY_S, MAX_RATE_HZ)
    assert seen["sim_speed_x"] > 0.75 * SPEED, seen  # the simulation did not stall
    for before, during in zip(seen["baseline_hz"], seen["stall_hz"], strict=True):
        assert during > 0.8 * before, seen  # each normal client kept its rate ...
        assert during > 0.8 * expected_hz, seen  # ... close to the rover's (capped) rate
    assert seen["normal_dropped_during_stall"] == [0, 0, 0], seen  # and lost nothing


def test_the_slow_client_is_told_it_lost_frames(seen: dict[str, Any]) -> None:
    assert seen["slow_dropped_during_stall"] > 0, seen


def test_no_client_gets_more_than_max_rate_hz(seen: dict[str, Any]) -> None:
    assert max(seen["stall_hz"]) <= 1.05 * MAX_RATE_HZ, seen
