"""The communication plan (``sim.comm.plan``): its defaults, its JSON round trip, and every
refusal naming the field."""

from __future__ import annotations

import dataclasses
import json
import math
from typing import Any

import numpy as np
import pytest

from sim.comm.plan import CommPlan
from sim.errors import InputError

FIELDS = [f.name for f in dataclasses.fields(CommPlan)]
# each field: values at and inside its edges (accepted), values just outside (refused)
EDGES: dict[str, tuple[list[float], list[float]]] = {
    "uplink_lmst_h": ([0.0, 23.999], [-0.001, 24.0]),
    "dte_lmst_h": ([0.0, 23.999], [-0.001, 24.0]),
    "planning_lmst_h": ([0.0, 23.999], [-0.001, 24.0]),
    "uplink_minutes": ([0.001, 720.0], [0.0, 720.001]),
    "dte_minutes": ([0.001, 720.0], [0.0, 720.001]),
    "uplink_rate_bps": ([0.001, 1.0e7], [0.0, 1.0e7 + 1.0]),
    "dte_rate_bps": ([0.001, 1.0e7], [0.0, -5.0]),
    "relay_rate_bps": ([1.0, 1.0e7], [0.0, 2.0e7]),
    "earth_min_elev_deg": ([0.0, 80.0], [-0.1, 80.1]),
    "relay_mask_deg": ([0.0, 80.0], [-0.1, 90.0]),
    "relay_latency_s": ([0.0, 7 * 86_400.0], [-1.0, 7 * 86_400.0 + 1.0]),
    "store_capacity_mbit": ([0.001, 1.0e6], [0.0, 1.0e6 + 1.0]),
    "decimate_s": ([1.0, 3_600.0], [0.999, 3_600.5]),
}


def test_the_defaults() -> None:
    plan = CommPlan()
    assert plan.as_json() == {
        "uplink_lmst_h": 9.0,
        "uplink_minutes": 60.0,
        "uplink_rate_bps": 2_000.0,
        "dte_lmst_h": 9.0,
        "dte_minutes": 60.0,
        "dte_rate_bps": 10_000.0,
        "earth_min_elev_deg": 10.0,
        "relay_mask_deg": 10.0,
        "relay_rate_bps": 128_000.0,
        "relay_latency_s": 1_800.0,
        "store_capacity_mbit": 2_048.0,
        "decimate_s": 60.0,
        "planning_lmst_h": 18.0,
    }
    # MER's 256 MB of flash; a relay pass of ~8 min at 128 kbit/s brings ~60 Mbit
    assert plan.store_capacity_mbit == 256 * 8
    assert plan.relay_rate_bps * 8 * 60 / 1e6 == pytest.approx(60.0, rel=0.03)
    assert set(EDGES) == set(FIELDS)  # every field's range is checked below


def test_json_round_trip_through_text() -> None:
    plan = CommPlan().replaced({"relay_mask_deg": 15, "uplink_lmst_h": 8.5})
    assert CommPlan.from_json(json.loads(json.dumps(plan.as_json()))) == plan
    assert all(type(v) is float for v in plan.as_json().values())


def test_a_checkpoint_without_a_newer_field_takes_its_default() -> None:
    data = CommPlan(dte_rate_bps=12_000.0).as_json()
    del data["decimate_s"]
    plan = CommPlan.from_json(data)
    assert plan.dte_rate_bps == 12_000.0 and plan.decimate_s == CommPlan().decimate_s


def test_replaced_is_a_validated_copy() -> None:
    plan = CommPlan()
    changed = plan.replaced({"relay_mask_deg": 20, "store_capacity_mbit": np.float64(512.0)})
    assert changed.relay_mask_deg == 20.0 and type(changed.relay_mask_deg) is float
    assert changed.store_capacity_mbit == 512.0
    assert plan.relay_mask_deg == 10.0  # the original is left as it was
    assert plan.replaced({}) == plan
    assert hash(changed) != hash(plan)  # a cache key


def test_an_unknown_field_is_refused_with_the_known_ones() -> None:
    with pytest.raises(InputError) as err:
        CommPlan().replaced({"relay_mask_deg": 12.0, "uplink_rate": 1000.0})
    assert err.value.parameter == "uplink_rate"
    assert all(name in err.value.problem for name in FIELDS)
    with pytest.raises(InputError) as err:
        CommPlan.from_json({"store_capacity": 10.0})
    assert err.value.parameter == "store_capacity"


@pytest.mark.parametrize("field", FIELDS)
@pytest.mark.parametrize("bad", [True, False, "10", None, [1.0], math.nan, math.inf, -math.inf])
def test_non_numbers_are_refused_naming_the_field(field: str, bad: Any) -> None:
    with pytest.raises(InputError) as err:
        CommPlan().replaced({field: bad})
    assert err.value.parameter == field
    with pytest.raises(InputError) as err:
        CommPlan.from_json({field: bad})
    assert err.value.parameter == field


@pytest.mark.parametrize("field", FIELDS)
def test_each_range_at_its_edges(field: str) -> None:
    good, bad = EDGES[field]
    for value in good:
        assert getattr(CommPlan().replaced({field: value}), field) == value
    for value in bad:
        with pytest.raises(InputError) as err:
            CommPlan().replaced({field: value})
        assert err.value.parameter == field
        with pytest.raises(InputError):
            CommPlan(**{field: value})  # the constructor checks as well


def test_not_a_mapping_is_refused() -> None:
    with pytest.raises(InputError) as err:
        CommPlan.from_json([("relay_mask_deg", 10.0)])  # type: ignore[arg-type]
    assert err.value.parameter == "comm_plan"
    with pytest.raises(InputError) as err:
        CommPlan().replaced("relay_mask_deg=10")  # type: ignore[arg-type]
    assert err.value.parameter == "changes"
