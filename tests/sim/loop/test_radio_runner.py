"""The radio + terrain-matching EKF beside SAPP in a rover session (the fusion issue,
item 3; ``sim.loop.side.radio``), and the onboard orbital maps it uses
(``sim.sensors.landmarks``)."""

from __future__ import annotations

from datetime import UTC, datetime

import numpy as np
import pytest

from estimation.sapp.aqf import AttitudeQuality
from sequences import commands as cmd
from sim.errors import InputError
from sim.loop.session import RoverSession
from sim.loop.side.radio import RadioEkfRunner
from sim.scenarios.radio import metres_per_radian
from sim.sensors.landmarks import LandmarkTiles, OrbitalDem, ground_height_m, matching_band
from sim.world.sites import make_terrain

# The relay orbiter (sim.sensors.orbiter, ORBIT_EPOCH) culminates at 51° over Gusev 7 min
# after this; its next pass there is 12.6 h later.
START = datetime(2004, 4, 14, 15, 0, tzinfo=UTC)


def _runner(session: RoverSession) -> RadioEkfRunner:
    (runner,) = [r for r in session.side.runners if isinstance(r, RadioEkfRunner)]
    return runner


def _gusev() -> RoverSession:
    return RoverSession("gusev", 5, START, estimators=("sapp", "radio_ekf"), frame_every_s=1.0)


@pytest.fixture(scope="module")
def gusev_drive() -> RoverSession:
    session = _gusev()
    session.nate.load_attitude(session.q_b_ll_true(), AttitudeQuality.FINE)
    session.execute(cmd.Wait(duration_s=30.0))
    session.execute(cmd.DriveStraight(distance_m=4.0))
    return session


def test_it_starts_at_the_first_drive_and_estimates_position_only(
    gusev_drive: RoverSession,
) -> None:
    frames, truths = gusev_drive.downlinks, gusev_drive.truths
    assert all(f.estimators == {} for f in frames if f.command.startswith("WAIT"))
    during = [f.estimators["radio_ekf"] for f in frames if f.command.startswith("DRIVE")]
    assert len(during) > 100  # a frame a second through the drive
    assert all(e["q_b_ll"] is None for e in during)
    scores = [t.estimators["radio_ekf"] for f, t in zip(frames, truths, strict=True)
              if f.command.startswith("DRIVE")]  # fmt: skip
    assert all(e["attitude_error_deg"] is None for e in scores)
    last = {**frames[-1].estimators["radio_ekf"], **truths[-1].estimators["radio_ekf"]}
    # landmarks of a 0.25 m map every second and 1 m ranges: decimetres (SAPP: ~1-3 %)
    assert last["position_error_m"] < 0.3
    assert last["p_mission"][0] == pytest.approx(truths[-1].p_mission_true[0], abs=0.3)
    runner = _runner(gusev_drive)
    assert runner.ekf is not None
    np.testing.assert_allclose(runner.ekf.estimate()[0][2:], 0.0, atol=1e-4)  # parked: v = 0


def test_a_pass_at_rest_brings_ranges_and_no_pass_changes_nothing(
    gusev_drive: RoverSession,
) -> None:
    session = _gusev()  # a copy through its checkpoint state: the fixture stays as it was
    session.load_state(gusev_drive.state())
    runner = _runner(session)
    assert runner.ekf is not None
    sigma_before = runner.ekf.horizontal_sigma_m()
    session.execute(cmd.Wait(duration_s=900.0))  # the rest of the pass
    assert runner.last_seen_t_s > session.downlinks[-1].t_s - 900.0
    assert runner.ekf.horizontal_sigma_m() < sigma_before  # the ranges were used
    held = session.downlinks[-1].estimators["radio_ekf"]["p_mission"]
    session.execute(cmd.Wait(duration_s=3600.0))  # the orbiter is below the mask
    assert session.downlinks[-1].estimators["radio_ekf"]["p_mission"] == held


