"""The mobility limits the ground sets, and their defaults.

MER's mobility flight software layered its checks (Biesiadecki and Maimone 2006, "The Mars
Exploration Rover surface mobility flight software: driving ambition", sec. 3): command
limits (a drive's time and extent), reactive checks (tilt, suspension, motor current) and
predictive ones from stereo. The limits here are the ground's dials on the first two
layers; ``SET_PARAM param=mobility.<name>`` sets one (``replace_limit``), in Idle, and a
drive command may override ``slip_limit``, ``vo_fail``, ``timeout_s`` and ``lmst_limit_h``
for itself (``sequences.commands``).

Defaults, and where they come from:

- ``slip_check_m`` 5 m and ``slip_limit`` 0.40: Opportunity's drives after the Purgatory
  dune (sol 446) stopped for a slip check about every 5 m; on sol 603 the limit was 40 %
  and the rover stopped after its first 5 m segment at 44.5 % (the MER mission's sol
  reports; Biesiadecki and Maimone 2006 sec. 6). Drivers used 30 % and 70 % too.
- ``vo_max_failures_in_row`` 3: approximate (no public MER figure): three failed VO steps
  in a row leave the slip of about 2 m of driving unknown.
- ``keepout_k_sigma`` 2: the keep-out check grows the onboard position by k times its 1σ
  uncertainty (``estimation.protection.position_sigma``); 2σ is a documented choice.
- ``tilt_limit_rad`` 30 deg: MER-class (the vehicle is statically stable to 45 deg; drives
  were capped near 30 deg, Biesiadecki and Maimone 2006 sec. 3.2).
- ``rocker_limit_rad`` 25 deg, ``bogie_limit_rad`` 45 deg: about three quarters of the
  rocker-bogie's joint travel (the simulated rover's approximate stops are ±35 deg and
  ±60 deg; Lindemann and Voorhees 2005 give the design, not the stops): approximate. At
  30 deg the bogies tripped on Gusev's rocks in ordinary 15 m drives (``roverops bench
  faults``, the gyro case, 8 of 30 runs).
- ``drive_timeout_s`` 43200 s: a drive command's default time budget, half an Earth day:
  longer than the longest drive the dictionary allows (100 m in VO steps, about 6.3 h with
  VO's stands), so that only a drive's own ``timeout_s`` is a real budget (approximate).
- ``odometry_sigma_fraction`` 0.03: the 1σ of wheel odometry's position error as a fraction
  of the distance driven (``estimation.protection.position_sigma``). MER's requirement was
  10 % of the distance (Ali et al. 2005 sec. 1); 3 % takes it as about 3σ (approximate).
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from dataclasses import dataclass
from typing import Any, Literal

from estimation.checks import is_real_number

VoFailPolicy = Literal["halt", "continue"]


@dataclass(frozen=True)
class LimitSpec:
    """One limit's unit and closed range (SI), as the validator and the console show it."""

    unit: str
    lo: float
    hi: float
    integer: bool = False
    note: str = ""


SPECS: dict[str, LimitSpec] = {
    "keepout_k_sigma": LimitSpec("", 0.0, 10.0, note="keep-out margin in position 1σ"),
    "slip_check_m": LimitSpec("m", 0.5, 50.0, note="commanded motion between slip checks"),
    "slip_limit": LimitSpec("", 0.0, 1.0, note="slip above which a VO drive halts"),
    "vo_max_failures_in_row": LimitSpec("", 1, 100, integer=True, note="VO failures: slip unknown"),
    "tilt_limit_rad": LimitSpec("rad", 0.0, math.radians(45.0), note="roll or pitch"),
    "rocker_limit_rad": LimitSpec("rad", 0.0, math.radians(45.0), note="|rocker angle|"),
    "bogie_limit_rad": LimitSpec("rad", 0.0, math.radians(60.0), note="|bogie angle|"),
    "drive_timeout_s": LimitSpec("s", 1.0, 86400.0, note="a drive's default time budget"),
    "odometry_sigma_fraction": LimitSpec("", 0.0, 1.0, note="odometry 1σ per m driven"),
}


@dataclass(frozen=True)
class MobilityLimits:
    """The ground-settable mobility limits (module docstring: defaults and sources)."""

    keepout_k_sigma: float = 2.0
    slip_check_m: float = 5.0
    slip_limit: float = 0.40
    vo_max_failures_in_row: int = 3
    tilt_limit_rad: float = math.radians(30.0)
    rocker_limit_rad: float = math.radians(25.0)
    bogie_limit_rad: float = math.radians(45.0)
    drive_timeout_s: float = 43200.0
    odometry_sigma_fraction: float = 0.03

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            check_limit(f.name, getattr(self, f.name))


def check_limit(name: str, value: object) -> None:
    """``ValueError`` naming ``name`` unless ``value`` is a number within its spec."""
    spec = SPECS.get(name)
    if spec is None:
        raise ValueError(f"mobility.{name}: no such limit (here: {', '.join(sorted(SPECS))})")
    if not is_real_number(value):
        raise ValueError(f"mobility.{name}: must be a number, got {value!r}")
    assert isinstance(value, numbers.Real)
    number = float(value)
    if spec.integer and not float(number).is_integer():
        raise ValueError(f"mobility.{name}: must be a whole number, got {value!r}")
    if not (math.isfinite(number) and spec.lo <= number <= spec.hi):
        unit = f" {spec.unit}" if spec.unit else ""
        raise ValueError(
            f"mobility.{name}: must be in [{spec.lo:g}, {spec.hi:g}]{unit}, got {value!r}"
        )


def replace_limit(limits: MobilityLimits, name: str, value: object) -> MobilityLimits:
    """``limits`` with ``name`` (no ``mobility.`` prefix) set to ``value``, checked."""
    check_limit(name, value)
    spec = SPECS[name]
    assert isinstance(value, numbers.Real)
    number = float(value)
    changes: dict[str, Any] = {name: int(number) if spec.integer else number}
    return dataclasses.replace(limits, **changes)


LIMITS = MobilityLimits()  # the defaults
