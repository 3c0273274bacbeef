"""The telemetry's channels packed by chunk, so that a channel query reads one array per chunk
instead of one row per frame (issue 21: 7 sols of one channel in <= 0.5 s).

The frame rows (``frames``, ``truth_frames``) stay the record, each number in its column
(``server.storage.columns``). Once a rover has ``CHUNK_FRAMES`` rows of a table beyond its
last chunk (by row id), those rows are packed in the same transaction as the insert that
completed them: one row of the chunk table (``frame_chunks``, ``truth_chunks``) per channel,
its ``data`` the channel's values over the chunk as little-endian float64 (null: NaN; the
row id, ``t_s`` and ``sol`` are channels too), with the chunk's id and time span. A float64
holds a stored double exactly, and an id or a sol as an exact integer, so the values read back
from a chunk are the values stored in the rows.

``read_channels`` reads some channels of a rover over a time range: the chunks whose time span
meets it (``numpy.frombuffer``, no row of Python objects per frame) and the rows after the last
chunk (fewer than ``CHUNK_FRAMES``) from their columns, in (``t_s``, row id) order as a query
of the rows would give them. Rows are packed by id, not by time, so a frame stored out of time
order (a rover run again from its checkpoint) is found wherever it went.

A database of an older version has no chunks: opening it packs every full chunk
(``pack_stored``, one transaction per chunk, so a packing stopped half-way carries on at the
next opening); the rows after the last chunk are read from their columns until they fill one.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from sqlalchemy import Table, func, insert, select
from sqlalchemy.engine import Connection, Engine

from server.storage.columns import DOWNLINK, TRUTH
from server.storage.schema import frame_chunks, frames_table, truth_chunks, truth_frames

log = logging.getLogger(__name__)

CHUNK_FRAMES = 4096  # 32 kB a channel's chunk; the rows after the last one cost ~2 us each
PACKED = np.dtype("<f8")
FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Packing:
    """A table of records (``rows``), the table of its chunks and the channels packed."""

    rows: Table
    chunks: Table
    channels: tuple[str, ...]  # "id" and "t_s" first


DOWNLINK_PACKING = Packing(frames_table, frame_chunks, ("id", "t_s", "sol", *DOWNLINK.columns))
TRUTH_PACKING = Packing(truth_frames, truth_chunks, ("id", "t_s", *TRUTH.columns))
PACKINGS = (DOWNLINK_PACKING, TRUTH_PACKING)


def last_packed_id(conn: Connection, packing: Packing, rover: str) -> int:
    """The id of the last row of ``rover`` packed in a chunk; 0 before the first chunk."""
    c = packing.chunks.c
    got = conn.execute(
        select(func.max(c.id_last)).where(c.rover == rover, c.channel == "id")
    ).scalar()
    return 0 if got is None else int(got)


def _floats(conn: Connection, query: Any, width: int) -> FloatArray:
    """The rows of ``query`` as a float array of ``width`` columns (null: NaN), from the
    driver's own tuples (numpy probing SQLAlchemy's rows for the array protocol is slow)."""
    rows = conn.execute(query).cursor.fetchall()
    if not rows:
        return np.empty((0, width))
    return np.array(rows, dtype=np.float64)


def pack(
    conn: Connection, packing: Packing, rover: str, chunk_frames: int, most: int | None = None
) -> int:
    """Pack the full chunks of ``rover``'s rows after its last chunk (module docstring), at
    most ``most`` of them; how many chunks."""
    rows = packing.rows.c
    packed = 0
    while most is None or packed < most:
        after = last_packed_id(conn, packing, rover)
        beyond = (rows.rover == rover, rows.id > after)
        if conn.execute(select(func.count()).where(*beyond)).scalar_one() < chunk_frames:
            return packed
        values = _floats(
            conn,
            select(*(rows[c] for c in packing.channels))
            .where(*beyond)
            .order_by(rows.id)
            .limit(chunk_frames),
            len(packing.channels),
        )
        t_s = values[:, 1]
        span = {
            "rover": rover,
            "id_first": int(values[0, 0]),
            "id_last": int(values[-1, 0]),
            "t_first": float(t_s.min()),
            "t_last": float(t_s.max()),
            "n": len(values),
        }
        conn.execute(
            insert(packing.chunks),
            [{**span, "channel": name, "data": values[:, j].astype(PACKED).tobytes()}
             for j, name in enumerate(packing.channels)],
        )  # fmt: skip
        packed += 1
    return packed


def pack_new(conn: Connection, rovers: Sequence[str], chunk_frames: int) -> None:
    """After an insert of frames of ``rovers``: pack what now fills a chunk, in its
    transaction."""
    for rover in dict.fromkeys(rovers):
        for packing in PACKINGS:
            pack(conn, packing, rover, chunk_frames)


def pack_stored(engine: Engine, chunk_frames: int) -> int:
    """Pack every full chunk of a database (an older version's has none: module docstring),
    one transaction a chunk; how many chunks. Each chunk packed is logged."""
    total = 0
    for packing in PACKINGS:
        with engine.connect() as conn:
            rovers = list(conn.execute(select(packing.rows.c.rover).distinct()).scalars())
        for rover in rovers:
            while True:
                with engine.begin() as conn:
                    if not pack(conn, packing, rover, chunk_frames, most=1):
                        break
                total += 1
                log.info("storage: packed %d %s rows of %s in a chunk (%d chunks so far)",
                         chunk_frames, packing.rows.name, rover, total)  # fmt: skip
    return total


def read_channels(
    conn: Connection,
    packing: Packing,
    rover: str,
    names: Sequence[str],
    t_from: float,
    t_to: float,
) -> list[FloatArray]:
    """Channels ``names`` of ``rover`` with t_from <= t_s <= t_to: ``[t_s, *names]``, an
    array each, in (t_s, row id) order (module docstring)."""
    wanted = ("t_s", *names)
    c = packing.chunks.c
    after = last_packed_id(conn, packing, rover)
    # No ORDER BY: SQLite would copy every 32 kB array into a temporary B-tree to sort them
    # (5 times the query); the chunks are put in id order here. ``id_last <= after``: a chunk
    # packed since ``after`` was read holds rows that the tail below reads already.
    found = conn.execute(
        select(c.id_first, c.n, c.t_first, c.t_last, c.channel, c.data).where(
            c.rover == rover,
            c.channel.in_(wanted),
            c.id_last <= after,
            c.t_last >= t_from,
            c.t_first <= t_to,
        )
    ).cursor.fetchall()
    chunks: dict[int, tuple[int, bool, dict[str, FloatArray]]] = {}
    for id_first, n, t_first, t_last, channel, data in found:
        whole = t_from <= t_first and t_last <= t_to
        chunks.setdefault(id_first, (n, whole, {}))[2][channel] = np.frombuffer(data, PACKED)
    parts: list[list[FloatArray]] = [[] for _ in wanted]
    for n, whole, got in (chunks[k] for k in sorted(chunks)):
        # a channel a chunk lacks (its field added to the record since): no value there
        arrays = [got[name] if name in got else np.full(n, np.nan) for name in wanted]
        if not whole:  # a chunk at an end of the range: its frames inside the range only
            arrays = [a[(arrays[0] >= t_from) & (arrays[0] <= t_to)] for a in arrays]
        for part, array in zip(parts, arrays, strict=True):
            part.append(array)
    rows = packing.rows.c
    tail = _floats(
        conn,
        select(*(rows[n] for n in wanted))
        .where(rows.rover == rover, rows.id > after, rows.t_s >= t_from, rows.t_s <= t_to)
        .order_by(rows.id),
        len(wanted),
    )
    columns = [np.concatenate([*part, tail[:, j]]) for j, part in enumerate(parts)]
    t_s = columns[0]
    if len(t_s) > 1 and not bool(np.all(t_s[1:] >= t_s[:-1])):
        order = np.argsort(t_s, kind="stable")  # id order within a time: stable
        columns = [column[order] for column in columns]
    return columns