def test_landmark_tiles_are_the_same_whenever_built_and_cover_the_reach() -> None:
    terrain = make_terrain("gusev", 5)
    tiles = LandmarkTiles(terrain, 0.25, seed=5)
    here = np.array([10.0, -30.0, 0.0])
    first = tiles.around(here, 40.0)
    again = LandmarkTiles(terrain, 0.25, seed=5)  # built again, from the seed
    second = again.around(here, 40.0)
    np.testing.assert_array_equal(first.true_s_m, second.true_s_m)
    np.testing.assert_array_equal(first.map_s_m, second.map_s_m)
    d = first.true_s_m[:, :2] - here[:2]
    # every 8 m cell within reach has its landmark: the reach's square holds ~(80/8)² of them
    assert np.count_nonzero(np.all(np.abs(d) <= 40.0, axis=1)) >= 90
    np.testing.assert_allclose(
        -first.true_s_m[:, 2], ground_height_m(terrain, first.true_s_m[:, 0], first.true_s_m[:, 1])
    )


def test_orbital_dem_is_the_ground_at_its_posts_and_bilinear_between() -> None:
    terrain = make_terrain("gusev", 5)
    dem = OrbitalDem(terrain, post_m=1.0)
    for n, e in [(3.0, -7.0), (-64.0, 63.0), (130.0, 2.0)]:
        assert dem.height_m(n, e) == pytest.approx(
            float(ground_height_m(terrain, np.array(n), np.array(e))), abs=1e-9
        )
    corners = [dem.height_m(3.0 + i, -7.0 + j) for i in (0, 1) for j in (0, 1)]
    assert dem.height_m(3.5, -6.5) == pytest.approx(np.mean(corners), abs=1e-12)


def test_site_metres_follow_the_ellipsoid() -> None:
    """At the equator: the meridian's radius of curvature a(1 - e²) and the equatorial
    radius a, from the IAU radii (3396.19 km equatorial, 3376.20 km polar)."""
    a, b = 3_396_190.0, 3_376_200.0
    m_per_lat, m_per_lon = metres_per_radian(0.0)
    assert m_per_lat == pytest.approx(b**2 / a, rel=1e-4)  # a(1 - e²) = b²/a
    assert m_per_lon == pytest.approx(a, rel=1e-4)


@pytest.mark.parametrize(
    ("resolution_m", "sigma_m", "band"),
    [
        (0.25, 0.3, (8.0, 20.0)),  # converged: as near as pairs remain
        (0.25, 10.0, (30.0, 60.0)),  # Jiang, Li et al. 2014's 10 m start: three sigmas out
        (0.25, 500.0, (50.0, 100.0)),  # lost: capped
        (10.0, 10.0, (50.0, 200.0)),  # a 10 m map: 5 to 20 resolutions
    ],
)
def test_the_matching_band_moves_out_with_the_position_uncertainty(
    resolution_m: float, sigma_m: float, band: tuple[float, float]
) -> None:
    assert matching_band(resolution_m, sigma_m) == pytest.approx(band)


def test_a_failing_estimator_beside_sapp_stops_without_refusing_the_drive(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    session = RoverSession("flat", 3, START, estimators=("sapp", "radio_ekf"))
    runner = _runner(session)

    def broken_map(p_s_m: np.ndarray, reach_m: float) -> None:
        raise InputError("tile_cells", "a broken map, for the test")

    monkeypatch.setattr(runner.landmarks, "around", broken_map)
    report = session.execute(cmd.DriveStraight(distance_m=1.0))
    assert report.status == "completed"
    assert report.details["distance_truth_m"] > 0.9
    assert any(e.text.startswith("radio_ekf stopped: tile_cells") for e in report.events)
    assert session.side.runners == [] and session.downlinks[-1].estimators == {}


def test_parked_frames_use_no_range_from_after_their_own_time() -> None:
    """The simulator rests in chunks and the frames inside a chunk come after it: each
    frame's estimate must still be the one of its own time (ranges up to then only)."""
    session = RoverSession("gusev", 5, START, estimators=("sapp", "radio_ekf"))
    session.nate.load_attitude(session.q_b_ll_true(), AttitudeQuality.FINE)
    session.execute(cmd.DriveStraight(distance_m=0.5))
    session.execute(cmd.ArticulateStart())  # 8 Hz frames at rest, in 600 s chunks
    first = len(session.downlinks)
    session.execute(cmd.Wait(duration_s=300.0))  # the orbiter is up (START + 7 min: 51°)
    positions = [tuple(f.estimators["radio_ekf"]["p_mission"]) for f in session.downlinks[first:]]
    assert len(set(positions)) > 20  # a range every 10 s of the pass, each in its own frame
