"""A rehearsal's inputs are what the ground knows (``server.rehearsal.gather``): the last
downlink record that came down, the tables the rover's events reported, the ground's map
around the rover, and the same from a database alone."""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from server.app import Server, ServerConfig, create_app, data_dir_url
from server.rehearsal.gather import (
    CROP_HALF_M,
    NoReportError,
    crop_map,
    runtime_inputs,
    stored_inputs,
)
from server.runtime import RoverRuntime
from server.terrain.feed import ground_feed
from sim.rehearsal.inputs import RehearsalInputs

SETUP = (
    "SEQUENCE setup\n"
    "SET_PARAM param=vo.rig value=1024\n"
    "SET_PARAM param=mobility.tilt_limit_rad value=0.4\n"
    "KEEPOUT_ADD zone=rock x_m=2.5 y_m=0.0 radius_m=0.3\n"
    'KEEPOUT_ADD zone=dune polygon_m="-3,-1 -2,-1 -2.5,1"\n'
    "DRIVE_STRAIGHT distance_m=4\n"
)
REHEARSED = "SEQUENCE next\nTURN_IN_PLACE angle_deg=90\n"


def play_out(runtime: RoverRuntime, sequence_id: int, text: str) -> None:
    """Queue ``text`` and run the clock flat out until it is over and played out."""
    from sequences.language import parse_any

    runtime.enqueue(sequence_id, parse_any(text).sequence)
    runtime.set_clock(speed=math.inf)
    for _ in range(400):
        runtime._tick(0.05)
        if not runtime.queued_ids() and not runtime._playout:
            return
    raise AssertionError("the sequence did not play out")


def inputs_equal(a: RehearsalInputs, b: RehearsalInputs) -> bool:
    """Field by field, the map's arrays bit for bit."""
    ma, mb = a.ground_map, b.ground_map
    arrays = ("height_m", "sigma_m", "albedo", "imaged")
    return (
        a.start == b.start
        and a.sequence_text == b.sequence_text
        and a.priors == b.priors
        and (ma.north0_m, ma.east0_m, ma.cell_m) == (mb.north0_m, mb.east0_m, mb.cell_m)
        and all(np.array_equal(getattr(ma, k), getattr(mb, k)) for k in arrays)
    )


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Server]:
    url = data_dir_url(Path(tmp_path_factory.mktemp("gather")))
    config = ServerConfig(database_url=url, start_clocks=False, validation_processes=0)
    app = create_app(config)
    found: Server = app.state.server
    found.writer.start()
    try:
        sequence_id = found.store.add_sequence("spirit", "setup", SETUP, "text", "queued", [],
                                               [], [])  # fmt: skip
        play_out(found.rovers["spirit"], sequence_id, SETUP)
        found.writer.flush()
        yield found
    finally:
        found.writer.stop()
        found.store.close()


def test_the_inputs_are_what_the_last_frame_and_the_events_say(server: Server) -> None:
    runtime = server.rovers["spirit"]
    inputs = runtime_inputs(runtime, server.store, REHEARSED)
    start, last = inputs.start, runtime.last_frame
    assert last is not None
    # the rover's own tables, which the ground knows only through its events
    onboard = runtime.session.loop.protection
    assert {z.name: z for z in start.keepout_zones} == onboard.zones
    assert onboard.fault is not None and start.mobility_fault == onboard.fault.reason
    assert start.params["vo.rig"] == 1024.0 and start.vo_rig == 1024
    assert start.params["mobility.tilt_limit_rad"] == 0.4
    # the frame's figures, as it reported them
    assert start.t_s == last["t_s"] and start.aqf == last["aqf"]
    assert start.p_s_est == tuple(last["p_s_est"]) and start.q_b_ll_est == tuple(last["q_b_ll_est"])
    assert start.p_mission_est == tuple(last["p_mission_est"])
    assert start.imu_integration_s == last["imu_integration_s"]
    assert start.position_sigma_m == last["position_sigma_m"] > 0.0
    assert (start.site, start.mission) == ("gusev", "spirit")
    assert inputs.sequence_text == REHEARSED
    # the drive halted short of its 4 m (at the rock): the rover moved, not all the way
    assert 0.3 < math.hypot(start.p_mission_est[0], start.p_mission_est[1]) < 2.5


def test_the_map_is_the_rovers_ground_map_around_it(server: Server) -> None:
    runtime = server.rovers["spirit"]
    inputs = runtime_inputs(runtime, server.store, REHEARSED)
    full = ground_feed(runtime, server.store).service.ground_map()
    got = inputs.ground_map
    i0 = round((got.north0_m - full.north0_m) / full.cell_m)
    j0 = round((got.east0_m - full.east0_m) / full.cell_m)
    ny, nx = got.height_m.shape
    for name in ("height_m", "sigma_m", "albedo", "imaged"):
        assert np.array_equal(getattr(got, name), getattr(full, name)[i0 : i0 + ny, j0 : j0 + nx])
    # it reaches CROP_HALF_M around the rover, or the map's edge
    n, e = inputs.start.p_mission_est[0], inputs.start.p_mission_est[1]
    last_row_m = full.north0_m + (full.shape[0] - 1) * full.cell_m
    assert got.north0_m <= max(full.north0_m, n - CROP_HALF_M) + 1e-9
    assert got.north0_m + (ny - 1) * got.cell_m >= min(last_row_m, n + CROP_HALF_M) - 1e-9
    assert got.east0_m <= max(full.east0_m, e - CROP_HALF_M) + 1e-9


def test_a_database_alone_gives_the_same_inputs(server: Server) -> None:
    runtime = server.rovers["spirit"]
    live = runtime_inputs(runtime, server.store, REHEARSED)
    stored = stored_inputs(server.store, "spirit", REHEARSED)
    assert inputs_equal(live, stored)
    with pytest.raises(NoReportError, match="opportunity"):
        stored_inputs(server.store, "opportunity", REHEARSED)


def test_a_crop_outside_the_map_takes_its_nearest_edge(server: Server) -> None:
    full = ground_feed(server.rovers["spirit"], server.store).service.ground_map()
    far = crop_map(full, 1e4, -1e4, 5.0)
    assert far.height_m.shape[0] >= 2 and far.height_m.shape[1] >= 2
    last_row = full.north0_m + (full.shape[0] - 1) * full.cell_m
    assert far.north0_m + (far.height_m.shape[0] - 1) * far.cell_m == pytest.approx(last_row)
    assert far.east0_m == full.east0_m
    small = crop_map(full, 0.0, 0.0, 1.0)  # 1 m around: 2 / cell + 1 cells a side, at most
    assert small.height_m.shape[0] <= math.ceil(2.0 / full.cell_m) + 2
    with pytest.raises(ValueError, match="half_m"):
        crop_map(full, 0.0, 0.0, -1.0)
