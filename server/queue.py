"""A rover's queue of accepted sequences (``server.runtime``): its entries, where they may
move, and their checkpointed form.

Only the head of the queue runs. A sequence that has started, and an immediate command,
keep their place (nothing moves in front of them): a started sequence's later steps assume
the rover its earlier steps left, and an immediate command was sent to run next. So an
immediate command goes in front of every sequence that has not started, but after a started
one: it waits for the started sequence to end, its steps run back to back.

In a checkpoint a queued sequence is plain data: its text (``sequences.language.to_text``,
parsed again on restore) and where it stands.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from collections.abc import Sequence as Seq
from dataclasses import asdict, dataclass, field
from typing import Any

from sequences import timing
from sequences.language import Sequence, TimeTag, parse, to_text
from server.errors import ConflictError
from sim.world.marsclock import sol_number_t_s, t_s_for_sol_lmst


@dataclass(frozen=True)
class StepOutcome:
    """How a step of a queued sequence ended (its command report, in short)."""

    status: str  # "completed", "failed", "refused" or "halted"
    reason: str | None
    start_t_s: float
    end_t_s: float


@dataclass
class QueuedSequence:
    """An accepted sequence in a rover's queue; ``next_step`` indexes ``sequence.steps``."""

    sequence_id: int
    sequence: Sequence
    next_step: int = 0
    immediate: bool = False
    wait_left_s: float | None = None  # a WAIT under way in chunks: what is left of it
    problems: list[str] = field(default_factory=list)  # steps that failed or were refused
    stopped: bool = False  # a refused or halted step stopped the sequence
    started: bool = False  # its first step has been taken up: it keeps its place
    outcomes: list[StepOutcome] = field(default_factory=list)  # steps done, in order

    @property
    def has_started(self) -> bool:
        """A step of it has run or is running (so its place in the queue is fixed)."""
        return self.started or self.next_step > 0 or self.wait_left_s is not None

    def summary(self) -> dict[str, Any]:
        """The entry as a rover's ``/state`` lists it."""
        return {
            "sequence_id": self.sequence_id,
            "name": self.sequence.name,
            "next_step": self.next_step,
            "steps": len(self.sequence.steps),
        }

    def state(self) -> dict[str, Any]:
        """The entry as plain data (the sequence as its text)."""
        return {
            "sequence_id": self.sequence_id,
            "text": to_text(self.sequence),
            "next_step": self.next_step,
            "immediate": self.immediate,
            "wait_left_s": self.wait_left_s,
            "problems": list(self.problems),
            "stopped": self.stopped,
            "started": self.started,
            "outcomes": [asdict(o) for o in self.outcomes],
        }

    @classmethod
    def from_state(cls, state: Mapping[str, Any]) -> QueuedSequence:
        """The entry of ``state()``."""
        return cls(
            sequence_id=int(state["sequence_id"]),
            sequence=parse(state["text"]),
            next_step=int(state["next_step"]),
            immediate=bool(state["immediate"]),
            wait_left_s=state["wait_left_s"],
            problems=list(state["problems"]),
            # "halted" before a step status took the name (a drive halted by fault protection)
            stopped=bool(state.get("stopped", state.get("halted", False))),
            started=bool(state["started"]),
            outcomes=[StepOutcome(**o) for o in state["outcomes"]],
        )


class QueueError(ConflictError):
    """A queue change refused; the message says why (``NotQueuedError``: not in it)."""


class NotQueuedError(QueueError):
    """The sequence is not in this rover's queue."""


@dataclass(frozen=True)
class QueueEntry:
    """A copy of one queued sequence, taken under the runtime's lock (``queue_snapshot``):
    ``pinned`` says why it cannot move (``None``: it can), ``running_step`` the index of
    the step executing or playing out now (``None``: none of its steps)."""

    sequence_id: int
    sequence: Sequence
    immediate: bool
    started: bool
    next_step: int
    stopped: bool
    outcomes: tuple[StepOutcome, ...]
    running_step: int | None
    pinned: str | None


@dataclass(frozen=True)
class Cancelled:
    """Where a cancelled sequence stopped: the steps done and the one still running (it
    runs to its end: a command is not interrupted), if any."""

    steps: int
    done: int
    running_step: int | None

    def where(self) -> str:
        """Where it stopped, in words (its record's ``detail``)."""
        if self.running_step is not None:
            rest = self.steps - self.running_step - 1
            left = f"; {rest} step(s) after it not run" if rest else ""
            return f"during step {self.running_step + 1} of {self.steps} (it runs to its end){left}"
        if self.done == 0:
            return f"before it started ({self.steps} step(s) not run)"
        return f"after step {self.done} of {self.steps} ({self.steps - self.done} not run)"


def pinned(item: QueuedSequence) -> str | None:
    """Why ``item`` keeps its place in the queue (``None``: it may move)."""
    if item.immediate:
        return "is an immediate command (it runs before every sequence not yet started)"
    if item.has_started:
        steps = len(item.sequence.steps)
        return f"has started (at step {min(item.next_step + 1, steps)} of {steps})"
    return None


