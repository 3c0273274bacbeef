"""The drive monitor on hand-made segments: which check trips first and where, the fault
latch, the checkpoint; and that the checks read nothing of the simulator."""

from __future__ import annotations

import ast
import math
from pathlib import Path

import numpy as np
import pytest

from estimation.protection.keepout import KeepOutZone
from estimation.protection.monitor import MobilityProtection

G = 3.711
N = 80
DT = 0.125
ROOT = Path(__file__).resolve().parents[3]


def _segment(speed_m_s: float = 0.05, pitch_rad: float = 0.0) -> dict[str, np.ndarray]:
    t = 1.0e8 + DT * np.arange(1, N + 1)
    x = speed_m_s * DT * np.arange(1, N + 1)
    p_s = np.column_stack([x, np.zeros(N), np.zeros(N)])
    f_b = np.tile([G * math.sin(pitch_rad), 0.0, -G * math.cos(pitch_rad)], (N, 1))
    return {
        "t_s": t,
        "p_s": p_s,
        "step_m": np.full(N, speed_m_s * DT),
        "delta_velocity_b": f_b * DT,
        "dt_s": np.full(N, DT),
        "rocker_rad": np.zeros(N),
        "bogie_rad": np.zeros((N, 2)),
    }


def _check(protection: MobilityProtection, seg: dict[str, np.ndarray], **limits: object):  # type: ignore[no-untyped-def]
    monitor = protection.begin_drive(1.0e8, math.radians(3.0), protection.drive_limits(**limits))  # type: ignore[arg-type]
    zones = {name: seg["p_s"] for name in protection.zones}
    return monitor.check_cycles(
        seg["t_s"], zones, seg["step_m"], seg["delta_velocity_b"], seg["dt_s"],
        seg["rocker_rad"], seg["bogie_rad"], seg["p_s"],
    )  # fmt: skip


def test_a_clear_drive_trips_nothing() -> None:
    assert _check(MobilityProtection(0.0), _segment()) is None


def test_the_keepout_check_halts_before_the_grown_disc_touches() -> None:
    protection = MobilityProtection(0.0)
    protection.uncertainty.sigma_m = 0.1  # known to 10 cm before the drive
    protection.add_zone(KeepOutZone.circle("rock", 0, 0.7, 0.0, 0.2))
    trip = _check(protection, _segment())
    assert trip is not None and trip.halt.check == "keepout"
    x = _segment()["p_s"][:, 0]
    sigma = np.sqrt(0.1**2 + ((0.03**2 + math.radians(1.0) ** 2) * (x**2)))
    clearance = np.abs(0.7 - x) - 0.2
    expected = int(np.flatnonzero(clearance <= 2.0 * sigma)[0])
    assert trip.index == expected
    assert trip.halt.values["margin_m"] == pytest.approx(2.0 * sigma[expected])
    assert trip.halt.p_s[0] == pytest.approx(x[expected])


def test_tilt_timeout_and_time_of_day_each_trip_where_they_should() -> None:
    steep = _check(MobilityProtection(0.0), _segment(pitch_rad=math.radians(31.0)))
    assert steep is not None and steep.halt.check == "tilt" and steep.index == 0
    assert math.degrees(steep.halt.values["pitch_rad"]) == pytest.approx(31.0)
    late = _check(MobilityProtection(0.0), _segment(), timeout_s=5.0)
    assert late is not None and late.halt.check == "timeout"
    assert late.index == round(5.0 / DT)  # the first cycle past 5 s
    bumpy = _segment()
    bumpy["bogie_rad"][50:, 1] = math.radians(50.0)
    trip = _check(MobilityProtection(0.0), bumpy)
    assert trip is not None and trip.halt.check == "suspension" and trip.index == 50


def test_the_fault_latches_until_cleared_and_survives_a_checkpoint() -> None:
    protection = MobilityProtection(1.0)
    trip = _check(protection, _segment(pitch_rad=0.7))
    assert trip is not None
    protection.fault = trip.halt
    protection.add_zone(KeepOutZone.polygon("dune", 0, [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0)]))
    protection.set_limit("slip_limit", 0.3)
    with pytest.raises(ValueError, match="CLEAR_MOBILITY_FAULT"):
        protection.require_enabled("DRIVE_STRAIGHT")
    restored = MobilityProtection(1.0)
    restored.load_state(protection.state())
    assert restored.state() == protection.state()
    assert restored.clear_fault() == trip.halt
    restored.require_enabled("DRIVE_STRAIGHT")
    with pytest.raises(ValueError, match=r"mobility\.slip_limit"):
        restored.set_limit("slip_limit", 1.5)
    with pytest.raises(ValueError, match="no keep-out zone 'x'"):
        restored.clear_zones("x")
    assert restored.clear_zones("all") == ["dune"]


def test_no_check_reads_the_truth() -> None:
    """The checks import only the flight software, numpy and the standard library: the
    simulator (``sim``), the ground (``server``, ``sequences``) are out of their reach."""
    for path in sorted((ROOT / "estimation" / "protection").glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                names = [node.module or ""]
            for name in names:
                top = name.split(".")[0]
                allowed = {"estimation", "numpy", "math", "dataclasses", "typing"}
                allowed |= {"collections", "__future__", "numbers", "re"}
                assert top in allowed, (path.name, name)


def test_a_drive_that_starts_within_the_margin_may_move_away_but_not_closer() -> None:
    protection = MobilityProtection(0.0)
    protection.uncertainty.sigma_m = 0.2
    protection.add_zone(KeepOutZone.circle("rock", 0, -0.5, 0.0, 0.3))  # 0.2 m behind
    assert _check(protection, _segment()) is None  # driving away from it
    protection.zones = {}
    protection.add_zone(KeepOutZone.circle("rock", 0, 0.8, 0.0, 0.3))
    trip = _check(protection, _segment())
    assert trip is not None and trip.halt.check == "keepout"
