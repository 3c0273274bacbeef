"""The queue in the runtime (issue 14, "the queue in the console"): moves and their rules,
cancel mid-sequence, safety against the clock thread by construction, and checkpoints that
keep the order the operators set."""

from __future__ import annotations

import contextlib
import math
import random
import re
import time
from typing import Any

import pytest

from sequences.language import Sequence
from sequences.validate import validate
from server.runtime import (
    ROVERS,
    NotQueuedError,
    QueueError,
    RoverRuntime,
)
from server.storage import CommandRecord
from tests.runtime_listener import RecordingListener

THREE = "SEQUENCE three\nNADIR_UPDATE\nWAIT duration_s=30\nGET_TILT_ATTITUDE\n"


def _seq(text: str = THREE) -> Sequence:
    result = validate(text)
    assert result.sequence is not None, result.errors
    return result.sequence


def _runtime(
    speed: float = math.inf, listener: RecordingListener | None = None
) -> tuple[RoverRuntime, list[CommandRecord]]:
    """A runtime whose clock the test ticks; its command reports (and the rest it reports)
    collected by its listener."""
    listener = listener or RecordingListener()
    runtime = RoverRuntime(ROVERS["spirit"], listener=listener)
    runtime.set_clock(speed=speed)
    return runtime, listener.reports


def _tick_until(runtime: RoverRuntime, done: Any, ticks: int = 200) -> None:
    for _ in range(ticks):
        if done():
            return
        runtime._tick(0.05)
    raise AssertionError("not reached")


def test_a_move_puts_the_sequence_there_and_the_others_keep_their_order() -> None:
    runtime, _ = _runtime()
    for i in (1, 2, 3):
        runtime.enqueue(i, _seq())
    runtime.move(3, 0)
    assert runtime.queued_ids() == [3, 1, 2]
    runtime.move(3, 2)
    assert runtime.queued_ids() == [1, 2, 3]
    runtime.move(2, 1)  # where it is: nothing to do
    assert runtime.queued_ids() == [1, 2, 3]


def test_a_started_sequence_and_an_immediate_command_keep_their_place() -> None:
    runtime, _ = _runtime()
    for i in (1, 2, 3):
        runtime.enqueue(i, _seq())
    runtime._tick(0.05)  # sequence 1 runs its first step
    assert runtime.queue[0].next_step == 1
    runtime.enqueue(9, _seq("SEQUENCE now\nSUNFIND\n"), immediate=True)
    assert runtime.queued_ids() == [1, 9, 2, 3]  # nothing in front of the started sequence
    refusals = {
        (1, 2): "sequence 1 has started (at step 2 of 3): it keeps its place",
        (9, 3): "sequence 9 is an immediate command",
        (3, 1): "position 1 is in front of sequence 9, which is an immediate command "
        "(it runs before every sequence not yet started): the highest free position is 2",
        (3, 0): "position 0 is in front of sequence 9",
        (2, 4): "position 4 is past the end of the queue (positions 0 to 3)",
    }
    for (sequence_id, to), why in refusals.items():
        with pytest.raises(QueueError, match=re.escape(why)):
            runtime.move(sequence_id, to)
        assert runtime.queued_ids() == [1, 9, 2, 3]  # nothing changed
    with pytest.raises(NotQueuedError, match="sequence 7 is not in spirit's queue"):
        runtime.move(7, 2)
    runtime.move(3, 2)
    assert runtime.queued_ids() == [1, 9, 3, 2]
    pinned = {e.sequence_id: e.pinned for e in runtime.queue_snapshot()}
    assert pinned[3] is None and pinned[2] is None
    assert pinned[9] and pinned[1] and "started" in pinned[1]


