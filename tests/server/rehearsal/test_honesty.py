"""The honesty rule (issue 25): a rehearsal knows only what the ground knows. Two rovers whose
hidden values differ (the soil, the IMU's biases, the mast's bias, the terrain at the scales
the ground's map does not resolve) but whose reports are the same (the same last downlink
record and reported tables, the same ground map) give the same rehearsal inputs, and a
campaign on them gives the same risk table and outcomes, bit for bit, with the same seed."""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

from server.rehearsal.cluster import DEFAULT_RUN, resolve_run
from server.rehearsal.gather import runtime_inputs
from server.rehearsal.service import campaign_risk
from server.rovers import ROVERS
from server.runtime import RoverRuntime
from server.storage import Store
from sim.loop.session import RoverSession
from sim.rehearsal.inputs import RehearsalInputs
from sim.rehearsal.outcome import RunOutcome
from sim.sensors.imu import Ln200Params
from sim.world.soil_patches import Circle, SoilPatch
from sim.world.terrain import SAND_TRAP
from tests.server.rehearsal.test_gather import inputs_equal, play_out

SETUP = (
    "SEQUENCE setup\nKEEPOUT_ADD zone=rock x_m=4 y_m=1 radius_m=0.4\nDRIVE_STRAIGHT distance_m=1\n"
)
REHEARSED = "SEQUENCE next\nDRIVE_STRAIGHT distance_m=1\nTURN_IN_PLACE angle_deg=20\n"
SEED = 5
RUNS = 3


@pytest.fixture(scope="module")
def two_rovers() -> Iterator[tuple[RoverRuntime, RoverRuntime, Store]]:
    spec = ROVERS["spirit"]
    plain = RoverRuntime(spec)
    # the other rover: another seed (its terrain at every scale below the orbital map's, its
    # sensors' noise), biased IMU, a badly aligned mast, and sand under its wheels
    imu = Ln200Params(gyro_bias_turn_on_deg_per_h=20.0, accel_bias_turn_on_ug=3000.0)
    session = RoverSession(spec.site, spec.seed + 7, spec.start_utc, frame_every_s=1.0,
                           imu_params=imu, mast_bias_sigma_deg=0.5)  # fmt: skip
    session.sim.add_soil_patch("sand", SoilPatch(SAND_TRAP, Circle(0.0, 0.0, 30.0)))
    hidden = RoverRuntime(spec, session=session)
    play_out(plain, 1, SETUP)
    # the same report on both: the last record that came down and the tables it reported
    with plain.lock, hidden.lock:
        hidden.last_frame = plain.last_frame
        hidden.reported.params = dict(plain.reported.params)
        hidden.reported.zones = dict(plain.reported.zones)
        hidden.reported.mobility_fault = plain.reported.mobility_fault
    store = Store("sqlite://")  # the same ground map: the orbital product, no pair yet
    yield plain, hidden, store
    store.close()


def _campaign(inputs: RehearsalInputs, seed: int) -> tuple[dict[str, Any], list[str]]:
    run = resolve_run(DEFAULT_RUN)  # the function the workers run
    outcomes: list[RunOutcome] = [run(inputs, i, seed) for i in range(RUNS)]
    risk = campaign_risk(inputs, outcomes)
    # repr of floats is exact (and tells -0.0 from 0.0); the wall time is no result
    return risk, [repr(dataclasses.replace(o, wall_s=0.0, worker="").as_dict())
                        for o in outcomes]  # fmt: skip


def test_hidden_values_leave_the_rehearsal_unchanged(
    two_rovers: tuple[RoverRuntime, RoverRuntime, Store],
) -> None:
    plain, hidden, store = two_rovers
    a, b = plain.session.sim, hidden.session.sim
    assert a.soil_at(0.0, 0.0) != b.soil_at(0.0, 0.0)  # the hidden values do differ
    imu_a, imu_b = a.imu.state(), b.imu.state()
    for bias in ("gyro_bias_on_rad_s", "accel_bias_m_s2"):
        assert not np.array_equal(imu_a[bias], imu_b[bias])
    assert not np.array_equal(a.mast_bias_rad, b.mast_bias_rad)
    assert a.terrain.height_m(2.3, 0.7) != b.terrain.height_m(2.3, 0.7)
    inputs_a = runtime_inputs(plain, store, REHEARSED)
    inputs_b = runtime_inputs(hidden, store, REHEARSED)
    assert inputs_equal(inputs_a, inputs_b)
    assert inputs_a.start.keepout_zones and inputs_a.start.position_sigma_m > 0.0
    risk_a, outcomes_a = _campaign(inputs_a, SEED)
    risk_b, outcomes_b = _campaign(inputs_b, SEED)
    assert repr(risk_a) == repr(risk_b) and outcomes_a == outcomes_b
    # and the result is not the same whatever happens: another seed draws other worlds
    assert _campaign(inputs_a, SEED + 1)[1] != outcomes_a
    assert risk_a["runs"] == RUNS and [e["line"] for e in risk_a["lines"]] == [2, 3]
