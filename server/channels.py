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
from collections.abc import Callable, Mapping
from dataclasses import dataclass, fields
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

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


def channels_of(last_frame: Mapping[str, Any] | None) -> dict[str, Channel]:
    """The channels of a rover: the frame's, and those of the estimators its last frame
    shows running beside SAPP."""
    running = sorted((last_frame or {}).get("estimators") or {})
    return frame_channels() | side_channels(running)


def _number(value: Any) -> float:
    if value is None or isinstance(value, bool):
        return math.nan
    return float(value)


def decimate(t: ArrayLike, values: ArrayLike, max_points: int) -> NDArray[np.intp]:
    """The indices to keep of a time series (``t`` ascending; a missing value is NaN or
    ``None``) so that at most ``max_points`` remain: per time bucket, the first gap and the
    first smallest and first largest value, in time order. Every index when there are few
    enough. Arrays in, arrays out: a bucket is a slice of the sorted times, found by searching
    the bucket edges in the times (not each time among the edges: 7 sols are 621,000 times)."""
    t = np.asarray(t, dtype=np.float64)
    v = np.asarray(values, dtype=np.float64)
    n = len(t)
    if n <= max_points:
        return np.arange(n)
    buckets = max(1, max_points // 3)  # up to a gap, a min and a max each
    t0, span = t[0], (t[-1] - t[0]) or 1.0
    ends = np.searchsorted(t, t0 + span * np.arange(1, buckets) / buckets, side="left")
    starts = np.unique(np.r_[0, ends])  # of the non-empty buckets (the last takes the rest)
    starts = starts[starts < n]
    lengths = np.diff(np.r_[starts, n])
    index = np.arange(n)
    gap = np.isnan(v)
    low = np.where(gap, np.inf, v)
    high = np.where(gap, -np.inf, v)

    def first(hits: NDArray[np.bool_]) -> NDArray[np.intp]:
        """Each bucket's first index where ``hits`` holds (``n``: nowhere)."""
        return np.minimum.reduceat(np.where(hits, index, n), starts)

    lo = np.repeat(np.minimum.reduceat(low, starts), lengths)
    hi = np.repeat(np.maximum.reduceat(high, starts), lengths)
    kept = np.unique(np.r_[first(gap), first(~gap & (low == lo)), first(~gap & (high == hi))])
    return kept[kept < n]


def series(
    t_s: NDArray[np.float64],
    sol: NDArray[np.int64],
    lmst_h: NDArray[np.float64],
    values: NDArray[np.float64],
    channel: Channel,
    max_points: int,
) -> dict[str, Any]:
    """A channel's ``values`` at the frames' times (arrays, ascending; NaN: no value),
    decimated to ``max_points``; lists for JSON (null: no value)."""
    keep = decimate(t_s, values, max_points)
    return {
        **channel.describe(),
        "frames": len(t_s),
        "decimated": len(keep) < len(t_s),
        "t_s": t_s[keep].tolist(),
        "sol": sol[keep].astype(int).tolist(),
        "lmst_h": lmst_h[keep].tolist(),
        "values": [None if math.isnan(x) else x for x in values[keep].tolist()],
    }


def channel_series(
    frames: list[dict[str, Any]], channel: Channel, max_points: int
) -> dict[str, Any]:
    """The channel's values over ``frames`` (ascending), decimated to ``max_points``: for
    the figures no column holds (a side estimator's), read from each frame."""
    return series(
        np.array([float(f["t_s"]) for f in frames], dtype=np.float64),
        np.array([int(f["sol"]) for f in frames], dtype=np.int64),
        np.array([_number(f.get("lmst_h")) for f in frames], dtype=np.float64),
        np.array([_number(channel.read(f)) for f in frames], dtype=np.float64),
        channel,
        max_points,
    )
