"""The slip check of a VO drive: how much of the wheels' motion was real.

Between slip checks a drive goes ``slip_check_m`` of commanded motion in VO steps; the
slip over that window is::

    slip = 1 - (VO motion / wheel-odometry motion)

summed over the steps whose VO converged (a step VO could not measure says nothing of
the slip). Above ``slip_limit`` the drive halts. After Opportunity was stuck in the
Purgatory dune (sol 446) its drives stopped for such a check about every 5 m; on sol 603
the limit was 40 % and it stopped after its first 5 m segment at 44.5 % (the MER mission's
sol reports; Biesiadecki and Maimone 2006 sec. 6). When VO fails ``vo_max_failures_in_row``
steps in a row the slip is unknown, and the command says whether the drive halts or goes
on on wheel odometry (``vo_fail``).

>>> slip_fraction(vo_m=2.775, wheel_m=5.0)
0.445
"""

from __future__ import annotations

import math
from dataclasses import dataclass


def slip_fraction(vo_m: float, wheel_m: float) -> float:
    """``1 - vo_m / wheel_m``: 0 when the wheels' motion was all real, 1 when the rover
    stood still (more when it slid back: a negative ``vo_m``)."""
    if not (math.isfinite(vo_m) and math.isfinite(wheel_m)):
        raise ValueError("vo_m, wheel_m: must be finite")
    if wheel_m <= 0.0:
        raise ValueError(f"wheel_m: must be positive, got {wheel_m}")
    return round(1.0 - vo_m / wheel_m, 12)


@dataclass
class SlipWindow:
    """The motions summed since the last slip check (module docstring)."""

    commanded_m: float = 0.0
    wheel_m: float = 0.0
    vo_m: float = 0.0
    failures_in_row: int = 0

    def add_step(self, commanded_m: float, wheel_m: float, vo_m: float | None) -> None:
        """One VO step: its commanded motion, wheel odometry's and VO's (``None``: failed)."""
        self.commanded_m += commanded_m
        if vo_m is None:
            self.failures_in_row += 1
            return
        self.failures_in_row = 0
        self.wheel_m += wheel_m
        self.vo_m += vo_m

    def due(self, slip_check_m: float) -> bool:
        """Whether a slip check is due (a step may cross the mark; floats forgiven)."""
        return self.commanded_m >= slip_check_m - 1e-9

    def slip(self) -> float | None:
        """The window's slip, ``None`` when VO measured too little motion to say."""
        if self.wheel_m < 1e-3:
            return None
        return slip_fraction(self.vo_m, self.wheel_m)

    def restart(self) -> None:
        """After a check: a new window (the failures in a row carry over)."""
        self.commanded_m = self.wheel_m = self.vo_m = 0.0
