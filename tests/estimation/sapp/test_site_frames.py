"""Site frames (Ali et al. 2005 sec. 4): planting resets the position, the chain joins the Sites."""

import numpy as np
import pytest

from estimation.sapp.site_frames import SiteChain


def test_planting_moves_the_origin_to_the_rover_and_counts_up() -> None:
    chain = SiteChain()
    assert chain.current.index == 0
    first = chain.plant([12.0, -3.0, 0.5])
    second = chain.plant([4.0, 4.0, -0.25])
    assert (first.index, second.index, len(chain)) == (1, 2, 3)
    np.testing.assert_allclose(second.origin_mission_m, [16.0, 1.0, 0.25])
    # the rover where Site 2 was planted is at Site 2's origin: the same mission point
    np.testing.assert_allclose(chain.to_mission([0.0, 0.0, 0.0], 2), [16.0, 1.0, 0.25])
    np.testing.assert_allclose(chain.to_mission([4.0, 4.0, -0.25], 1), [16.0, 1.0, 0.25])


def test_a_traverse_is_continuous_across_plants() -> None:
    rng = np.random.default_rng(3)
    path_mission = np.cumsum(rng.normal(size=(300, 3)), axis=0)
    chain = SiteChain()
    index, origin = 0, np.zeros(3)
    for k, p in enumerate(path_mission):
        p_s = p - origin  # what the rover would report in its current Site
        np.testing.assert_allclose(chain.to_mission(p_s, index), p, atol=1e-9)
        if k % 50 == 49:
            site = chain.plant(p_s)
            index, origin = site.index, site.origin_mission_m
    assert chain.current.index == 6


def test_bad_input_names_the_parameter() -> None:
    chain = SiteChain()
    with pytest.raises(ValueError, match="p_s"):
        chain.plant([1.0, np.nan, 0.0])
    with pytest.raises(ValueError, match="index"):
        chain.to_mission([0.0, 0.0, 0.0], 3)
    assert len(chain) == 1  # nothing was planted by the failed call
