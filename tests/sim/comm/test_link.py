"""The link across light time (sim.comm.link) on windows and a light time of its own: when
uplinks go and arrive, what a pass sends and when it lands, and that the link's state is
whole at any moment (a checkpoint mid-pass goes on as if nothing happened)."""

from __future__ import annotations

import copy
from typing import Any

import pytest

from sim.comm.link import CommLink, Progress
from sim.comm.plan import CommPlan
from sim.comm.store import HEADER_BITS, packed_bits
from sim.comm.windows import Window

OWLT_S = 600.0


class FixedLight:
    """A light time that does not change."""

    def uplink_arrival_t_s(self, t_radiated_s: float) -> float:
        return t_radiated_s + OWLT_S

    def downlink_arrival_t_s(self, t_sent_s: float) -> float:
        return t_sent_s + OWLT_S


WINDOWS = [
    Window("uplink", 1_000.0, 1_100.0, 100.0, 40.0),
    Window("relay", 5_000.0, 5_480.0, 1_000.0, 60.0),
    Window("dte", 9_000.0, 9_100.0, 100.0, 40.0),
    Window("uplink", 20_000.0, 20_100.0, 100.0, 40.0),
    Window("relay", 30_000.0, 30_480.0, 1_000.0, 60.0),
]


def fixed_windows(_lat: float, _lon: float, _plan: CommPlan, t0: float, t1: float) -> list[Window]:
    return [w for w in WINDOWS if w.end_t_s >= t0 and w.start_t_s <= t1]


def make_link(**plan: Any) -> CommLink:
    return CommLink(
        0.0,
        0.0,
        CommPlan().replaced({"relay_latency_s": 60.0, **plan}),
        0.0,
        fixed_windows,
        FixedLight(),
    )


def frame(t_s: float, events: bool = False) -> dict[str, Any]:
    return {
        "t_s": t_s,
        "sol": 1,
        "nate_mode": "Idle",
        "p": [0.0] * 20,
        "events": [{"text": "e", "kind": "k", "severity": "info"}] if events else [],
    }


def run(link: CommLink, t_to: float, step: float) -> Progress:
    total = Progress()
    t = link.t_s
    while t < t_to:
        t = min(t + step, t_to)
        got = link.advance(t)
        total.radiated += got.radiated
        total.onboard += got.onboard
        total.on_ground += got.on_ground
    return total


def test_an_uplink_waits_for_its_window_and_arrives_a_light_time_after_it_is_radiated() -> None:
    link = make_link()
    uplink = link.accept("sequence", 7, 1_000, 10.0)
    early = link.advance(999.0)
    assert not early.radiated and link.waiting == [uplink]
    got = run(link, 2_000.0, 5.0)
    assert got.radiated == [uplink] and got.onboard == [uplink]
    assert uplink.radiated_t_s == pytest.approx(1_000.0 + 1_000 / 100.0)  # its bits at 100 bit/s
    assert uplink.arrival_t_s == pytest.approx(uplink.radiated_t_s + OWLT_S)


def test_an_uplink_that_does_not_fit_in_what_is_left_of_a_window_takes_the_next() -> None:
    link = make_link()
    first = link.accept("sequence", 1, 8_000, 0.0)  # 80 s of the 100 s window
    second = link.accept("sequence", 2, 3_000, 0.0)  # 30 s: not in the 20 s left
    run(link, 25_000.0, 50.0)
    assert first.radiated_t_s == pytest.approx(1_080.0)
    assert second.radiated_t_s == pytest.approx(20_030.0)
    for u in (first, second):  # radiated whole inside an uplink window
        assert u.radiated_t_s is not None
        assert any(
            w.kind == "uplink" and w.start_t_s <= u.radiated_t_s <= w.end_t_s for w in WINDOWS
        )


def test_a_pass_sends_the_highest_priority_first_and_nothing_lands_early() -> None:
    link = make_link()
    for i in range(100):
        link.store.add_frame(frame(float(i), events=(i == 50)))
    link.store.add_report(99.0, {"type": "command", "status": "completed"})
    got = run(link, 40_000.0, 97.0)
    assert link.store.counts()[1] == link.store.counts()[2] == 0
    kinds = [(s.product.priority, s.product.t_s) for s in got.on_ground]
    priorities = [s.product.priority for s in got.on_ground if s.sent_t_s <= 5_480.0]
    # the reports first (the event's frame, the command's, the store's own account made at
    # the pass's opening), oldest first, then the decimated frames, then the rest
    # (and the store's account at every pass after)
    assert [t for p, t in kinds if p == 0][:3] == [50.0, 99.0, 5_000.0]
    assert got.on_ground[2].product.payload["type"] == "store"
    assert priorities == sorted(priorities)
    for sent in got.on_ground:
        latency = 60.0 if sent.via == "relay" else 0.0
        assert sent.arrival_t_s == pytest.approx(sent.sent_t_s + latency + OWLT_S)
        assert sent.sent_t_s >= sent.product.t_s
        assert any(w.start_t_s <= sent.sent_t_s <= w.end_t_s for w in WINDOWS if w.kind != "uplink")


def test_a_pass_cut_short_by_the_orbiter_setting_leaves_the_rest_for_the_next() -> None:
    link = make_link()
    bits = HEADER_BITS + packed_bits(frame(0.0))
    n = int(480 * 1_000 / bits) + 200  # more than one relay pass carries
    for i in range(n):
        link.store.add_frame(frame(float(i % 4_000)))
    first = run(link, 9_000.0, 33.0)
    sent_bits = sum(s.product.bits for s in first.on_ground)
    assert sent_bits <= 480 * 1_000  # no more than the pass's capacity
    assert all(s.sent_t_s <= 5_480.0 for s in first.on_ground)
    assert len(link.store) > 0
    second = run(link, 40_000.0, 333.0)
    assert len(link.store) == 0
    assert all(s.sent_t_s >= 9_000.0 for s in second.on_ground)


def test_small_steps_and_one_big_step_give_the_same_link() -> None:
    """The clock may advance the link by a tick or by a sol: the same passes either way."""
    results = []
    for step in (7.0, 40_000.0):
        link = make_link()
        link.accept("sequence", 3, 2_000, 0.0)
        for i in range(3_000):
            link.store.add_frame(frame(float(i), events=(i % 500 == 0)))
        got = run(link, 40_000.0, step)
        results.append([(s.product.id, round(s.arrival_t_s, 6)) for s in got.on_ground])
    assert results[0] == results[1]


def test_a_checkpoint_mid_pass_goes_on_as_if_uninterrupted() -> None:
    link = make_link()
    for i in range(3_000):
        link.store.add_frame(frame(float(i)))
    run(link, 5_200.0, 50.0)  # in the middle of the relay pass
    saved = copy.deepcopy(link.state())
    rest = run(link, 40_000.0, 100.0)
    again = CommLink.from_state(0.0, 0.0, saved, fixed_windows, FixedLight())
    rest_again = run(again, 40_000.0, 100.0)
    assert [s.product.id for s in rest.on_ground] == [s.product.id for s in rest_again.on_ground]
    assert again.state() == link.state()


def test_drain_puts_everything_through_at_once() -> None:
    link = make_link()
    link.accept("sequence", 1, 100, 0.0)
    link.store.add_frame(frame(5.0))
    got = link.drain(10.0)
    assert [u.sequence_id for u in got.onboard] == [1]
    assert [s.product.t_s for s in got.on_ground] == [5.0]
    assert len(link.store) == 0 and not link.waiting
