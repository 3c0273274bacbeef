"""Validation across the light time through the server (``server.validation.comm_context``):
the onboard time it predicts is the one the simulated link gives, behind the uplinks already
waiting; its light time is DE421's; a rover in mission mode answers ``POST
/api/sequences/validate`` with ``before-onboard`` and ``restricted-sol``, and the same upload
to a rover whose link is instant answers without them."""

from __future__ import annotations

import pickle
from collections.abc import Iterator

import pytest
from fastapi.testclient import TestClient

from sequences.comm_timing import UPLINK_HEADER_BITS, CommTiming, uplink_bits
from sequences.language import parse
from server.app import ServerConfig, create_app
from server.runtime import ROVERS, RoverRuntime
from server.validation.comm_context import SEARCH_SOLS, RoverLink, rover_link
from server.validation.context import rover_site
from sim.comm import link as sim_link
from sim.comm.link import CommLink
from sim.comm.store import HEADER_BITS
from sim.world.light_time import downlink_arrival_t_s, uplink_arrival_t_s
from sim.world.marsclock import SOL_S

# Spirit starts on sol 100 at 08:33 LMST: the uplink window opens at 09:00, the sequence is
# onboard at 09:17 (17 min of light); the morning session is open until 10:00, the next
# relay pass is at 20:54 LMST.
PLAN = (
    "SEQUENCE plan_sol100\n"
    "@ sol 100 09:05 LMST NADIR_CHECK\n"  # before it is onboard
    "DRIVE_STRAIGHT distance_m=2\n"  # its results go down in the morning session
    "@ 12:00 LMST DRIVE_STRAIGHT distance_m=2\n"  # its results wait for the evening pass
)
COMM_CODES = {"before-onboard", "no-uplink", "restricted-sol"}


def test_the_constants_are_the_links() -> None:
    assert UPLINK_HEADER_BITS == HEADER_BITS
    assert SEARCH_SOLS == sim_link.SEARCH_SOLS


@pytest.fixture(scope="module")
def runtime() -> RoverRuntime:
    return RoverRuntime(ROVERS["spirit"], comm="mission")


def _link_onboard(link: RoverLink, ahead: list[int], bits: int) -> float | None:
    """When the simulated link (``sim.comm.link``) has ``bits`` onboard, accepted at the
    validation moment behind uplinks of ``ahead`` bits."""
    sim = CommLink(link.lat_deg, link.lon_east_deg, link.plan, link.t_s)
    for i, size in enumerate(ahead):
        sim.accept("sequence", i + 1, size, link.t_s)
    ours = sim.accept("sequence", 99, bits, link.t_s)
    progress = sim.advance(link.t_s + 2 * SOL_S)
    return next((u.arrival_t_s for u in progress.onboard if u is ours), None)


def test_the_onboard_time_is_the_simulated_links(runtime: RoverRuntime) -> None:
    link = rover_link(runtime)
    assert link is not None and link.waiting == ()
    bits = uplink_bits(parse(PLAN))
    timing = link.timing()
    assert timing is not None
    predicted = timing.onboard(bits)
    assert predicted is not None
    assert predicted[1] == pytest.approx(_link_onboard(link, [], bits), abs=0.01)
    # behind 3 Mbit waiting on the ground (25 minutes of the window)
    behind = RoverLink(**{**link.__dict__, "waiting": ((link.t_s, 3_000_000),)})
    later = behind.timing()
    assert later is not None
    onboard = later.onboard(bits)
    assert onboard is not None and onboard[1] > predicted[1] + 1400.0
    assert onboard[1] == pytest.approx(_link_onboard(link, [3_000_000], bits), abs=0.01)
    # behind an uplink no window can hold: it fails on the ground, this one goes as if alone
    stuck = RoverLink(**{**link.__dict__, "waiting": ((link.t_s, 8_000_000),)})
    unblocked = stuck.timing()
    assert unblocked is not None
    alone = unblocked.onboard(bits)
    assert alone is not None and alone[1] == pytest.approx(predicted[1], abs=0.01)
    assert alone[1] == pytest.approx(_link_onboard(link, [8_000_000], bits), abs=0.01)


def test_the_light_time_is_de421s(runtime: RoverRuntime) -> None:
    link = rover_link(runtime)
    assert link is not None
    timing = link.timing()
    assert timing is not None
    for k in range(40):
        t = link.t_s + k * SOL_S / 3.7
        assert timing.downlink_arrival_t_s(t) == pytest.approx(downlink_arrival_t_s(t), abs=0.01)
        assert timing.uplink_arrival_t_s(t) == pytest.approx(uplink_arrival_t_s(t), abs=0.01)
    # the windows reach 3 sols past the uplink search
    assert timing.horizon_t_s == pytest.approx(link.t_s + (SEARCH_SOLS + 3) * SOL_S)
    assert {w.kind for w in timing.windows} == {"uplink", "relay", "dte"}


def test_the_site_carries_the_link_in_mission_mode_only(runtime: RoverRuntime) -> None:
    assert rover_site(RoverRuntime(ROVERS["spirit"])).comm is None
    site = rover_site(runtime)
    assert site.comm is not None and site.comm.t_s == site.start_t_s == runtime.t_s
    again = pickle.loads(pickle.dumps(site))  # to a validation process
    assert isinstance(again.context().comm, CommTiming)


def _client(comm: str) -> TestClient:
    config = ServerConfig(database_url="sqlite://", start_clocks=False, comm=comm)
    return TestClient(create_app(config))


@pytest.fixture(scope="module")
def clients() -> Iterator[tuple[TestClient, TestClient]]:
    """A server whose rovers' links cross the light time, and one whose links are instant
    (validating in a worker process each: the link's timing crosses to it)."""
    with _client("mission") as mission, _client("instant") as instant:
        yield mission, instant


def test_the_server_warns_across_the_light_time(
    clients: tuple[TestClient, TestClient], runtime: RoverRuntime
) -> None:
    mission, instant = clients
    answer = mission.post("/api/sequences/validate?rover=spirit", content=PLAN).json()
    assert answer["valid"] is True
    found = [(w["line"], w["code"]) for w in answer["warnings"] if w["code"] in COMM_CODES]
    assert found == [(2, "before-onboard"), (4, "restricted-sol")]
    early, late = (w["message"] for w in answer["warnings"] if w["code"] in COMM_CODES)
    context = rover_site(runtime).context()
    assert context.comm is not None
    onboard = context.comm.onboard(uplink_bits(parse(PLAN)))
    assert onboard is not None
    assert early.startswith("sol 100 09:05 LMST comes before the sequence can be onboard")
    assert f"({context.clock(onboard[1])}: radiated by" in early
    assert late.startswith("sol 100's plan cannot build on this drive: its results reach")
    assert "relay pass" in late and "after the 18:00 LMST planning time (restricted sol)" in late
    # the same upload to a rover whose link is instant: onboard at once, nothing to say
    answer = instant.post("/api/sequences/validate?rover=spirit", content=PLAN).json()
    assert answer["valid"] is True
    assert [w["code"] for w in answer["warnings"] if w["code"] in COMM_CODES] == []
