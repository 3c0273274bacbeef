"""The 1024 px VO bench on a quick count (the full run is ``measure_gusev_1024()``): its
drives are ``bench_vo``'s Gusev convergence drives with the session's rig at 1024 px, and its
figures are consistent counts and fractions."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench.vo.courses import KINDS, _session
from bench.vo.rig1024 import gusev_1024_specs, measure_gusev_1024
from estimation.vo.params import VoParams
from sim.errors import InputError


def test_the_drives_are_the_convergence_drives_at_1024_px() -> None:
    specs = gusev_1024_specs(100, seed=0)
    assert len(specs) == 25  # 3 m drives of four 0.75 m steps
    assert [(s.kind, s.site_name, s.seed, s.index, s.length_m) for s in specs[:2]] == [
        ("convergence", "gusev", 0, 0, 3.0),
        ("convergence", "gusev", 1, 1, 3.0),
    ]
    spec = specs[0]
    session, _ = _session(
        spec, np.random.default_rng([spec.seed, spec.index, KINDS.index("convergence")])
    )
    assert session.vo.rig.camera.width_px == 1024
    assert session.vo.params == VoParams().for_width(1024)


def test_a_two_step_run_gives_consistent_figures() -> None:
    m = measure_gusev_1024(steps=2, seed=0, drive_m=1.5)
    assert m["drives_gusev_1024"] == 1 and m["convergence_steps_gusev_1024"] == 2
    assert m["drives_not_completed_gusev_1024"] == 0
    accepted = m["accepted_steps_gusev_1024"]
    failed = sum(v for k, v in m.items() if k.startswith("convergence_failures_gusev_1024_"))
    assert accepted + failed == 2  # every step converged or failed for a reason
    assert m["convergence_pct_gusev_1024"] == pytest.approx(100.0 * accepted / 2)
    assert 0 <= m["false_update_count_gusev_1024"] <= accepted
    if accepted:
        assert 0.0 < m["vo_step_s_1024"] < 60.0
    else:
        assert math.isnan(m["vo_step_s_1024"])


@pytest.mark.parametrize(
    "kwargs", [{"steps": 0}, {"processes": 0}, {"seed": -1}, {"steps": True}, {"drive_m": 0.0}]
)
def test_bad_arguments_are_refused(kwargs: dict[str, int | float]) -> None:
    with pytest.raises(InputError, match=next(iter(kwargs))):
        measure_gusev_1024(**kwargs)  # type: ignore[arg-type]