def test_a_step_starts_only_if_its_sequence_is_still_at_the_head() -> None:
    """The clock thread picks the head, then runs its step outside the lock: a move or a
    cancel in between must not let the picked sequence run from behind another (it would
    be started out of place), nor a cancelled one run at all."""
    runtime, reports = _runtime()
    runtime.enqueue(1, _seq())
    runtime.enqueue(2, _seq())
    picked = runtime._next_step()
    assert picked is not None and picked[0].sequence_id == 1
    runtime.move(2, 0)  # an operator, between the pick and the step
    runtime._execute(picked[0])
    assert reports == [] and runtime.queue[1].has_started is False
    runtime._tick(0.05)
    assert [(r.sequence_id, r.step_index) for r in reports] == [(2, 0)]
    runtime._tick(0.05)  # its frames played out: between two steps
    assert runtime.current_step is None

    picked = runtime._next_step()
    assert picked is not None and picked[0].sequence_id == 2
    cancelled = runtime.cancel(2)
    assert cancelled is not None and cancelled.done == 1 and cancelled.running_step is None
    runtime._execute(picked[0])
    assert len(reports) == 1  # the cancelled sequence ran nothing more


def test_moves_and_cancels_from_another_thread_never_break_a_sequence() -> None:
    """The clock thread at max speed while an operator thread moves and cancels at random:
    each sequence's steps run in order and together (a started sequence keeps the head),
    a cancelled one runs no step after the one running when it was cancelled, and every
    other one runs whole."""

    def stored(_report: CommandRecord) -> None:
        # as the server's storage takes a moment: at max speed the clock thread no longer
        # sleeps between steps, and could drain the queue before this thread ran at all
        time.sleep(0.002)

    runtime, reports = _runtime(listener=RecordingListener(on_report=stored))
    short = _seq("SEQUENCE short\nWAIT duration_s=5\nWAIT duration_s=5\nWAIT duration_s=5\n")
    ids = list(range(1, 41))
    for i in ids:
        runtime.enqueue(i, short)
    cancelled: dict[int, int] = {}  # id: the last step it may have run
    rng = random.Random(14)
    runtime.start()
    try:
        deadline = time.monotonic() + 20.0
        while runtime.queued_ids() and time.monotonic() < deadline:
            queued = runtime.queued_ids()
            victim = rng.choice(queued)
            # until one is cancelled, then at random: at max speed the clock thread does not
            # sleep between steps, and the queue may drain in a few of these iterations
            if not cancelled or rng.random() < 0.15:
                stopped = runtime.cancel(victim)
                if stopped is not None:
                    last = stopped.running_step if stopped.running_step is not None else -1
                    cancelled[victim] = max(stopped.done - 1, last)
            else:
                # refused when started, in front of a started one, or gone meanwhile
                with contextlib.suppress(QueueError):
                    runtime.move(victim, rng.randrange(len(queued)))
            time.sleep(rng.random() * 0.003)
        _wait_for(lambda: not runtime.queued_ids() and not runtime.executing)
    finally:
        runtime.stop()
    ran = [(r.sequence_id, r.step_index) for r in reports]
    runs: list[int] = []  # sequences in the order they ran, one entry per contiguous run
    for sequence_id, _step in ran:
        if not runs or runs[-1] != sequence_id:
            runs.append(sequence_id)
    assert len(runs) == len(set(runs)), "a sequence was interrupted by another"
    for i in ids:
        steps = [s for q, s in ran if q == i]
        expected = 3 if i not in cancelled else cancelled[i] + 1
        assert steps == list(range(len(steps))) and len(steps) <= expected, (i, steps)
        if i not in cancelled:
            assert steps == [0, 1, 2], (i, steps)
    assert cancelled and len(runs) >= len(ids) - len(cancelled)


def _wait_for(predicate: Any, timeout_s: float = 30.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not predicate():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.01)


def test_every_queue_change_is_in_the_checkpoint_a_restart_restores() -> None:
    listener = RecordingListener()
    runtime, _ = _runtime(listener=listener)
    blobs = listener.blobs
    for i in (1, 2, 3):
        runtime.enqueue(i, _seq())
    runtime.checkpoint()  # the last full checkpoint: before any step
    _tick_until(runtime, lambda: len(runtime.queue[0].outcomes) == 3)  # 1 ran its steps
    runtime.move(3, 1)
    runtime.enqueue(4, _seq())
    runtime.cancel(2)
    assert runtime.queued_ids() == [1, 3, 4]
    assert listener.commits == 2  # a move and a cancel are stored before they return
    restored = RoverRuntime.restore(ROVERS["spirit"], blobs[-1])
    assert restored.queued_ids() == [1, 3, 4]
    # what ran after the full checkpoint runs again after a restart, as before
    assert [q.next_step for q in restored.queue] == [0, 0, 0]

    _tick_until(runtime, lambda: runtime.queued_ids()[0] == 3)  # 1 left the queue
    runtime.cancel(4)
    restored = RoverRuntime.restore(ROVERS["spirit"], blobs[-1])
    assert restored.queued_ids() == [1, 3]  # 1 still there: it keeps its place, first


