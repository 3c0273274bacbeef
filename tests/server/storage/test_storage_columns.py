"""The telemetry records in numeric columns (``server.storage.columns``): every numeric field
of ``Downlink`` and ``Truth`` has its column named as the channel and the CSV name it, a
record comes back as it was stored (NaN and None as null, ints as ints, what does not fit a
column kept whole), a field added to a record reaches an existing database, and a channel
read from its column is the channel of the stored records; on SQLite and PostgreSQL."""

from __future__ import annotations

import logging
import math
from collections.abc import Iterator
from datetime import UTC, datetime
from typing import Any

import numpy as np
import pytest

from server.channels import frame_channels
from server.storage import BatchWriter, Store
from server.storage.chunks import CHUNK_FRAMES
from server.storage.columns import DOWNLINK, TRUTH
from sim.loop.downlink import downlink_fields
from sim.scoring.truth import truth_fields

FramePairs = list[tuple[dict[str, Any], dict[str, Any]]]


@pytest.fixture(scope="module")
def pairs() -> FramePairs:
    """A real session's records (a Nadir Update, then a short drive): the downlink and its
    truth, as the runtime hands them to storage."""
    from sequences import commands
    from sim.loop.session import RoverSession

    session = RoverSession(
        "flat", 0, datetime(2004, 4, 14, 16, 30, tzinfo=UTC), estimators=("sapp", "kinematic_ekf")
    )
    assert session.execute(commands.NadirUpdate()).status == "completed"
    assert session.execute(commands.DriveStraight(distance_m=0.5)).status == "completed"
    got = session.take_frames()
    assert len(got) > 100 and any(d["events"] for d, _ in got)
    return got


@pytest.fixture
def store(store_url: str) -> Iterator[Store]:
    s = Store(store_url)
    yield s
    s.close()


def _stored(store: Store, pairs: FramePairs) -> None:
    writer = BatchWriter(store)
    writer.frames("spirit", [d for d, _ in pairs], [t for _, t in pairs])
    writer.stop()


def test_every_numeric_channel_of_each_record_has_its_column() -> None:
    channels = frame_channels()
    downlink = {c.name for c in channels.values() if not c.truth}
    truth = {c.name for c in channels.values() if c.truth}
    assert set(DOWNLINK.columns) == downlink | {"lmst_h"}  # t_s and sol: the row's own
    assert set(TRUTH.columns) == truth
    assert {"q_b_ll_est_3", "steer_enc_deg_3", "bogie_enc_deg_1"} <= set(DOWNLINK.columns)
    assert {"hga_margin_deg", "sun_ll_true_2"} <= set(TRUTH.columns)


def test_both_records_come_back_as_stored(store: Store, pairs: FramePairs) -> None:
    _stored(store, pairs)
    t = [d["t_s"] for d, _ in pairs]
    got = store.frames("spirit", -math.inf, math.inf)
    assert got == [d for d, _ in pairs]  # every field, bit for bit
    assert [list(f) for f in got[:1]] == [downlink_fields()]  # in the record's order
    truths = store.truths("spirit", t[0], t[-1])
    assert truths == {tr["t_s"]: tr for _, tr in pairs}  # by time (the last of a time)
    assert next(iter(truths.values())).keys() == set(truth_fields())
    assert store.last_frame("spirit") == pairs[-1][0]
    assert store.last_truth("spirit") == pairs[-1][1]
    k = next(i for i, (d, _) in enumerate(pairs) if d["estimators"])  # the drive's
    merged = store.frames("spirit", t[k], t[k], with_truth=True)[0]
    assert merged["hga_margin_deg"] == pairs[k][1]["hga_margin_deg"]
    assert merged["estimators"]["kinematic_ekf"].keys() >= {"p_mission", "position_error_m"}


