"""``roverops bench server`` in a quick version: the same pieces on a small scale (5
WebSocket clients for 2 s, a 1,000-line validation, a 2 m drive and a 1 min HGA pass),
checking the output contract of docs/DESIGN.md and that the figures make sense. No speed is
asserted (TESTING.md: benchmarks measure, tests assert correctness)."""

from __future__ import annotations

import json
from typing import Any

import pytest

from bench.server import TARGETS, bench_server, example_blocks, validation_text
from cli.main import main
from sequences.validate import validate

UNITS = ("_s", "_ms", "_m", "_x", "_per_s")  # units a float metric's key ends with


@pytest.fixture(scope="module")
def quick() -> dict[str, Any]:
    return bench_server(
        ws_clients=5,
        ws_window_s=2.0,
        validate_lines=1000,
        validate_repeats=1,
        drive_m=2.0,
        hga_min=1.0,
        blank_lines=10_000,
        upload_bytes=100_000,
        sol_repeats=1,  # one sol on one server: the figures' sense, not their spread
        channel_every_s=600.0,  # 7 sols of a frame every 10 min
    )


def test_the_output_contract(quick: dict[str, Any]) -> None:
    assert json.loads(json.dumps(quick, allow_nan=False)) == quick  # plain JSON
    assert set(quick) == {"bench", "metrics", "targets", "ok", "machine"}
    assert quick["bench"] == "server"
    assert quick["targets"] == TARGETS
    assert set(TARGETS) == {
        "sol_sim_wall_s",
        "ws_clients",
        "ws_p99_latency_ms",
        "validate_10k_lines_s",
        "validate_100k_blank_lines_s",
        "event_loop_stall_ms_during_upload",
        "channel_query_7_sols_s",
    }
    assert set(quick["targets"]) <= set(quick["metrics"])
    assert isinstance(quick["ok"], bool)
    assert quick["ok"] is False  # 5 clients are not the 50 of the target
    for key, value in quick["metrics"].items():
        assert isinstance(value, (int, float)), key  # figures only
        if isinstance(value, float):
            # the unit ends the key, or follows the quantity (the name for the stall)
            assert key.endswith(UNITS) or "_ms_during_" in key, f"{key}: no unit in the key"


def test_the_sol_ran_through_the_server(quick: dict[str, Any]) -> None:
    m = quick["metrics"]
    assert m["sol_sim_wall_s"] > 0.0
    assert m["sol_sim_commands"] == 3 and m["sol_sim_commands_not_completed"] == 0
    assert 1.5 < m["sol_sim_distance_m"] < 2.5
    # GET_FINE_ATTITUDE, the drive (53 s at 3.75 cm/s) and the 60 s pass, simulated
    assert m["sol_sim_simulated_s"] > 60.0 + 2.0 / 0.0375


def test_the_websocket_clients_received_stamped_frames(quick: dict[str, Any]) -> None:
    m = quick["metrics"]
    assert m["ws_clients_connected"] == 5
    assert 0 <= m["ws_clients"] <= 5
    assert m["ws_messages"] > 0 and m["ws_msgs_per_client_per_s"] > 0.0
    assert 0.0 <= m["ws_p50_latency_ms"] <= m["ws_p99_latency_ms"] <= m["ws_max_latency_ms"]
    assert m["ws_rover_speed_seen_x"] > 0.0


def test_the_validation_figures(quick: dict[str, Any]) -> None:
    m = quick["metrics"]
    assert m["validate_lines"] == 1000 and m["validate_steps"] == 999
    assert m["validate_errors"] == 0
    assert m["validate_10k_lines_s"] > 0.0 and m["validate_10k_lines_with_rover_s"] > 0.0


def test_the_blank_lines_and_the_stall_figures(quick: dict[str, Any]) -> None:
    m = quick["metrics"]
    assert m["blank_lines"] == 10_000
    assert m["validate_100k_blank_lines_s"] > 0.0 and m["upload_100k_blank_lines_s"] > 0.0
    assert 90_000 < m["upload_1mb_bytes"] <= 100_000 and m["upload_1mb_validate_s"] > 0.0
    if m["event_loop_stall_samples"]:  # a fast machine may validate 100 kB within one poll
        assert 0.0 < m["event_loop_stall_ms_during_upload"] <= m["event_loop_stall_max_ms"]


def test_the_channel_query_read_the_7_sols_stored(quick: dict[str, Any]) -> None:
    m = quick["metrics"]
    sols_s = 7 * 88775.244  # 7 Mars solar days
    assert m["channel_rows_stored"] == pytest.approx(sols_s / 600.0, abs=2)
    assert m["channel_repeats"] == 3 and m["channel_store_wall_s"] > 0.0
    assert m["channel_query_7_sols_s"] > 0.0 and m["channel_query_7_sols_truth_s"] > 0.0
    assert 0 < m["channel_points"] <= m["channel_rows_stored"]


def test_the_validation_text_is_the_examples_and_valid() -> None:
    text = validation_text(300)
    lines = text.splitlines()
    assert len(lines) == 300 and lines[0] == "SEQUENCE validate_bench"
    every_example_line = {line for block in example_blocks() for line in block}
    assert len(example_blocks()) >= 5
    # each line is an example's line, its LMST tag moved to a sol of its own
    for line in lines[1:]:
        assert line in every_example_line or line.startswith("@ sol "), line
    result = validate(text)
    assert result.errors == [] and result.sequence is not None


def test_an_unknown_benchmark_names_the_choices(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bench", "warp", "--json"]) == 2
    err = capsys.readouterr().err
    assert "name" in err and "server" in err and "sim" in err
