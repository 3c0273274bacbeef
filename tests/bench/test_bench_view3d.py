"""``roverops bench view3d`` in a quick version: a 2 m drive drawn without and with a viewer,
two terrain re-cuts, and one sol with a 2 m drive through the real server with the 3D view
on and off; the output contract of docs/DESIGN.md, figures that are positive, finite and
consistent with each other, and the parsing of viser's wire format. No speed is asserted
(TESTING.md: benchmarks measure, tests assert correctness)."""

from __future__ import annotations

import json
import math
import re
from typing import Any

import pytest

from bench.view3d import TARGETS, bench_view3d, by_span, window_stamp
from cli.main import main
from sim.errors import InputError

UNIT = re.compile(r"_(ms|s|m|ratio)(_|$)")  # a float metric names its unit
# Draws the server's own scene made by the time a sol completed: in a 1 s sol the scene
# thread may still be cutting its first terrain patch. Draws that re-cut the terrain: the
# first patch is cut when the view starts, so a drive shorter than TERRAIN_RECUT_M needs none.
MAY_BE_ZERO = {"view_sol_frames_drawn", "view_draw_recuts"}


@pytest.fixture(scope="module")
def quick() -> dict[str, Any]:
    return bench_view3d(
        drive_m=2.0, recuts=2, sol_drive_m=2.0, sol_hga_min=1.0, sol_repeats=1, console_repeats=1
    )


def test_the_output_contract(quick: dict[str, Any]) -> None:
    assert json.loads(json.dumps(quick, allow_nan=False)) == quick  # plain JSON
    assert set(quick) == {"bench", "metrics", "targets", "ok", "machine"}
    assert quick["bench"] == "view3d"
    assert (
        quick["targets"]
        == TARGETS
        == {
            "view_draw_ms_p95_1_client": {"le": 100.0},
            "signin_with_view_s": {"le": 1.0},
            "command_round_trip_with_view_s": {"le": 1.0},
        }
    )
    metrics = quick["metrics"]
    assert quick["ok"] is (
        metrics["view_draw_ms_p95_1_client"] <= 100.0
        and metrics["signin_with_view_s"] <= 1.0
        and metrics["command_round_trip_with_view_s"] <= 1.0
    )
    for key, value in metrics.items():
        assert isinstance(value, (int, float)) and not isinstance(value, bool), key
        assert math.isfinite(value) and value >= 0, f"{key} = {value}"
        assert value > 0 or key in MAY_BE_ZERO, f"{key} = {value}"
        if isinstance(value, float):
            assert UNIT.search(key), f"{key}: no unit in the key"


def test_the_draw_figures_are_consistent(quick: dict[str, Any]) -> None:
    m = quick["metrics"]
    assert m["view_drive_m"] == 2.0 and m["view_frames"] > 3
    assert m["view_draw_ms_median"] <= m["view_draw_ms_p95"] <= m["view_draw_ms_max"]
    low, high = m["view_draw_ms_median_1_client"], m["view_draw_ms_p95_1_client"]
    assert low <= high <= m["view_draw_ms_max_1_client"]
    # delivery includes the draw itself
    assert m["view_draw_to_client_ms_median_1_client"] >= low
    # the view cut the first patch at its start: 2 m from it, no draw re-cuts (8 m)
    assert m["view_draw_recuts"] == 0


def test_the_viewer_received_the_scene_draws_and_terrain(quick: dict[str, Any]) -> None:
    m = quick["metrics"]
    # a terrain patch (201 x 201 vertices, float32) outweighs a drawn frame many times
    assert m["view_terrain_bytes_1_client"] > 201 * 201 * 3 * 4
    assert m["view_terrain_bytes_1_client"] > 20 * m["view_bytes_per_draw_1_client"]
    # the initial scene holds a patch too (elsewhere: its bands' vertex counts differ a bit)
    assert m["view_initial_scene_bytes_1_client"] >= 0.9 * m["view_terrain_bytes_1_client"]
    assert m["view_messages_per_draw_1_client"] >= 2  # two rovers, the arrows, the status
    assert m["view_terrain_recuts"] == 2
    assert m["view_terrain_recut_s_median"] >= m["view_terrain_cut_s_median"]


def test_the_sol_ran_with_the_view_on_and_off(quick: dict[str, Any]) -> None:
    m = quick["metrics"]
    assert m["view_sol_repeats"] == 1 and m["view_sol_drive_m"] == 2.0
    assert m["view_sol_wall_ratio"] == pytest.approx(
        m["sol_sim_wall_s_3d"] / m["sol_sim_wall_s_no_3d"]
    )


def test_the_console_was_measured_with_the_view_shown(quick: dict[str, Any]) -> None:
    m = quick["metrics"]
    assert m["console_repeats"] == 1
    assert m["signin_with_view_s"] > 0 and m["command_round_trip_with_view_s"] > 0


def test_a_window_that_is_not_vipers_wire_format_is_refused() -> None:
    with pytest.raises(ValueError, match="shorter than its header"):
        window_stamp(b"\x00" * 8)
    claims_more = (10).to_bytes(8, "little") + (1000).to_bytes(8, "little") + b"x" * 10
    with pytest.raises(ValueError, match="claims 1000 compressed bytes"):
        window_stamp(claims_more)
    garbage = (10).to_bytes(8, "little") + (4).to_bytes(8, "little") + b"abcd"
    with pytest.raises(ValueError, match="does not decode"):
        window_stamp(garbage)


def test_messages_go_to_the_span_they_were_serialised_in() -> None:
    assert by_span([0.1, 1.0, 1.5, 2.0, 3.0], [1.0, 2.0, 2.5]) == [[1, 2], [3], [4]]
    assert by_span([], [1.0]) == [[]]


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"drive_m": 0.0}, "drive_m"),
        ({"drive_m": math.nan}, "drive_m"),
        ({"sol_drive_m": -1.0}, "sol_drive_m"),
        ({"recuts": 0}, "recuts"),
        ({"sol_repeats": 0}, "sol_repeats"),
    ],
)
def test_bad_sizes_are_refused_by_name(kwargs: dict[str, Any], name: str) -> None:
    with pytest.raises(InputError) as error:
        bench_view3d(**kwargs)
    assert error.value.parameter == name


def test_the_cli_lists_view3d(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bench", "warp", "--json"]) == 2
    assert "view3d" in capsys.readouterr().err