def test_values_that_do_not_fit_a_column_round_trip(store: Store, pairs: FramePairs) -> None:
    """NaN, infinities and None read back as null; a list of the wrong length, a list
    without a finite component, a string in a numeric field and a key of no field are kept
    as they were; an integer field reads back an int."""
    downlink, truth = pairs[0]
    odd = {
        **downlink,
        "tilt_est_deg": math.nan,
        "tilt_accel_deg": None,
        "hga_margin_predicted_deg": -math.inf,
        "q_b_ll_est": [0.0, None, math.nan, 1.0],
        "p_s_est": [1.0, 2.0],
        "p_mission_est": [None, None, None],
        "bogie_enc_deg": None,
        "imu_integration_s": "n/a",
        "site_index": 3,
        "vo_failures_in_row": 2.5,
        "not_a_field": {"kept": [1, 2]},
    }
    odd_truth = {**truth, "sun_ll_true": [math.nan] * 3, "earth_up": False}
    store.add_frames("spirit", [odd], [odd_truth])
    (got,) = store.frames("spirit", -math.inf, math.inf)
    assert got["tilt_est_deg"] is None and got["tilt_accel_deg"] is None
    assert got["hga_margin_predicted_deg"] is None
    assert got["q_b_ll_est"] == [0.0, None, None, 1.0]
    assert got["p_s_est"] == [1.0, 2.0] and got["p_mission_est"] == [None, None, None]
    assert got["bogie_enc_deg"] is None and got["imu_integration_s"] == "n/a"
    assert got["site_index"] == 3 and type(got["site_index"]) is int
    assert got["vo_failures_in_row"] == 2.5 and got["not_a_field"] == {"kept": [1, 2]}
    (got_truth,) = store.truths("spirit", -math.inf, math.inf).values()
    assert got_truth["sun_ll_true"] == [None, None, None] and got_truth["earth_up"] is False


def test_a_field_added_to_a_record_gets_its_column_in_an_old_database(
    store_url: str, pairs: FramePairs
) -> None:
    """A database from before ``hga_margin_predicted_deg`` (and the truth's ``hga_margin_deg``)
    existed: opening it adds their columns, the old rows read them as null, and so do its
    packed chunks (``server.storage.chunks``, one frame each here), which lack the channels."""
    from sqlalchemy import inspect, text

    store = Store(store_url, chunk_frames=1)
    store.add_frames("spirit", [pairs[0][0]], [pairs[0][1]])
    with store.engine.begin() as conn:
        conn.execute(text("ALTER TABLE frames DROP COLUMN hga_margin_predicted_deg"))
        conn.execute(text("ALTER TABLE truth_frames DROP COLUMN hga_margin_deg"))
        conn.execute(text("DELETE FROM frame_chunks WHERE channel = 'hga_margin_predicted_deg'"))
        conn.execute(text("DELETE FROM truth_chunks WHERE channel = 'hga_margin_deg'"))
    store.close()
    store = Store(store_url, chunk_frames=1)
    try:
        assert "hga_margin_predicted_deg" in {
            c["name"] for c in inspect(store.engine).get_columns("frames")
        }
        store.add_frames("spirit", [pairs[1][0]], [pairs[1][1]])
        old, new = store.frames("spirit", -math.inf, math.inf)
        assert old["hga_margin_predicted_deg"] is None
        assert new == pairs[1][0] and new["hga_margin_predicted_deg"] is not None
        truths = list(store.truths("spirit", -math.inf, math.inf).values())
        assert truths[0]["hga_margin_deg"] is None and truths[1] == pairs[1][1]
        for name, record in (("hga_margin_predicted_deg", 0), ("hga_margin_deg", 1)):
            got = store.channel("spirit", name, -math.inf, math.inf)
            assert got is not None
            want = [math.nan, pairs[1][record][name]]
            assert np.array_equal(got.values, want, equal_nan=True)
    finally:
        store.close()


@pytest.mark.parametrize("chunk_frames", [7, CHUNK_FRAMES])  # packed, or all in the rows
@pytest.mark.parametrize("name", ["tilt_est_deg", "q_b_ll_est_2", "site_index",
                                  "attitude_error_deg", "sun_ll_true_0"])  # fmt: skip
