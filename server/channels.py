"""Telemetry at a glance: any numeric channel of the telemetry frame against time, over a
sol or a range of sols, decimated on the server so that spikes survive.

A channel is a numeric field of one of the two records of a frame (``hga_margin_deg``), one
component of a numeric list field (``p_mission_est_0``), or a figure of an estimator
running beside SAPP (``kinematic_ekf_position_error_m``): the names are the telemetry CSV's
column names. A channel of the rover's downlink (``sim.loop.downlink.Downlink``) is what the
rover reports; a channel of the truth record (``sim.scoring.truth.Truth``: the simulator's
truth and the scores against it) carries ``truth: true``: a real operator would not have it.
The flag comes from the record the field belongs to, never from its name.

Decimation keeps, per time bucket, the bucket's smallest and largest value (at their own
times), so a one-frame spike is never averaged or skipped away; a bucket with a missing
value (NaN, Earth below the horizon) keeps one gap.
"""

from __future__ import annotations

import math
import typing
from collections.abc import Callable
from dataclasses import dataclass, fields
from typing import Any

from estimation.geometry import STEERED_INDEX
from sim.loop.downlink import ESTIMATORS, Downlink
from sim.scoring.truth import TRUTH_FIELDS, Truth

MAX_SOLS = 7  # sols per request: a sol is up to ~90 000 stored frames at 1 Hz
MAX_POINTS = 10_000
DEFAULT_POINTS = 2000
MIN_POINTS = 4  # two buckets of min and max
AXES = ("t_s", "sol", "lmst_h")  # the x axis, not channels
# Components of the list fields (the records' docstrings: quaternions [x, y, z, w],
# positions and unit vectors [x, y, z] in their frame, bogies [left, right]).
LENGTHS = {"q_": 4, "p_": 3, "bogie_": 2, "steer_": len(STEERED_INDEX), "_ll_true": 3}
# Each side estimator's figures: its pose (downlink) and its errors (truth), with lengths.
SIDE_FIELDS = {"position_error_m": None, "attitude_error_deg": None, "p_mission": 3, "q_b_ll": 4}
SIDE_TRUTH = {"position_error_m", "attitude_error_deg"}
UNITS = (("_deg", "deg"), ("_m", "m"), ("_s", "s"))


@dataclass(frozen=True)
class Channel:
    """One plottable channel: its name (a CSV column), unit, truth flag and getter."""

    name: str
    unit: str
    truth: bool
    read: Callable[[dict[str, Any]], Any]

    def describe(self) -> dict[str, Any]:
        return {"name": self.name, "unit": self.unit, "truth": self.truth}


def _unit(field_name: str) -> str:
    if field_name.startswith("p_"):
        return "m"
    for suffix, unit in UNITS:
        if field_name.endswith(suffix):
            return unit
    return ""  # quaternion components, unit vectors, counts


def vector_length(field_name: str) -> int:
    """How many components a list field of the frame has (``LENGTHS``, by its name)."""
    for key, n in LENGTHS.items():
        if field_name.startswith(key) or field_name.endswith(key):
            return n
    raise ValueError(f"no known length for the list field {field_name}")


def is_truth(name: str) -> bool:
    """Whether a frame field, a channel or a side estimator's figure is the simulator's truth
    or scored against it: what the truth view alone may show (``channels``, alarm limits),
    by the record it belongs to (``sim.scoring.truth.Truth``)."""
    shared = ("t_s", "events", "estimators")  # in both records: the downlink's
    truth_only = name in TRUTH_FIELDS and name not in shared
    return truth_only or name in SIDE_TRUTH or name in truth_channel_names()


def _component(key: str, i: int) -> Callable[[dict[str, Any]], Any]:
    def read(f: dict[str, Any]) -> Any:
        value = f.get(key) or []
        return value[i] if len(value) > i else None

    return read


def _scalar(key: str) -> Callable[[dict[str, Any]], Any]:
    return lambda f: f.get(key)


