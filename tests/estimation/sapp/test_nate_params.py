"""NATE's parameters (SET_PARAM) and the commands it refuses, on the simulated rover: a
refused command changes nothing (Ali et al. 2005 sec. 2.2; the fixtures and helpers are
those of tests/estimation/sapp/test_nate_camera.py)."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest

from estimation.sapp.aqf import AttitudeQuality as Aqf
from estimation.sapp.nate import (
    CONTROL_DT_S,
)
from tests.estimation.sapp.test_nate_camera import imu, q_true, rover, state, turned


def test_set_param_by_dotted_path_changes_that_field_only_and_is_used() -> None:
    sim, nate = rover()
    p0 = nate.params
    nate.set_param("sunfind.image_spacing_s", 5.0)
    nate.set_param("sungaze.early_stop", False)
    nate.set_param("nadir.min_valid_samples", 30)
    nate.set_param("min_sun_elevation_rad", math.radians(10.0))
    p = nate.params
    assert p.sunfind.image_spacing_s == 5.0 and p.sungaze.early_stop is False
    assert p.nadir.min_valid_samples == 30 and isinstance(p.nadir.min_valid_samples, int)
    assert p.min_sun_elevation_rad == math.radians(10.0)
    assert p.sunfind.confirm_spacing_s == p0.sunfind.confirm_spacing_s
    assert p.sungaze.timer_s == p0.sungaze.timer_s and p.suncheck == p0.suncheck
    # the new spacing is what the search waits between images
    nate.load_attitude(turned(q_true(sim), 90.0), Aqf.TILT_ONLY)
    nate.sunfind()
    req = nate.camera_request
    assert req is not None and nate.wait_hint_s == 0.0
    samples = sim.rest(CONTROL_DT_S)
    nate.step(imu(samples), image=sim.pancam_sun_image(req.az_rad, req.el_rad).image)
    assert nate.camera_request is not None
    assert nate.camera_request.purpose == "search 1"
    assert nate.wait_hint_s == pytest.approx(5.0)


@pytest.mark.parametrize(
    ("path", "value"),
    [
        ("no_such", 1.0),
        ("sungaze.no_such", 1.0),
        ("sungaze", 1.0),
        ("", 1.0),
        ("sungaze.timer_s", -1.0),
        ("sungaze.timer_s", math.nan),
        ("sungaze.timer_s", math.inf),
        ("sungaze.timer_s", "600"),
        ("sungaze.timer_s", True),
        ("sungaze.timer_s", None),
        ("sungaze.interval_s", 900.0),
        ("sungaze.early_stop", 1),
        ("suncheck.tolerance_rad", 4.0),
        ("nadir.min_valid_samples", 2.5),
        ("min_sun_elevation_rad", 2.0),
        ("gyrocompass.gyro_bias_sigma_rad_s", -1.0),
        ("fine_to_coarse_s", 0.0),
    ],
)
def test_set_param_refuses_bad_names_and_values_and_changes_nothing(
    path: str, value: object
) -> None:
    _, nate = rover()
    before = nate.params
    with pytest.raises(ValueError) as info:
        nate.set_param(path, value)
    if path:
        assert path in str(info.value)
    assert nate.params == before


def test_set_param_is_refused_outside_idle() -> None:
    sim, nate = rover()
    nate.load_attitude(q_true(sim), Aqf.TILT_ONLY)
    nate.sunfind()
    before = state(nate)
    with pytest.raises(ValueError, match="set_param: refused in mode Sunfind"):
        nate.set_param("sungaze.timer_s", 300.0)
    assert state(nate) == before


def test_out_of_range_camera_commands_change_nothing() -> None:
    sim, nate = rover()
    nate.load_attitude(turned(q_true(sim), 3.0), Aqf.COARSE)
    bad: list[tuple[Callable[[], object], str]] = [
        (lambda: nate.suncheck(tolerance_deg=200), "tolerance_deg"),
        (lambda: nate.suncheck(tolerance_deg=0.0), "tolerance_deg"),
        (lambda: nate.suncheck(tolerance_deg=math.nan), "tolerance_deg"),
        (lambda: nate.gyrocompass(duration_s=-1), "duration_s"),
        (lambda: nate.gyrocompass(duration_s=math.inf), "duration_s"),
        (lambda: nate.sungaze(use_gravity="yes"), "use_gravity"),  # type: ignore[arg-type]
        (lambda: nate.sungaze(use_gravity=1), "use_gravity"),  # type: ignore[arg-type]
    ]
    for command, name in bad:
        before = state(nate)
        with pytest.raises(ValueError, match=name):
            command()
        assert state(nate) == before
    # a camera mode running: every other command is refused, the procedure untouched
    nate.suncheck()
    for command_name in ("sunfind", "sungaze", "suncheck", "gyrocompass", "get_fine_attitude"):
        before = state(nate)
        with pytest.raises(ValueError, match="refused in mode Suncheck"):
            getattr(nate, command_name)()
        assert state(nate) == before


def test_images_out_of_turn_are_refused() -> None:
    sim, nate = rover()
    nate.load_attitude(q_true(sim), Aqf.COARSE)
    image = sim.pancam_sun_image(0.0, 0.5).image
    before = state(nate)
    with pytest.raises(ValueError, match="no camera mode"):
        nate.step(imu(sim.rest(1.0)), image=image)
    assert nate.q_b_ll.tolist() == before[0] and nate.t_s == before[7]  # nothing happened
    nate.sunfind()
    nate.step(imu(sim.rest(CONTROL_DT_S)), image=image)  # search 0: now is fine
    assert nate.wait_hint_s == pytest.approx(10.0)  # the search's image spacing
    before = state(nate)
    with pytest.raises(ValueError, match="before the requested"):
        nate.step(imu(sim.rest(1.0)), image=image)  # 9 s early
    after = state(nate)
    assert after[:7] == before[:7] and after[8:] == before[8:]  # all but the clock: below


def test_an_early_image_refused_leaves_the_clock_alone() -> None:
    sim, nate = rover()
    nate.load_attitude(q_true(sim), Aqf.COARSE)
    nate.sunfind()
    req = nate.camera_request
    assert req is not None
    nate.step(imu(sim.rest(CONTROL_DT_S)), image=sim.pancam_sun_image(req.az_rad, req.el_rad).image)
    t_before = nate.t_s
    with pytest.raises(ValueError, match="before the requested"):
        nate.step(imu(sim.rest(1.0)), image=np.zeros((1024, 1024)))  # 9 s early
    assert nate.t_s == t_before


def test_set_param_reaches_the_sunfind_search_thresholds() -> None:
    _, nate = rover()
    nate.set_param("sunfind.search.elevation_tolerance_rad", math.radians(3.0))
    assert nate.params.sunfind.search.elevation_tolerance_rad == math.radians(3.0)


def test_set_param_refuses_an_infinite_whole_number() -> None:
    _, nate = rover()
    with pytest.raises(ValueError, match=r"nadir\.min_valid_samples"):
        nate.set_param("nadir.min_valid_samples", math.inf)


@pytest.mark.parametrize("command", ["suncheck", "gyrocompass"])
def test_camera_commands_refuse_a_bool_as_a_number(command: str) -> None:
    sim, nate = rover()
    nate.load_attitude(q_true(sim), Aqf.COARSE)
    with pytest.raises(ValueError):
        if command == "suncheck":
            nate.suncheck(tolerance_deg=True)
        else:
            nate.gyrocompass(duration_s=True)