def test_a_channel_read_from_its_column_is_the_records_channel(
    store_url: str, pairs: FramePairs, name: str, chunk_frames: int
) -> None:
    store = Store(store_url, chunk_frames=chunk_frames)
    try:
        check_channel(store, pairs, name)
    finally:
        store.close()


def check_channel(store: Store, pairs: FramePairs, name: str) -> None:
    """Channel ``name`` read as arrays is the stored records' channel, frame for frame."""
    _stored(store, pairs)
    channel = frame_channels()[name]
    # every downlink with its truth, each time once: the values of the records written
    written = store.channel("spirit", name, -math.inf, math.inf)
    assert written is not None
    assert written.t_s.tolist() == [d["t_s"] for d, _ in pairs]
    record = 1 if channel.truth else 0
    want_written = [channel.read(pair[record]) for pair in pairs]
    want_written = [math.nan if v is None else v for v in want_written]
    assert np.array_equal(written.values, want_written, equal_nan=True)
    store.add_frames("opportunity", [pairs[0][0]], [pairs[0][1]])  # another rover: not read
    # a stretch stored again later (a rover run again from its checkpoint): out of time order
    store.add_frames("spirit", [d for d, _ in pairs[20:40]], [t for _, t in pairs[20:40]])
    # one downlink without its truth record: a truth channel has no value there
    lonely = {**pairs[-1][0], "t_s": pairs[-1][0]["t_s"] + 10.0}
    store.add_frames("spirit", [lonely], [{**pairs[-1][1], "t_s": lonely["t_s"] + 0.5}])
    t = [d["t_s"] for d, _ in pairs]
    got = store.channel("spirit", name, t[5], lonely["t_s"])
    assert got is not None
    frames = store.frames("spirit", t[5], lonely["t_s"], with_truth=True)
    unpaired = channel.truth and frames[-1]["t_s"] == lonely["t_s"]
    expected = [channel.read(f) for f in frames[: -1 if unpaired else None]]
    expected += [None] if unpaired else []
    assert got.t_s.tolist() == [f["t_s"] for f in frames]
    assert got.sol.tolist() == [f["sol"] for f in frames]
    assert got.lmst_h.tolist() == [f["lmst_h"] for f in frames]
    want = np.array([math.nan if v is None else v for v in expected], dtype=float)
    assert np.array_equal(got.values, want, equal_nan=True)
    assert np.isfinite(got.values).any()
    assert store.channel("spirit", "kinematic_ekf_position_error_m", 0.0, 1e12) is None
    empty = store.channel("spirit", name, 0.0, 1.0)
    assert empty is not None and len(empty) == 0


def test_a_database_without_chunks_has_its_channels_packed_when_opened(
    store_url: str, pairs: FramePairs, caplog: pytest.LogCaptureFixture
) -> None:
    """A database of the release before the chunks (its rows' numbers in columns only) opens
    with them packed, a chunk a transaction, and its channels read as before."""
    from sqlalchemy import text

    store = Store(store_url)  # a chunk is more frames than stored: none packed
    _stored(store, pairs)
    with store.engine.begin() as conn:  # as that release left it
        for table in ("frame_chunks", "truth_chunks"):
            conn.execute(text(f"DROP TABLE {table}"))
        for index in ("ix_frames_rover_id", "ix_truth_frames_rover_id"):
            conn.execute(text(f"DROP INDEX {index}"))
    store.close()
    with caplog.at_level(logging.INFO, logger="server.storage"):
        store = Store(store_url, chunk_frames=10)
    try:
        chunks = 2 * (len(pairs) // 10)  # the downlink's and the truth's
        assert f"({chunks} chunks so far)" in caplog.text
        got = store.channel("spirit", "tilt_est_deg", -math.inf, math.inf)
        assert got is not None and got.t_s.tolist() == [d["t_s"] for d, _ in pairs]
        want = [math.nan if d["tilt_est_deg"] is None else d["tilt_est_deg"] for d, _ in pairs]
        assert np.array_equal(got.values, want, equal_nan=True)
    finally:
        store.close()
