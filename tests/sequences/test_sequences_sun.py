"""The validator warns, on the line, when a command that images the sun would start with
the sun below what NATE accepts (issue 14, item 8): a sequence queued at 23:41 LMST failed
at run time with "the sun is -76.5 deg high" and the validator had said nothing.

The predicted elevation is checked against Mars24 (the GISS algorithm, ``sim.world.marsclock``:
an outside reference, not the DE421 samples the validator uses) and against the refusal of
the flight software itself in a rover session at the same moment.
"""

from __future__ import annotations

import math
import re

import pytest

from estimation.sapp.nate import NateParams
from sequences.commands import SetParam, Sunfind, Wait
from sequences.validate import CODES, ValidationContext, ValidationResult, validate
from server.runtime import ROVERS, RoverRuntime
from server.validation.context import rover_site, site_context
from sim.loop.session import RoverSession
from sim.world.marsclock import get_mission, mars24, t_s_for_sol_lmst, t_s_to_utc, utc_to_t_s
from sim.world.sites import site

SPIRIT = site("gusev")
SOL = 100
START_T_S = t_s_for_sol_lmst("spirit", SOL - 1, 12.0)  # the sol before, at noon
DAWN_T_S = t_s_for_sol_lmst("spirit", SOL, 6.75)  # the sun up, but only 2 deg
SUN_COMMANDS = (
    "SUNFIND",
    "SUNGAZE",
    "SUNCHECK",
    "GET_COARSE_ATTITUDE",
    "GET_FINE_ATTITUDE",
    "SUNCHECK_SUNGAZE",
)
MIN_SUN_DEG = math.degrees(NateParams().min_sun_elevation_rad)


def _spirit(start_t_s: float = START_T_S) -> ValidationContext:
    return site_context(
        "spirit", math.radians(SPIRIT.lat_deg), math.radians(SPIRIT.lon_east_deg), start_t_s
    )


def _sun_warnings(result: ValidationResult) -> list[tuple[int, int, str]]:
    return [(d.line, d.column, d.message) for d in result.warnings if d.code == "sun-too-low"]


def _elevation(message: str) -> float:
    found = re.match(r"the sun is (-?\d+\.\d) deg high", message)
    assert found, message
    return float(found.group(1))


@pytest.mark.parametrize("command", SUN_COMMANDS)
def test_a_sun_command_at_night_warns_on_its_line_and_at_noon_does_not(command: str) -> None:
    context = _spirit()
    night = validate(f"SEQUENCE night\nPLANT_SITE\n@ sol {SOL} 23:41 LMST  {command}\n", context)
    ((line, column, message),) = _sun_warnings(night)
    assert (line, column) == (3, 23)  # the command's keyword, after the tag
    assert f"sol {SOL} 23:41 LMST" in message and f"{command} would be refused" in message
    assert f"below the {MIN_SUN_DEG:.1f} deg NATE needs" in message
    assert _elevation(message) < -60.0  # the issue's -76.5 was at another season
    noon = validate(f"SEQUENCE noon\n@ sol {SOL} 12:00 LMST  {command}\n", context)
    assert _sun_warnings(noon) == []


def test_commands_that_need_no_sun_do_not_warn_at_night() -> None:
    text = f"@ sol {SOL} 23:41 LMST NADIR_UPDATE\nGET_TILT_ATTITUDE\nGYROCOMPASS\n"
    assert _sun_warnings(validate(text, _spirit())) == []


def test_the_threshold_is_the_flight_softwares_and_follows_set_param() -> None:
    assert CODES["sun-too-low"] == "warning"
    assert _spirit().min_sun_elevation_deg == MIN_SUN_DEG  # from NateParams, not a copy
    # 06:45 LMST: the sun has risen, but is below NATE's minimum (not the horizon)
    dawn = validate("SUNFIND\n", _spirit(DAWN_T_S))
    ((_, _, message),) = _sun_warnings(dawn)
    assert 0.0 < _elevation(message) < MIN_SUN_DEG
    lowered = "SET_PARAM param=min_sun_elevation_rad value=0.02\nSUNFIND\n"
    assert _sun_warnings(validate(lowered, _spirit(DAWN_T_S))) == []


def test_without_a_sun_model_the_validator_does_not_guess() -> None:
    context = _spirit()
    blind = type(context)(**{**context.__dict__, "sun_elevation_deg": None})
    assert _sun_warnings(validate(f"@ sol {SOL} 23:41 LMST SUNFIND\n", blind)) == []
    assert _sun_warnings(validate(f"@ sol {SOL} 23:41 LMST SUNFIND\n")) == []


@pytest.mark.parametrize("lmst", ["23:41", "06:00", "17:50", "03:10"])
def test_the_predicted_elevation_agrees_with_mars24(lmst: str) -> None:
    """Mars24 (an independent, published algorithm) at the instant the command starts."""
    hours, minutes = (int(x) for x in lmst.split(":"))
    t_s = t_s_for_sol_lmst("spirit", SOL, hours + minutes / 60.0)
    context = _spirit()
    assert context.sun_elevation_deg is not None
    predicted = context.sun_elevation_deg(t_s)
    lon_west = get_mission("spirit").lon_west_deg
    reference = mars24(t_s_to_utc(t_s), SPIRIT.lat_deg, lon_west).sun_elev_deg
    assert predicted == pytest.approx(reference, abs=0.3)  # deg: Mars24's own accuracy
    result = validate(f"@ sol {SOL} {lmst} LMST SUNGAZE\n", context)
    warned = _sun_warnings(result)
    assert bool(warned) == (predicted < MIN_SUN_DEG)
    if warned:
        assert _elevation(warned[0][2]) == pytest.approx(reference, abs=0.35)


def test_the_rover_refuses_what_the_validator_warned_about() -> None:
    """The flight software in a session at the warned moment refuses the command and
    names the elevation the validator predicted (IVP against DE421: within 0.2 deg)."""
    spec = ROVERS["spirit"]
    text = "SEQUENCE late\n@ 23:41 LMST SUNFIND\n"
    start = utc_to_t_s(spec.start_utc)
    ((_, _, message),) = _sun_warnings(validate(text, _spirit(start)))
    session = RoverSession(spec.site, spec.seed, spec.start_utc)
    # the start of the sol after, at 23:41 LMST, as the validator predicted the tag
    sol = int(re.search(r"at sol (\d+) 23:41", message).group(1))  # type: ignore[union-attr]
    wait_s = t_s_for_sol_lmst("spirit", sol, 23 + 41 / 60) - session.sim.t_s
    session.execute(Wait(duration_s=wait_s))
    report = session.execute(Sunfind())
    assert report.status == "refused"
    said = re.search(r"the sun is (-?\d+\.\d) deg high", report.reason or "")
    assert said and float(said.group(1)) == pytest.approx(_elevation(message), abs=0.2)
    # a rover whose parameter was changed is predicted with its own threshold
    # (as the ground knows it: once the rover's frames reporting it are played out)
    runtime = RoverRuntime(spec, session)
    session.execute(SetParam(param="min_sun_elevation_rad", value=-1.5))
    runtime._publish(session.take_frames())
    site_now = rover_site(runtime)
    assert site_now.min_sun_elevation_rad == -1.5
    assert _sun_warnings(validate("SUNFIND\n", site_now.context())) == []
