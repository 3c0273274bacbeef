"""What a killed server stored, compared with what a run never killed stored.

Both runs are the same deterministic scenario (``bench.comm.kills``), so the rows are the
same but for the kills'. Compared, each as a multiset of keys:

- ``frames``: the downlink frames, by ``t_s``;
- ``events``: by time, kind and text, but the server's own start notices (a restart adds
  one each);
- ``commands``: the command rows, by sequence, step, command, status and start time (a
  step run again after a restart keeps its row: a second run at another time shows here);
- ``stages``: each sequence's command history, by stage name;
- ``status``: each sequence's final status.

``lost``: in the reference, not stored; ``duplicated``: stored more often than in the
reference; ``extra``: stored, not in the reference at all (what a command run twice
leaves: its second run's frames, events and start time).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Hashable

from bench.comm.checks import Stored

KINDS = ("frames", "events", "commands", "stages", "status")


def keys(stored: Stored) -> dict[str, Counter[Hashable]]:
    """What is compared of ``stored``, each kind a multiset of keys (module docstring)."""
    names = {int(s["id"]): str(s["name"]) for s in stored.sequences}
    return {
        "frames": Counter(round(t, 6) for t, _r in stored.frames),
        "events": Counter(
            (round(t, 6), kind, text) for t, kind, text, _r in stored.events if kind != "server"
        ),
        "commands": Counter(
            (
                names.get(int(c["sequence_id"] or 0)),
                c["step_index"],
                c["command"],
                c["status"],
                round(float(c["start_t_s"]), 3),
            )
            for c in stored.commands
        ),
        "stages": Counter(
            (str(s["name"]), str(g["stage"])) for s in stored.sequences for g in s["stages"] or []
        ),
        "status": Counter((str(s["name"]), str(s["status"])) for s in stored.sequences),
    }


def compare(reference: Stored, killed: Stored) -> dict[str, dict[str, int]]:
    """Per kind of row: ``lost``, ``duplicated`` and ``extra`` (module docstring)."""
    ref, got = keys(reference), keys(killed)
    out = {}
    for kind in KINDS:
        twice = {k: n - ref[kind][k] for k, n in got[kind].items() if n > ref[kind].get(k, n)}
        out[kind] = {
            "lost": sum((ref[kind] - got[kind]).values()),
            "duplicated": sum(twice.values()),
            "extra": sum(n for k, n in got[kind].items() if k not in ref[kind]),
        }
    return out


def examples(reference: Stored, killed: Stored, n: int = 3) -> list[str]:
    """Up to ``n`` keys of each kind lost, duplicated and extra, in words."""
    ref, got = keys(reference), keys(killed)
    out: list[str] = []
    for kind in KINDS:
        lost = list(ref[kind] - got[kind])
        twice = [k for k, c in got[kind].items() if c > ref[kind].get(k, c)]
        extra = [k for k in got[kind] if k not in ref[kind]]
        out += [f"{kind} lost: {k}" for k in lost[:n]]
        out += [f"{kind} duplicated: {k}" for k in twice[:n]]
        out += [f"{kind} extra: {k}" for k in extra[:n]]
    return out