def snapshot(
    queue: Iterable[QueuedSequence], current_step: tuple[int, int] | None
) -> list[QueueEntry]:
    """Copies of the entries of ``queue``, ``current_step`` (sequence id, step) the step
    executing or playing out now."""
    running = current_step
    return [
        QueueEntry(
            sequence_id=q.sequence_id,
            sequence=q.sequence,
            immediate=q.immediate,
            started=q.has_started,
            next_step=q.next_step,
            stopped=q.stopped,
            outcomes=tuple(q.outcomes),
            running_step=running[1] if running and running[0] == q.sequence_id else None,
            pinned=pinned(q),
        )
        for q in queue
    ]


def insert(queue: list[QueuedSequence], item: QueuedSequence) -> None:
    """Put ``item`` in ``queue``: an immediate command after the entries that keep their
    place (a started sequence, the immediate commands sent before it: commands run in the
    order sent) and before the other sequences, a sequence last."""
    if item.immediate:
        queue.insert(_first_free([pinned(q) is not None for q in queue]), item)
    else:
        queue.append(item)


def _first_free(kept: Seq[bool]) -> int:
    """Where an immediate command goes: after the entries at the head that keep their place
    (``kept``, in queue order), nothing moving in front of them."""
    return next((i for i, k in enumerate(kept) if not k), len(kept))


def _kept_state(entry: Mapping[str, Any]) -> bool:
    """``pinned`` for an entry's ``state()``: an immediate command or a started sequence."""
    return bool(
        entry["immediate"]
        or entry["started"]
        or entry["next_step"] > 0
        or entry["wait_left_s"] is not None
    )


def moved(
    items: Seq[QueuedSequence], sequence_id: int, to: int, rover: str
) -> list[QueuedSequence] | None:
    """``items`` with sequence ``sequence_id`` at position ``to`` (0 is the head), the others
    keeping their order; ``None`` if it is there already. Refused (``QueueError`` saying
    why) for a pinned sequence, in front of one, or past the end (module docstring)."""
    out = list(items)
    at = next((i for i, q in enumerate(out) if q.sequence_id == sequence_id), None)
    if at is None:
        raise NotQueuedError(f"sequence {sequence_id} is not in {rover}'s queue")
    why = pinned(out[at])
    if why is not None:
        raise QueueError(f"sequence {sequence_id} {why}: it keeps its place")
    if to >= len(out):
        raise QueueError(
            f"position {to} is past the end of the queue (positions 0 to {len(out) - 1})"
        )
    fixed = [i for i, q in enumerate(out) if pinned(q) is not None]
    if fixed and to <= fixed[-1]:
        head = out[fixed[-1]]
        raise QueueError(
            f"position {to} is in front of sequence {head.sequence_id}, which "
            f"{pinned(head)}: the highest free position is {fixed[-1] + 1}"
        )
    if to == at:
        return None
    out.insert(to, out.pop(at))
    return out


def merged(
    saved: Iterable[Mapping[str, Any]], queue: Iterable[QueuedSequence], removed: int | None
) -> list[dict[str, Any]]:
    """A checkpoint's queue ``saved`` (entries' ``state()``, an older copy) with the queue
    changes since applied: sequences that finished since keep their places there (a restart
    runs them again), ``removed`` goes, one queued since is added as new (an immediate command
    as ``insert`` puts it: after a started sequence, even one that finished since), and the
    others take the order they have in ``queue`` now."""
    out = [dict(q) for q in saved if q["sequence_id"] != removed]
    now = list(queue)
    held = {q["sequence_id"] for q in out}
    for item in now:
        if item.sequence_id not in held:
            fresh = QueuedSequence(item.sequence_id, item.sequence, immediate=item.immediate)
            if item.immediate:
                out.insert(_first_free([_kept_state(q) for q in out]), fresh.state())
            else:
                out.append(fresh.state())
    order = {item.sequence_id: i for i, item in enumerate(now)}
    slots = [i for i, q in enumerate(out) if q["sequence_id"] in order]
    ordered = sorted((out[i] for i in slots), key=lambda q: order[q["sequence_id"]])
    for slot, entry in zip(slots, ordered, strict=True):
        out[slot] = entry
    return out


def start_time(tag: TimeTag, mission: str, now_t_s: float, last_done_t_s: float) -> float:
    """When a step with time tag ``tag`` starts (TT s), the rover of ``mission`` at
    ``now_t_s``, its previous command done at ``last_done_t_s`` (``sequences.timing``, on
    the mission's clock)."""
    return timing.start_time(
        tag,
        now_t_s,
        last_done_t_s,
        lambda t: int(sol_number_t_s(mission, t)),
        lambda sol, lmst_h: t_s_for_sol_lmst(mission, sol, lmst_h),
    )


def tag_text(tag: TimeTag) -> str:
    """A step's time tag in words (empty: when the previous step completes)."""
    if tag.kind == "lmst":
        return f"at {tag.clock()} LMST"
    if tag.kind == "sol_lmst":
        return f"at sol {tag.sol} {tag.clock()} LMST"
    if tag.kind == "relative":
        return f"{tag.after_s:g} s after the previous step"
    return ""
