"""A store too small for what the rover makes: the lowest priority is dropped, and the ground
learns of every drop from the gap the rover reports (nothing lost silently)."""

from __future__ import annotations

import dataclasses
import math

from sequences.validate import validate
from server.state import Server
from tests.server.comm.conftest import tick_until

DRIVE = "SEQUENCE d\nNADIR_UPDATE\nDRIVE_STRAIGHT distance_m=6\n"


def test_an_overflowing_store_reports_its_gaps(server: Server) -> None:
    runtime = server.rovers["spirit"]
    runtime.set_clock(speed=math.inf)
    small = dataclasses.replace(runtime.comm.plan, store_capacity_mbit=0.05)  # ~45 frames
    runtime.comm.request(plan=small)
    sequence = validate(DRIVE).sequence
    assert sequence is not None
    seq_id = server.store.add_sequence("spirit", "d", DRIVE, "text", "queued", [], [], [])
    runtime.enqueue(seq_id, sequence)
    mission = runtime.comm.mission
    assert mission is not None

    def gaps_reported() -> int:
        return sum(int(g["count"]) for g in mission.ground_view()["gaps"])

    tick_until(runtime, lambda: (server.store.get_sequence(seq_id) or {}).get("status")
               == "completed", "the drive's completion to come down")  # fmt: skip
    store = mission.link.store
    assert store.stats.dropped > 0
    tick_until(runtime, lambda: gaps_reported() == store.stats.dropped
               and not any(p.kind == "gap" for q in store._queues.values() for p in q),
               "every drop reported")  # fmt: skip
    server.writer.flush()
    texts = [e["text"] for e in server.store.events("spirit", -math.inf, math.inf)]
    assert any(t.startswith("downlink gap: the onboard store was full") for t in texts)
    # the reports were kept: the drive's command reports came down whole
    commands = server.store.commands("spirit", -math.inf, math.inf)
    assert [c["status"] for c in commands if c["sequence_id"] == seq_id] == ["completed"] * 2
