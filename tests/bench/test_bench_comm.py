"""``roverops bench comm`` in a quick version: 5 light-time samples, one sol, one kill (while
the rover computes the drive it runs during an uplink's flight), checking the output
contract and the targets that must be zero. No speed is asserted."""

from __future__ import annotations

import json
from typing import Any

import pytest

from bench.comm import kills
from bench.comm.report import KILLS_ENV, TARGETS, bench_comm, kills_from_env
from bench.registry import BENCHES
from sim.errors import InputError

UNITS = ("_s", "_m", "_deg", "_pct", "_mbit", "_per_sol", "_median")


@pytest.fixture(scope="module")
def quick() -> dict[str, Any]:
    return bench_comm(kills=1, sols=1, light_samples=5, drive_m=5.0, kill_spread=0.3)


def test_the_bench_is_registered_and_its_kills_setting_is_checked(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    assert BENCHES["comm"].target == "bench.comm.report:bench_comm"
    for bad in ("0", "-1", "many", "101"):
        monkeypatch.setenv(KILLS_ENV, bad)
        with pytest.raises(InputError, match=KILLS_ENV):
            kills_from_env()
    monkeypatch.setenv(KILLS_ENV, "3")
    assert kills_from_env() == 3


def test_the_output_contract(quick: dict[str, Any]) -> None:
    assert json.loads(json.dumps(quick, allow_nan=False)) == quick  # plain JSON
    assert set(quick) == {"bench", "metrics", "targets", "ok", "machine", "details"}
    assert quick["bench"] == "comm"
    assert quick["targets"] == TARGETS
    assert set(TARGETS) <= set(quick["metrics"])
    for key, value in quick["metrics"].items():
        assert isinstance(value, (bool, int, float)), key  # figures only
        if isinstance(value, float) and not isinstance(value, bool):
            assert key.endswith(UNITS) or "_per_" in key, f"{key}: no unit in the key"


def test_the_targets_that_must_hold(quick: dict[str, Any]) -> None:
    m = quick["metrics"]
    assert m["owlt_samples"] == 5 and m["owlt_max_error_s"] <= 0.01
    assert 182.0 <= m["owlt_min_s"] <= m["owlt_max_s"] <= 1342.0  # Earth-Mars
    assert m["sols"] == 1 and m["drives_completed"] == 1
    assert m["relay_passes_per_sol"] >= 1 and m["downlink_passes_used"] >= 1
    assert 0.0 < m["downlinked_mbit_per_sol"] <= m["downlink_capacity_mbit_per_sol"]
    assert m["downlinked_mbit_le_capacity"] is True and m["downlinked_tally_agrees"] is True
    assert m["overflow_dropped"] > 0 and m["overflow_accounted_pct"] == 100.0
    assert m["kills"] == 1 and m["kills_mid_uplink"] == 1 and m["kill_reference_frames"] > 0
    for key in ("early_arrivals", "uplink_before_window", "products_lost_with_room"):
        assert m[key] == 0, (key, quick["details"])
    assert m["kill_mid_pass_lost"] == 0 and m["kill_mid_pass_duplicated"] == 0, quick["details"]
    assert quick["ok"] is True


def test_the_kill_triggers_come_in_the_scenarios_order() -> None:
    scene = kills.scenario()
    drives = [t.t_s for t in scene.triggers if t.what == "drive"]
    assert drives == sorted(drives) and len(drives) == 3
    assert drives[-1] == scene.end_s  # a run ends at rest after the last drive
    assert kills.quotas(10, scene.triggers) == [1, 2, 2, 1, 1, 1, 1, 1]
