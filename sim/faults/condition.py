"""The faulted condition of the simulated hardware: what the sensors and the scorer read.

A ``RoverSim`` carries one (``RoverSim.condition``); ``sim.faults.plan`` sets it when a fault
is applied. Healthy by default, and then nothing anywhere changes: each reader takes its
healthy path (the downlink and the truth are byte for byte those of a simulator without
faults, ``tests/sim/faults``).

- ``navcam_failed``: the Navcams give no image (``RoverSim.navcam_pair`` raises
  ``NavcamFailedError``, which a VO drive counts as a failed step);
- ``pancam_tau``: the optical depth of dust between the sun and the Pancam's detector
  (``sim.sensors.pancam.render_sun_image``'s ``dust_slant_tau`` along the line of sight);
- ``hga_stuck_rad``: the HGA gimbal's true (azimuth, elevation), rad, when it is stuck
  (the scorer scores these angles instead of those the rover commands).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from sim.errors import InputError


class NavcamFailedError(InputError):
    """The Navcams gave no image (a failed Navcam, ``sim.faults``)."""

    def __init__(self) -> None:
        super().__init__("navcam", "no image: the Navcams have failed")


@dataclass
class FaultCondition:
    """The hardware's faulted state (module docstring); healthy as made."""

    navcam_failed: bool = False
    pancam_tau: float = 0.0
    hga_stuck_rad: tuple[float, float] | None = None

    @property
    def healthy(self) -> bool:
        """No fault in effect."""
        return self == FaultCondition()

    def state(self) -> dict[str, Any]:
        """Plain data (checkpoints)."""
        stuck = None if self.hga_stuck_rad is None else list(self.hga_stuck_rad)
        return {"navcam_failed": self.navcam_failed, "pancam_tau": self.pancam_tau,
                "hga_stuck_rad": stuck}  # fmt: skip

    def load_state(self, state: Mapping[str, Any]) -> None:
        """Load ``state()``."""
        self.navcam_failed = bool(state["navcam_failed"])
        self.pancam_tau = float(state["pancam_tau"])
        stuck = state["hga_stuck_rad"]
        self.hga_stuck_rad = None if stuck is None else (float(stuck[0]), float(stuck[1]))