def _side(name: str, key: str, i: int | None) -> Callable[[dict[str, Any]], Any]:
    def read(f: dict[str, Any]) -> Any:
        value = ((f.get("estimators") or {}).get(name) or {}).get(key)
        if i is None or value is None:
            return value
        return value[i] if len(value) > i else None

    return read


def frame_channels() -> dict[str, Channel]:
    """The numeric channels of every frame, from the two records' field types: the
    downlink's, then the truth's (``truth: true``)."""
    out: dict[str, Channel] = {}
    for record, truth in ((Downlink, False), (Truth, True)):
        hints = typing.get_type_hints(record)
        for f in fields(record):
            hint = hints[f.name]
            if f.name in AXES:
                continue
            if hint in (float, int):
                out[f.name] = Channel(f.name, _unit(f.name), truth, _scalar(f.name))
            elif typing.get_origin(hint) is list and typing.get_args(hint) == (float,):
                for i in range(vector_length(f.name)):
                    name = f"{f.name}_{i}"
                    out[name] = Channel(name, _unit(f.name), truth, _component(f.name, i))
    return out


def truth_channel_names() -> set[str]:
    """The names of every channel scored against, or read from, the simulator's truth."""
    side = {f"{e}_{k}" for e in ESTIMATORS for k in SIDE_TRUTH}
    return {c.name for c in frame_channels().values() if c.truth} | side


def side_channels(estimators: list[str]) -> dict[str, Channel]:
    """The figures of the estimators running beside SAPP (their error figures are scored
    against truth; their estimates are not)."""
    out: dict[str, Channel] = {}
    for name in estimators:
        for key, n in SIDE_FIELDS.items():
            for i in [None] if n is None else list(range(n)):
                full = f"{name}_{key}" + ("" if i is None else f"_{i}")
                out[full] = Channel(full, _unit(key), key in SIDE_TRUTH, _side(name, key, i))
    return out


def channels_of(last_frame: dict[str, Any] | None) -> dict[str, Channel]:
    """The channels of a rover: the frame's, and those of the estimators its last frame
    shows running beside SAPP."""
    running = sorted((last_frame or {}).get("estimators") or {})
    return frame_channels() | side_channels(running)


def _number(value: Any) -> float | None:
    if value is None or isinstance(value, bool):
        return None
    x = float(value)
    return x if math.isfinite(x) else None


def decimate(t: list[float], values: list[float | None], max_points: int) -> list[int]:
    """The indices to keep of a time series (``t`` ascending) so that at most
    ``max_points`` remain: per time bucket, the first gap and the smallest and largest
    value, in time order. Every index when there are few enough."""
    n = len(t)
    if n <= max_points:
        return list(range(n))
    buckets = max(1, max_points // 3)  # up to a gap, a min and a max each
    t0, span = t[0], (t[-1] - t[0]) or 1.0
    keep: list[int] = []
    start = 0
    for b in range(buckets):
        end = n if b == buckets - 1 else start
        edge = t0 + span * (b + 1) / buckets
        while end < n and t[end] < edge:
            end += 1
        if end > start:
            lo = hi = gap = None
            for i in range(start, end):
                v = values[i]
                if v is None:
                    gap = i if gap is None else gap
                    continue
                if lo is None or v < values[lo]:  # type: ignore[operator]
                    lo = i
                if hi is None or v > values[hi]:  # type: ignore[operator]
                    hi = i
            keep.extend(sorted({i for i in (lo, hi, gap) if i is not None}))
        start = end
    return keep


def channel_series(
    frames: list[dict[str, Any]], channel: Channel, max_points: int
) -> dict[str, Any]:
    """The channel's values over ``frames`` (ascending), decimated to ``max_points``."""
    t = [float(f["t_s"]) for f in frames]
    values = [_number(channel.read(f)) for f in frames]
    keep = decimate(t, values, max_points)
    return {
        **channel.describe(),
        "frames": len(frames),
        "decimated": len(keep) < len(frames),
        "t_s": [t[i] for i in keep],
        "sol": [int(frames[i]["sol"]) for i in keep],
        "lmst_h": [float(frames[i]["lmst_h"]) for i in keep],
        "values": [values[i] for i in keep],
    }
