"""Across light time an image waits in the rover's store like any product and comes down with
a pass: the ground has nothing of it while it waits, and stores it when it arrives, never
earlier than it was sent in a downlink window plus the light time."""

from __future__ import annotations

import math
from collections.abc import Iterator

import pytest

from server.state import Server, ServerConfig
from server.storage.images import list_images
from sim.comm.windows import comm_windows
from sim.world.light_time import one_way_light_time_s
from sim.world.marsclock import get_mission
from tests.server.comm.conftest import tick_until, upload


@pytest.fixture
def server() -> Iterator[Server]:
    server = Server.open(ServerConfig(database_url="sqlite://", start_clocks=False, comm="mission"))
    server.start()
    try:
        yield server
    finally:
        server.stop()


def test_an_image_arrives_only_after_a_pass(server: Server) -> None:
    runtime = server.rovers["spirit"]
    link = runtime.comm.mission
    assert link is not None
    upload(server, "SEQUENCE look\nNAVCAM_STEREO az_deg=30 el_deg=-35\n")
    runtime.set_clock(speed=math.inf)

    def held() -> list[float]:
        store = link.link.store
        return [p.t_s for q in store._queues.values() for p in q if p.kind == "image"]

    tick_until(runtime, lambda: held() or list_images(server.store, "spirit")[1],
               "the pair made onboard")  # fmt: skip
    made = held()
    assert len(made) == 1, "the pair waits in the store"
    assert list_images(server.store, "spirit")[1] == 0  # nothing of it on the ground yet
    tick_until(runtime, lambda: list_images(server.store, "spirit")[1], "the pair on the ground")
    (image,), _ = list_images(server.store, "spirit")
    assert image["t_s"] == made[0]
    received = image["received_t_s"]
    assert received is not None
    owlt = float(one_way_light_time_s(image["t_s"]))
    assert received >= image["t_s"] + owlt - 1e-3
    # sent in a downlink window (relay or DTE) that was open before it arrived
    site = get_mission("spirit")
    windows = comm_windows(site.lat_deg, site.lon_east_deg, runtime.comm.plan, image["t_s"],
                           received)  # fmt: skip
    down = [w for w in windows if w.kind in ("relay", "dte") and w.end_t_s >= image["t_s"]]
    assert any(w.start_t_s + owlt - 1e-3 <= received for w in down)
    passes = link.ground_view()["passes"]
    assert any(p["first_received_t_s"] <= received <= p["last_received_t_s"] for p in passes)
