"""The onboard store (sim.comm.store): priorities, decimation, overflow told as gaps."""

from __future__ import annotations

from typing import Any

import pytest

from sim.comm.store import (
    HEADER_BITS,
    PRIORITY_DECIMATED,
    PRIORITY_FULL,
    PRIORITY_REPORT,
    OnboardStore,
    packed_bits,
)


def frame(
    t_s: float, mode: str = "Idle", events: list[dict[str, str]] | None = None
) -> dict[str, Any]:
    return {
        "t_s": t_s,
        "sol": 1,
        "nate_mode": mode,
        "aqf": "Unknown",
        "q_b_ll_est": [0.0, 0.0, 0.0, 1.0],
        "events": events or [],
        "command": "",
    }


def test_packed_bits_counts_numbers_flags_and_characters() -> None:
    # 2 numbers, a flag, a 3-character string, None, a list of 2 numbers
    assert packed_bits({"a": 1.5, "b": 2, "c": True, "d": "abc", "e": None, "f": [1.0, 2.0]}) == (
        32 + 32 + 8 + 24 + 8 + 64
    )
    with pytest.raises(TypeError):
        packed_bits({"x": object()})


def test_priorities_follow_events_decimation_and_mode_changes() -> None:
    store = OnboardStore(capacity_bits=10**9, decimate_s=60.0)
    store.add_frame(frame(0.0))  # the first: decimated
    store.add_frame(frame(10.0))  # full rate
    store.add_frame(frame(20.0, events=[{"text": "x", "kind": "k", "severity": "info"}]))
    store.add_frame(frame(30.0, mode="Mobility"))  # mode change: decimated
    store.add_frame(frame(40.0, mode="Mobility"))  # full rate
    store.add_frame(frame(90.0, mode="Mobility"))  # 60 s after the last kept
    store.add_report(95.0, {"type": "command", "status": "completed"})
    assert store.counts() == {PRIORITY_REPORT: 2, PRIORITY_DECIMATED: 3, PRIORITY_FULL: 2}
    order = []
    while (p := store.next_ready(1e9)) is not None:
        order.append((p.priority, p.t_s))
        store.remove(p)
    assert order == [(0, 20.0), (0, 95.0), (1, 0.0), (1, 30.0), (1, 90.0), (2, 10.0), (2, 40.0)]
    assert store.used_bits == 0 and store.stats.sent == 7


def test_a_product_is_not_ready_before_it_is_made() -> None:
    store = OnboardStore(capacity_bits=10**9)
    store.add_report(100.0, {"type": "x"})
    assert store.next_ready(99.9) is None
    assert store.next_made_t_s() == 100.0
    assert store.next_ready(100.0) is not None


def test_overflow_drops_lowest_priority_oldest_first_and_accounts_for_every_drop() -> None:
    one = HEADER_BITS + packed_bits(frame(0.0))
    store = OnboardStore(capacity_bits=20 * one, decimate_s=60.0)
    for i in range(200):  # 1 Hz: one decimated in 60, the rest full rate
        store.add_frame(frame(float(i)))
        assert store.used_bits <= store.capacity_bits + 2 * 250  # gaps may overrun by their bits
    assert store.stats.dropped > 0
    gaps = [p for p in _all(store) if p.kind == "gap"]
    assert sum(int(g.payload["count"]) for g in gaps) == store.stats.dropped
    assert sum(int(g.payload["bits"]) for g in gaps) == store.stats.dropped_bits
    # full-rate frames went first: the decimated ones (t = 0, 60, 120, 180) are all kept
    kept = {p.t_s for p in _all(store) if p.kind == "frame"}
    assert {0.0, 60.0, 120.0, 180.0} <= kept
    # the newest full-rate frames are kept, the oldest dropped
    assert 199.0 in kept and 1.0 not in kept
    gap = next(g for g in gaps if g.payload["priority"] == PRIORITY_FULL)
    assert gap.payload["first_t_s"] == 1.0 and gap.priority == PRIORITY_REPORT


def test_nothing_is_dropped_while_there_is_room() -> None:
    store = OnboardStore(capacity_bits=10**8)
    for i in range(500):
        store.add_frame(frame(float(i)))
    assert store.stats.dropped == 0 and len(store) == 500


def test_a_sent_gap_is_closed_and_later_drops_open_a_new_one() -> None:
    one = HEADER_BITS + packed_bits(frame(0.0))
    store = OnboardStore(capacity_bits=5 * one, decimate_s=1e3)
    for i in range(10):
        store.add_frame(frame(float(i)))
    gap = store.next_ready(1e9)
    assert gap is not None and gap.kind == "gap"
    first_count = gap.payload["count"]
    store.remove(gap)
    for i in range(10, 13):
        store.add_frame(frame(float(i)))
    gaps = [p for p in _all(store) if p.kind == "gap"]
    assert len(gaps) == 1 and gaps[0].payload["first_t_s"] >= 5.0
    assert first_count + gaps[0].payload["count"] == store.stats.dropped


def test_state_round_trip_keeps_order_gaps_and_decimation() -> None:
    one = HEADER_BITS + packed_bits(frame(0.0))
    store = OnboardStore(capacity_bits=8 * one, decimate_s=30.0)
    for i in range(20):
        store.add_frame(frame(float(i)))
    copy = OnboardStore.from_state(store.state())
    assert copy.state() == store.state()
    store.add_frame(frame(20.0))
    copy.add_frame(frame(20.0))
    assert copy.state() == store.state()


def _all(store: OnboardStore) -> list[Any]:
    return [p for q in store._queues.values() for p in q]
