"""A whole sol's stored frames agree with those of the loop before it was made fast, and before
each frame became two records.

Issue 16 rewrote the per-cycle path (NATE's step, gyro and odometry propagation, the frames
built over a segment in arrays) without changing what it computes; issue 21 split each frame
into the rover's downlink and the scorer's truth record, without changing a figure. The
reference, ``frames_before_fast_loop.json.gz`` (beside it), holds every frame (the one
record of those days, as a dict) of the session below as the loop of commit 7a9fe57 made
it, with the server's frame rate: a
Fine attitude loaded from the truth, a straight drive, a turn in place, an arc, Articulate
and an HGA pass, with both side estimators. It was written by running this module with
``--write`` on that commit. A downlink and its truth record put back together
(``sim.scoring.truth.merged``) must equal the old frame on every field it had (the fields the
downlink has added since, such as the encoders' readings, are not in the reference). Every
number must agree to 1e-6 (metres, degrees, seconds, and the unitless quaternion
components); texts, flags and modes exactly.

Issue 21 made a rover's frames strictly increasing in ``t_s`` (one frame per moment,
``sim.loop.frames``). The reference holds three second frames of a moment, each made by a
command that took no time after the previous command's last frame: ARTICULATE_START after
the arc, ARTICULATE_STOP after the WAIT, and HGA_PASS's first frame after ARTICULATE_STOP.
None of them carries an event, and the loop now makes none of them; the frames that follow
are unchanged (the frame rate counts from the moment's first frame, as it did). So the
reference is compared without them (``one_frame_per_moment``), and the file is unchanged.
"""

from __future__ import annotations

import gzip
import json
import math
import sys
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from estimation.sapp.aqf import AttitudeQuality
from sequences import commands as cmd
from sim.loop.session import RoverSession
from sim.scoring.truth import merged

REFERENCE = Path(__file__).parent / "frames_before_fast_loop.json.gz"
TOLERANCE = 1e-6


def session_frames() -> list[dict[str, Any]]:
    """The frames of the reference session (module docstring)."""
    session = RoverSession(
        "gusev",
        7,
        datetime(2004, 4, 14, 16, 30, 0, tzinfo=UTC),
        frame_every_s=1.0,
        estimators=("sapp", "kinematic_ekf", "radio_ekf"),
    )
    session.nate.load_attitude(session.q_b_ll_true(), AttitudeQuality.FINE)
    session.run(
        [
            cmd.DriveStraight(12.0),
            cmd.TurnInPlace(-30.0),
            cmd.DriveArc(4.0, 25.0),
            cmd.ArticulateStart(),
            cmd.Wait(20.0),
            cmd.ArticulateStop(),
            cmd.HgaPass(3.0),
        ]
    )
    return [
        merged(d.as_dict(), t.as_dict())
        for d, t in zip(session.downlinks, session.truths, strict=True)
    ]


def one_frame_per_moment(frames: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """``frames`` without each frame at the ``t_s`` of the one before it (module docstring);
    such a frame must carry no event, or its events would be lost rather than carried."""
    kept = frames[:1]
    for frame in frames[1:]:
        if frame["t_s"] <= kept[-1]["t_s"]:
            assert frame["events"] == [], frame
            continue
        kept.append(frame)
    return kept


def _differences(before: Any, after: Any, path: str, out: list[str]) -> None:
    if isinstance(before, dict) and isinstance(after, dict):
        if before.keys() != after.keys():
            out.append(f"{path}: keys {sorted(before)} != {sorted(after)}")
            return
        for key in before:
            _differences(before[key], after[key], f"{path}.{key}", out)
    elif isinstance(before, list) and isinstance(after, list):
        if len(before) != len(after):
            out.append(f"{path}: length {len(before)} != {len(after)}")
            return
        for i, (b, a) in enumerate(zip(before, after, strict=True)):
            _differences(b, a, f"{path}[{i}]", out)
    elif isinstance(before, float) and isinstance(after, (int, float)):
        both_nan = math.isnan(before) and math.isnan(float(after))
        if not both_nan and not abs(before - after) <= TOLERANCE:
            out.append(f"{path}: {before!r} != {after!r}")
    elif before != after:
        out.append(f"{path}: {before!r} != {after!r}")


def test_a_sols_frames_agree_with_the_loop_before_it_was_made_fast() -> None:
    with gzip.open(REFERENCE, "rt", encoding="utf-8") as f:
        recorded = json.load(f)
    before = one_frame_per_moment(recorded)
    assert len(recorded) - len(before) == 3  # the three of the module docstring
    after = json.loads(json.dumps(session_frames()))  # as stored: through JSON
    assert len(after) == len(before)
    after = [{k: v for k, v in a.items() if k in b} for a, b in zip(after, before, strict=True)]
    differences: list[str] = []
    _differences(before, after, "frames", differences)
    assert not differences, f"{len(differences)} differences, first: {differences[:5]}"
    assert len(after) > 400  # the whole session, not a prefix


def test_the_comparison_catches_a_difference_above_the_tolerance() -> None:
    frame = {"p_s_est": [1.0, 2.0, 3.0], "aqf": "Fine", "t_s": 5.0}
    differences: list[str] = []
    _differences(frame, {**frame, "p_s_est": [1.0, 2.0 + 2e-6, 3.0]}, "f", differences)
    _differences(frame, {**frame, "aqf": "Coarse"}, "f", differences)
    _differences(frame, {**frame, "t_s": 5.0 + 5e-7}, "f", differences)
    assert differences == ["f.p_s_est[1]: 2.0 != 2.000002", "f.aqf: 'Fine' != 'Coarse'"]


if __name__ == "__main__" and sys.argv[1:] == ["--write"]:
    with gzip.open(REFERENCE, "wt", encoding="utf-8") as f:
        json.dump(session_frames(), f)
