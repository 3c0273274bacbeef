"""``roverops bench faults``, small: one seed of each case, and the runs setting checked."""

from __future__ import annotations

import pytest

from bench.faults import cases, injected
from bench.registry import BENCHES
from sequences.limits import VO_STEP_MAX_M
from sim.errors import InputError


def test_the_bench_is_registered_and_its_runs_setting_is_checked(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    assert "faults" in BENCHES
    for bad in ("0", "-3", "1e9", "many", "1001"):
        monkeypatch.setenv("ROVEROPS_FAULTS_RUNS", bad)
        with pytest.raises(InputError, match="ROVEROPS_FAULTS_RUNS"):
            cases.runs_from_env()
    monkeypatch.setenv("ROVEROPS_FAULTS_RUNS", "3")
    assert cases.runs_from_env() == 3


def test_one_run_of_the_protection_cases() -> None:
    trap = cases.sandtrap_run(0)
    assert trap["halted"] and trap["past_edge_m"] <= 5.0 + VO_STEP_MAX_M
    tilt = cases.tilt_run(0)
    assert tilt["check"] == "tilt" and tilt["excess_deg"] <= 1.0
    wopmay = cases.wopmay_run(0, True)
    assert not wopmay["entered"]


def test_one_run_of_the_injected_faults() -> None:
    assert injected.navcam_run(0, "halt")["clean"]
    assert injected.navcam_run(0, "continue")["clean"]
    dust = injected.dust_run(0)
    assert dust["clean"] and dust["status"] == "failed"
    gyro = injected.gyro_step_run(0)
    assert gyro["detected"] and gyro["restored"]
