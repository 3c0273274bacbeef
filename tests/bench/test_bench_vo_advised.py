"""The issue-24 VO benches on their quick sizes (the full runs are ``roverops bench vo``):
the advised Meridiani drives (bench.vo.advised) and sol 235 (bench.vo.sol235): their
contracts, the ground map the advisor is given, and sol 235's prevention."""

from __future__ import annotations

import numpy as np
import pytest

from bench.vo.advised import ground_map, meridiani_advised
from bench.vo.courses import _sun_time
from bench.vo.sol235 import Sol235Spec, bench_sol235, sol235_run
from sim.errors import InputError
from sim.loop.session import RoverSession


def test_the_advised_drive_on_its_quick_size() -> None:
    out = meridiani_advised(n_drives=1, seed=1, workers=1)
    assert out["convergence_steps_meridiani_advised"] == 4  # 3 m in 0.75 m steps
    assert 0.0 <= out["convergence_pct_meridiani_advised"] <= 100.0
    assert out["false_update_count_meridiani_advised"] == 0
    assert sum(out["advised_pointings_deg"].values()) == 1
    with pytest.raises(InputError, match="n_drives"):
        meridiani_advised(n_drives=0)


def test_the_ground_map_is_the_orbital_dem_and_the_first_pairs_texture() -> None:
    utc = _sun_time(np.random.default_rng(3), "meridiani", (30.0, 60.0))
    session = RoverSession("meridiani", 3, utc, x_m=12.0, y_m=-4.0, frame_every_s=3600.0)
    gmap = ground_map(session, 3)
    # tied at the start: the ground under the body origin (mission z = 0) 0.30 m below it
    assert float(gmap.height_at(np.array([0.0]), np.array([0.0]))[0]) == pytest.approx(-0.30)
    # the first pair's texture only where it looked (ahead, North here), none behind
    measured = np.isfinite(gmap.texture)
    assert measured.any() and np.array_equal(measured, gmap.imaged)
    i_ahead, j = gmap.cell_of(np.array([3.0]), np.array([0.0]))
    i_behind, _ = gmap.cell_of(np.array([-3.0]), np.array([0.0]))
    col = round(float(j[0]))
    assert gmap.imaged[round(float(i_ahead[0])), col]
    assert not gmap.imaged[round(float(i_behind[0])), col]
    assert np.all(gmap.texture[measured] > 0.0)


def test_sol235_quick_size_and_its_prevention() -> None:
    out = bench_sol235(n_drives=1, seed=0, workers=1)
    for suffix in ("_unprevented", "", "_advised"):
        assert out[f"sol235_steps{suffix}"] == 15  # 3 m in 0.2 m steps
    assert out["false_update_count_sol235"] == 0  # the shadow mask
    assert out["false_update_count_sol235_advised"] == 0
    masked = sol235_run(Sol235Spec(0, "mask"))
    # what converges with the mask is right; without it, what converges is the shadow
    assert masked["false"] == 0
    with pytest.raises(InputError, match="mode"):
        sol235_run(Sol235Spec(0, "hope"))
