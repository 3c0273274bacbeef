"""The rehearsal tests' map (``rehearsal_data``)."""

from __future__ import annotations

import pytest
from rehearsal_data import plane_map

from sim.rehearsal.inputs import GroundMapData


@pytest.fixture(scope="module")
def ground_map() -> GroundMapData:
    return plane_map()
