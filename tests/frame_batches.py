"""Frame batches for the sink tests: frames written as one dict (a downlink's fields beside
a truth's, as ``sim.scoring.truth.merged`` gives them) split into the two records the runtime
hands its sinks (``server.sinks.FrameBatch``). Each side estimator's pose stays with the
downlink, its errors go to the truth; the events stay with the downlink."""

from __future__ import annotations

from typing import Any

from server.sinks import FrameBatch
from sim.scoring.truth import truth_fields

TRUTH_ONLY = set(truth_fields()) - {"t_s", "events", "estimators"}
SIDE_SCORES = {"position_error_m", "attitude_error_deg"}


def batch(frames: list[dict[str, Any]]) -> FrameBatch:
    """``frames`` as the two records apart (module docstring)."""
    downlinks, truths = [], []
    for f in frames:
        side = f.get("estimators") or {}
        downlink = {"events": [], "estimators": {}}
        downlink.update((k, v) for k, v in f.items() if k not in TRUTH_ONLY)
        if side:
            downlink["estimators"] = {
                n: {k: v for k, v in e.items() if k not in SIDE_SCORES} for n, e in side.items()
            }
        truth = {k: v for k, v in f.items() if k in TRUTH_ONLY}
        truth.update(
            t_s=f["t_s"],
            events=[],
            estimators={
                n: {k: v for k, v in e.items() if k in SIDE_SCORES} for n, e in side.items()
            },
        )
        downlinks.append(downlink)
        truths.append(truth)
    return FrameBatch(downlinks, truths)


def scores_of(frames: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """A truth record for each of ``frames`` with nothing scored (for the tests of the
    downlink's storage)."""
    return [{"t_s": f["t_s"], "events": [], "estimators": {}} for f in frames]
