"""A rover's ground map fed with the stereo pairs the ground has received.

The pairs are read back from storage (``server.storage.images.stereo_pairs``), where they were
stored once as they came down, each with the pose the rover reported when it took it: so a
map is the same whether its pairs arrived one by one, all at once after a pass, or before a
restart of the server (the map is rebuilt from them then). Nothing here reads the simulator.
One feed per runtime, shared by its 3D views and the pointing advisor (``ground_feed``);
fusing a pair takes a dense-stereo solve, so callers catch up off the clock thread.
"""

from __future__ import annotations

import logging
import math
import threading
import weakref
from typing import TYPE_CHECKING

import numpy as np

from server.storage.images import StereoPair, stereo_pairs
from server.terrain.service import DownlinkedPair, GroundMapService

if TYPE_CHECKING:
    from server.runtime import RoverRuntime
    from server.storage.store import Store

log = logging.getLogger(__name__)

GROUND_HALF_M = 40.0  # a rover's ground map: an 80 m square around where it landed
PAGE = 8  # pairs decoded at a time (a 1024 px pair is 2 MB decoded)

_FEEDS: weakref.WeakKeyDictionary[RoverRuntime, GroundFeed] = weakref.WeakKeyDictionary()
_FEEDS_LOCK = threading.Lock()


def downlinked_pair(pair: StereoPair) -> DownlinkedPair:
    """A stored pair as the map takes it: its images, pointing and reported pose."""
    meta = pair.meta
    return DownlinkedPair(
        pair.left, pair.right, int(meta["width_px"]), math.radians(meta["mast_az_deg"]),
        math.radians(meta["mast_el_deg"]), np.asarray(meta["p_mission_est"], dtype=np.float64),
        np.asarray(meta["q_b_ll_est"], dtype=np.float64),
    )  # fmt: skip


class GroundFeed:
    """Feeds ``service`` with ``rover``'s pairs stored in ``store`` (module docstring)."""

    def __init__(self, service: GroundMapService, store: Store, rover: str) -> None:
        self.service = service
        self.store = store
        self.rover = rover
        self.last_id = 0  # the newest stored pair taken
        self.refused = 0  # pairs the map could not use (logged)
        self._lock = threading.Lock()

    def catch_up(self) -> int:
        """Fuse every pair stored since the last call; the number taken."""
        taken = 0
        with self._lock:
            while True:
                page = stereo_pairs(self.store, self.rover, after_id=self.last_id, limit=PAGE)
                for pair in page:
                    self.last_id = pair.id
                    try:
                        self.service.add(downlinked_pair(pair))
                        taken += 1
                    except ValueError as error:  # a pair the map cannot place (logged)
                        self.refused += 1
                        log.warning("%s: pair %d not in the ground map: %s", self.rover,
                                    pair.id, error)  # fmt: skip
                if len(page) < PAGE:
                    return taken


def ground_feed(
    runtime: RoverRuntime, store: Store, service: GroundMapService | None = None
) -> GroundFeed:
    """The rover's feed, one per runtime: its map starts from the orbital product of its site
    around where the rover was placed (the landing the mission localised). With ``service``,
    a feed of that map instead (not shared)."""
    if service is not None:
        return GroundFeed(service, store, runtime.spec.name)
    with _FEEDS_LOCK:
        feed = _FEEDS.get(runtime)
        if feed is None:
            start_n, start_e = runtime.session.sim.start_xy_m
            service = GroundMapService(runtime.spec.site, runtime.spec.seed, start_n, start_e,
                                       half_m=GROUND_HALF_M)  # fmt: skip
            feed = GroundFeed(service, store, runtime.spec.name)
            _FEEDS[runtime] = feed
        return feed


def shared_feed(runtime: RoverRuntime) -> GroundFeed | None:
    """The rover's shared feed if one exists (its 3D views', its pointing advisor's), without
    making one: validation reads the map the ground has, and never fuses pairs itself."""
    with _FEEDS_LOCK:
        return _FEEDS.get(runtime)
