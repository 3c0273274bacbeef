"""Directions in the sky at many frame times, interpolated between nodes.

A direction (Earth's, the sun's) is computed every ``EARTH_NODE_S`` of simulated time and
interpolated linearly in between (normalised): over a minute its path bends by far less than
a microradian from the chord. The frame recorder interpolates IVP's Earth (what the rover
points its HGA at) and the scorer the true Earth and sun, each with a ``SkyNodes`` of its own.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
Direction = Callable[[FloatArray], FloatArray]  # times (2,) -> unit vectors (2, 3)

EARTH_NODE_S = 60.0  # see the module docstring


class SkyNodes:
    """The directions ``directions`` (each from times to unit vectors) interpolated at
    increasing times, a new node pair where a time leaves the last one."""

    def __init__(self, directions: Sequence[Direction]) -> None:
        self._directions = list(directions)
        self._t0 = float("nan")
        self._nodes = np.zeros((len(self._directions), 2, 3))

    def at(self, t_s: FloatArray) -> FloatArray:
        """Each direction at each of ``t_s``, (D, K, 3), unit vectors."""
        u = np.empty(len(t_s))
        nodes = np.empty((len(t_s), len(self._directions), 2, 3))
        for k, t in enumerate(t_s.tolist()):
            u_k = (t - self._t0) / EARTH_NODE_S
            if not 0.0 <= u_k <= 1.0:
                self._t0, u_k = t, 0.0
                at = np.array([t, t + EARTH_NODE_S])
                self._nodes = np.stack([direction(at) for direction in self._directions])
            u[k], nodes[k] = u_k, self._nodes
        u3 = u[:, None, None]
        v = (1.0 - u3) * nodes[:, :, 0] + u3 * nodes[:, :, 1]
        v /= np.linalg.norm(v, axis=2, keepdims=True)
        out: FloatArray = np.moveaxis(v, 1, 0)
        return out

    def state(self) -> dict[str, Any]:
        """The current node pair (plain data; a checkpoint)."""
        return {"t0": self._t0, "nodes": self._nodes.copy()}

    def load_state(self, state: Mapping[str, Any]) -> None:
        """Load ``state`` (``state()``) onto nodes of the same directions."""
        self._t0 = float(state["t0"])
        self._nodes = np.array(state["nodes"], dtype=np.float64)
