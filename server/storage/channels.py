"""The telemetry tables' rows as records, and one channel read as arrays.

``downlink_row`` / ``truth_row`` make a table row of a record and ``downlink_record`` /
``truth_record`` the record back from a row selected as ``DOWNLINK_ROW`` / ``TRUTH_ROW``
(the columns: ``server.storage.columns``). ``read_channel`` reads one numeric channel of
either record over a time range: its column and the frames' ``t_s``, ``sol`` and ``lmst_h``
only, from the chunks they are packed in (``server.storage.chunks``) and the rows after the
last chunk, into numpy arrays (a truth channel's values put at the times of the downlink rows
they pair with), so 7 sols of one channel need neither decode any frame's JSON nor read a
row per frame (issue 21).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, cast

import numpy as np
from numpy.typing import NDArray
from sqlalchemy.engine import Connection

from server.storage.chunks import DOWNLINK_PACKING, TRUTH_PACKING, read_channels
from server.storage.columns import DOWNLINK, TRUTH
from server.storage.schema import RECORD_LAYOUT, frame_events, frames_table, truth_frames

if TYPE_CHECKING:  # types only: storage loads without the simulator (roverops users)
    from sim.loop.downlink import DownlinkDict
    from sim.scoring.truth import TruthDict

FRAMES = frames_table.c
TRUTHS = truth_frames.c
DOWNLINK_ROW = (FRAMES.t_s, FRAMES.sol, FRAMES.data, *(FRAMES[c] for c in DOWNLINK.columns))
TRUTH_ROW = (TRUTHS.t_s, TRUTHS.data, *(TRUTHS[c] for c in TRUTH.columns))
DOWNLINK_CHANNELS = frozenset(DOWNLINK.columns)
TRUTH_CHANNELS = frozenset(TRUTH.columns)


def downlink_row(rover: str, record: Mapping[str, Any]) -> dict[str, Any]:
    """The ``frames`` row of a downlink record (``Downlink.as_dict()``)."""
    return {"rover": rover, "t_s": float(record["t_s"]), "sol": int(record["sol"]),
            "layout": RECORD_LAYOUT, **DOWNLINK.encode(record)}  # fmt: skip


def truth_row(rover: str, record: Mapping[str, Any]) -> dict[str, Any]:
    """The ``truth_frames`` row of a truth record (``Truth.as_dict()``)."""
    return {"rover": rover, "t_s": float(record["t_s"]), **TRUTH.encode(record)}


def downlink_record(row: Sequence[Any]) -> DownlinkDict:
    """The downlink record of a row selected as ``DOWNLINK_ROW``."""
    head = {"t_s": float(row[0]), "sol": int(row[1])}
    return cast("DownlinkDict", frame_events(DOWNLINK.decode(head, row[3:], row[2])))


def truth_record(row: Sequence[Any]) -> TruthDict:
    """The truth record of a row selected as ``TRUTH_ROW``."""
    return cast("TruthDict", frame_events(TRUTH.decode({"t_s": float(row[0])}, row[2:], row[1])))


FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class ChannelArrays:
    """One channel at the stored frames' times, ascending; NaN where it has no value."""

    t_s: FloatArray
    sol: NDArray[np.int64]
    lmst_h: FloatArray
    values: FloatArray

    def __len__(self) -> int:
        return len(self.t_s)

    def where(self, keep: NDArray[np.bool_]) -> ChannelArrays:
        """The frames where ``keep`` holds (these arrays themselves when it holds at every
        frame, as for a whole range of sols: no copy of 621,000 frames)."""
        if bool(keep.all()):
            return self
        return ChannelArrays(self.t_s[keep], self.sol[keep], self.lmst_h[keep], self.values[keep])


def read_channel(
    conn: Connection, rover: str, name: str, t_from: float, t_to: float
) -> ChannelArrays | None:
    """Channel ``name`` of ``rover`` with t_from <= t_s <= t_to (module docstring); ``None``
    when no column holds it."""
    if name not in DOWNLINK_CHANNELS and name not in TRUTH_CHANNELS:
        return None
    own = (name,) if name in DOWNLINK_CHANNELS else ()
    t_s, sol, lmst_h, *values = read_channels(
        conn, DOWNLINK_PACKING, rover, ("sol", "lmst_h", *own), t_from, t_to
    )
    if own:
        return ChannelArrays(t_s, sol.astype(np.int64), lmst_h, values[0])
    truth_t_s, truth_values = read_channels(conn, TRUTH_PACKING, rover, (name,), t_from, t_to)
    if np.array_equal(truth_t_s, t_s) and bool(np.all(t_s[1:] > t_s[:-1])):
        # each downlink with its truth, no time twice: the pairs are in place already
        return ChannelArrays(t_s, sol.astype(np.int64), lmst_h, truth_values)
    paired_values = np.full(len(t_s), np.nan)
    if len(truth_t_s):
        at = np.minimum(np.searchsorted(truth_t_s, t_s), len(truth_t_s) - 1)
        paired = truth_t_s[at] == t_s
        paired_values[paired] = truth_values[at[paired]]
    return ChannelArrays(t_s, sol.astype(np.int64), lmst_h, paired_values)
