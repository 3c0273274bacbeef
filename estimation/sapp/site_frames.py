"""Site frames and their chain (Ali et al. 2005, Table 1, sec. 1 and sec. 4 "Operations on Mars").

A Site frame has the orientation of the Local-Level frame and the origin the LL frame
had when it was planted, fixed to the surface. SAPP keeps the rover's position in the
current Site. Planting a new Site "attaches a new frame affixed to the Mars surface with
the same origin and orientation as the current Local-Level frame": the position resets to
the origin, which removes the error accumulated with respect to the new Site, and the Site
index increments.

To show a whole traverse in one frame (estimate and truth alike), the chain keeps where
each Site's origin lies in the mission frame, the Site 0 axes: planting at position ``p``
in Site ``k`` puts Site ``k + 1``'s origin at ``origin_k + p``. The Sites' axes all point
North-East-Down where they were planted; they differ from each other only by the turn of
the LL frame over the curved surface, ``d / R`` (3e-4 rad per km on Mars), so adding the
offsets without rotating them is good to ~0.3 m per km of separation, far below the
position knowledge of a traverse (Ali et al. 2005 requires 10 % of distance driven).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class SiteFrame:
    """Site ``index`` and its origin in the mission frame (Site 0 axes), metres, (3,)."""

    index: int
    origin_mission_m: FloatArray


class SiteChain:
    """The planted Sites of a mission, from Site 0 at the landing (or wherever it starts)."""

    def __init__(self) -> None:
        self._sites = [SiteFrame(0, np.zeros(3))]

    def state(self) -> dict[str, Any]:
        """The Sites' origins in the mission frame, (n, 3) m, as plain data."""
        return {"origins_mission_m": np.array([s.origin_mission_m for s in self._sites])}

    def load_state(self, state: Mapping[str, Any]) -> None:
        """Load ``state()``'s output onto this chain."""
        origins = np.array(state["origins_mission_m"], dtype=np.float64).reshape(-1, 3)
        self._sites = [SiteFrame(i, origin.copy()) for i, origin in enumerate(origins)]

    @property
    def current(self) -> SiteFrame:
        """The Site frame positions are kept in now."""
        return self._sites[-1]

    def __len__(self) -> int:
        return len(self._sites)

    def site(self, index: int) -> SiteFrame:
        """Site ``index``; ``ValueError`` if it was never planted."""
        if not 0 <= index < len(self._sites):
            raise ValueError(f"index: no Site {index}; Sites 0..{len(self._sites) - 1} exist")
        return self._sites[index]

    def plant(self, p_s: ArrayLike) -> SiteFrame:
        """Plant a new Site where the rover is, ``p_s`` (3,) in the current Site, metres.

        Returns the new Site; the rover's position in it is the origin.
        """
        p = _position(p_s, "p_s")
        new = SiteFrame(self.current.index + 1, self.current.origin_mission_m + p)
        self._sites.append(new)
        return new

    def to_mission(self, p_s: ArrayLike, index: int) -> FloatArray:
        """A position in Site ``index`` (..., 3) expressed in the mission frame."""
        p = np.asarray(p_s, dtype=float)
        if p.shape[-1:] != (3,) or not np.all(np.isfinite(p)):
            raise ValueError(f"p_s: must be finite with shape (..., 3), got {p.shape}")
        out: FloatArray = p + self.site(index).origin_mission_m
        return out


def _position(p: ArrayLike, name: str) -> FloatArray:
    arr = np.asarray(p, dtype=float)
    if arr.shape != (3,) or not np.all(np.isfinite(arr)):
        raise ValueError(f"{name}: must be a finite 3-vector, got {arr!r}")
    return arr
