"""A rover across light time through the whole server (``--comm mission``): a sequence waits
for its window, goes up, runs onboard only once it has arrived, and what it made reaches
the ground in the passes after, never earlier than the light allows; the truth goes out live."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Any

import pytest
from sqlalchemy import select

from server.state import Server
from server.storage.schema import frames_table
from sim.comm.windows import comm_windows
from sim.world.light_time import one_way_light_time_s
from sim.world.marsclock import get_mission
from tests.server.comm.conftest import upload

DRIVE = "SEQUENCE short_drive\nNADIR_UPDATE\nDRIVE_STRAIGHT distance_m=2\n"


def wait_for(what: Callable[[], Any], why: str, timeout_s: float = 180.0) -> Any:
    deadline = time.monotonic() + timeout_s
    while not (got := what()):
        assert time.monotonic() < deadline, f"timed out waiting for {why}"
        time.sleep(0.05)
    return got


def stages(server: Server, seq_id: int) -> dict[str, float]:
    found = server.store.get_sequence(seq_id) or {}
    return {s["stage"]: s["t_s"] for s in found.get("stages") or []}


def test_a_sequence_crosses_light_time_both_ways(server: Server) -> None:
    runtime = server.rovers["spirit"]
    assert runtime.comm.mode == "mission"
    accepted_t = runtime.t_s
    seq_id = upload(server, DRIVE)
    assert set(stages(server, seq_id)) == {"accepted", "waiting"}
    assert runtime.queue_snapshot() == []  # nothing onboard yet
    runtime.set_clock(speed=math.inf)
    runtime.start()
    wait_for(lambda: server.store.get_sequence(seq_id)["status"] == "completed",
             "the sequence's completion to come down")  # fmt: skip
    got = stages(server, seq_id)
    for name in ("accepted", "waiting", "radiated", "received", "started", "completed"):
        assert name in got, got
    site = get_mission("spirit")
    windows = comm_windows(site.lat_deg, site.lon_east_deg, runtime.comm.plan, accepted_t,
                           got["radiated"])  # fmt: skip
    # radiated inside an uplink window, onboard a light time later, started after that
    assert any(w.kind == "uplink" and w.start_t_s <= got["radiated"] <= w.end_t_s for w in windows)
    owlt = float(one_way_light_time_s(got["received"]))
    assert got["received"] - got["radiated"] == pytest.approx(owlt, abs=0.5)
    assert got["started"] >= got["received"]
    # every stored downlink came down no earlier than a light time after it was made
    server.writer.flush()
    with server.store.engine.connect() as conn:
        rows = conn.execute(
            select(frames_table.c.t_s, frames_table.c.received_t_s).where(
                frames_table.c.rover == "spirit")).all()  # fmt: skip
    assert rows
    for t_s, received in rows:
        assert received is not None
        assert received >= t_s + float(one_way_light_time_s(t_s)) - 1e-3
    # the commands' reports are stored as the rover made them
    commands = server.store.commands("spirit", -math.inf, math.inf)
    assert [c["status"] for c in commands] == ["completed", "completed"]
    assert commands[0]["start_t_s"] >= got["received"]


def test_the_truth_is_live_while_the_downlink_waits_for_a_pass(server: Server) -> None:
    runtime = server.rovers["spirit"]
    # at max speed with nothing the operators wait for the clock runs in real time (a pass
    # would take hours): a finite speed instead
    runtime.set_clock(speed=10_000.0)
    runtime.start()
    # truth records are stored as the clock plays them out; downlink records only once a
    # pass has brought them down
    wait_for(lambda: runtime.last_truth is not None, "the live truth")
    truth_t = runtime.last_truth["t_s"]  # type: ignore[index]
    if runtime.last_frame is not None:
        assert runtime.last_frame["t_s"] < truth_t
    comm = runtime.comm.mission
    assert comm is not None
    wait_for(lambda: comm.store_reported is not None, "a pass and its store account")