def test_cancel_mid_sequence_runs_nothing_after_the_step_under_way() -> None:
    runtime, reports = _runtime(speed=10.0)  # a finite speed: a step's frames play out
    runtime.enqueue(1, _seq())
    _tick_until(runtime, lambda: runtime.current_step == (1, 1))  # the WAIT, in chunks
    stopped = runtime.cancel(1)
    assert stopped is not None and (stopped.steps, stopped.done, stopped.running_step) == (3, 1, 1)
    for _ in range(100):
        runtime._tick(0.25)
    assert [(r.sequence_id, r.step_index) for r in reports] == [(1, 0)]
    assert runtime.queued_ids() == [] and runtime.current_step is None


def test_the_snapshot_says_each_steps_outcome_and_which_runs() -> None:
    runtime, _ = _runtime(speed=10.0)
    runtime.enqueue(1, _seq())
    _tick_until(runtime, lambda: runtime.current_step == (1, 1))
    (entry,) = runtime.queue_snapshot()
    assert entry.started and entry.running_step == 1
    assert [o.status for o in entry.outcomes] == ["completed"]
    assert entry.outcomes[0].end_t_s > entry.outcomes[0].start_t_s


def test_immediate_commands_run_in_the_order_they_were_sent() -> None:
    """Each immediate command goes before the queued sequences but after the immediate
    commands sent before it: two commands sent A then B run A then B."""
    runtime, _ = _runtime()
    runtime.enqueue(1, _seq())
    runtime.enqueue(2, _seq("NADIR_UPDATE\n"), immediate=True)
    runtime.enqueue(3, _seq("GET_TILT_ATTITUDE\n"), immediate=True)
    assert runtime.queued_ids() == [2, 3, 1]


def test_an_immediate_command_waits_for_a_started_sequence_to_end() -> None:
    """Issue 21: an immediate command sent while a started sequence is between its steps
    (its drive done and played out, its PLANT_SITE not yet taken up) ran between them,
    though nothing moves in front of a started sequence. It runs after the sequence's last
    step, and before the sequences that have not started."""
    runtime, reports = _runtime()
    drive = "SEQUENCE drive\nNADIR_UPDATE\nDRIVE_STRAIGHT distance_m=0.5\nPLANT_SITE\n"
    runtime.enqueue(1, _seq(drive))
    runtime.enqueue(2, _seq("SEQUENCE later\nGET_TILT_ATTITUDE\n"))
    _tick_until(runtime, lambda: runtime.queue[0].next_step == 2 and not runtime._playout)
    assert runtime.current_step is None  # between the drive and the PLANT_SITE
    runtime.enqueue(9, _seq("SEQUENCE now\nNADIR_UPDATE\n"), immediate=True)
    assert runtime.queued_ids() == [1, 9, 2]
    _tick_until(runtime, lambda: not runtime.queue and not runtime._playout)
    order = [(r.sequence_id, r.command.split()[0]) for r in reports]
    assert order == [
        (1, "NADIR_UPDATE"),
        (1, "DRIVE_STRAIGHT"),
        (1, "PLANT_SITE"),
        (9, "NADIR_UPDATE"),
        (2, "GET_TILT_ATTITUDE"),
    ]


def test_a_restart_keeps_an_immediate_command_behind_a_sequence_started_before_it() -> None:
    """The checkpoint's copy of the queue (``server.queue.merged``): sequence 1 had started
    at the last checkpoint and has finished since, then an immediate command came. A
    restart runs sequence 1's rest again, so the command still goes after it."""
    from server.queue import QueuedSequence, merged

    started = QueuedSequence(1, _seq(), next_step=1, started=True)
    later = QueuedSequence(2, _seq())
    saved = [started.state(), later.state()]
    now = [QueuedSequence(9, _seq("SEQUENCE now\nSUNFIND\n"), immediate=True), later]
    assert [q["sequence_id"] for q in merged(saved, now, None)] == [1, 9, 2]
