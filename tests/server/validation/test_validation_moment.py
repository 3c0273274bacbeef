"""The validation context describes one moment, the one the ground has seen: the rover's
last downlink record and the played-out clock, never the live session, which can be a whole
command ahead of both (issue 21: ``rover_site`` read ``session.nate`` and ``session.sim``
without the runtime's lock)."""

from __future__ import annotations

import math

from sequences import commands as cmd
from server.runtime import ROVERS, RoverRuntime
from server.validation.context import MIN_SUN_ELEVATION_RAD, rover_site
from sim.world.sites import site


def test_a_command_the_session_ran_but_the_ground_has_not_seen_does_not_show() -> None:
    runtime = RoverRuntime(ROVERS["spirit"])
    before = rover_site(runtime)
    assert before.aqf == "Unknown" and not before.articulating
    # The session runs ahead of the played-out clock: nothing is published yet.
    runtime.session.execute(cmd.SetParam("min_sun_elevation_rad", 0.2))
    runtime.session.execute(cmd.ArticulateStart())
    runtime.session.execute(cmd.Wait(2.0))  # a frame that reports the mode
    assert runtime.session.nate.mode.value == "Articulate"
    ahead = rover_site(runtime)
    assert not ahead.articulating  # the ground has not seen the rover articulate
    assert ahead.min_sun_elevation_rad == MIN_SUN_ELEVATION_RAD  # nor the parameter set
    assert ahead.start_t_s == runtime.t_s
    # Once the frames are played out, the ground knows both.
    runtime._publish(runtime.session.take_frames())
    seen = rover_site(runtime)
    assert seen.articulating and seen.min_sun_elevation_rad == 0.2
    assert seen.start_t_s == runtime.t_s == runtime.last_frame["t_s"]  # type: ignore[index]


def test_the_site_is_the_landing_sites_published_coordinates() -> None:
    runtime = RoverRuntime(ROVERS["opportunity"])
    landing = site(ROVERS["opportunity"].site)
    got = rover_site(runtime)
    assert got.lat_rad == math.radians(landing.lat_deg)
    assert got.lon_east_rad == math.radians(landing.lon_east_deg)
