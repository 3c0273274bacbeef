"""Mobility fault protection onboard: the checks of a drive, and the fault latch.

The rover keeps, between commands, its mobility limits, its keep-out zones, its position
uncertainty and, after a halt, the fault that disabled mobility until the ground sends
``CLEAR_MOBILITY_FAULT`` (``MobilityProtection``). Each drive command gets a
``DriveMonitor`` with the limits it runs under (the defaults, or its own overrides) that
checks, layer by layer as MER's mobility flight software did (Biesiadecki and Maimone 2006
sec. 3):

- command limits: the drive's time budget and its time-of-day limit
  (``estimation.protection.drive_time``);
- reactive checks, every 8 Hz cycle: roll and pitch from the accelerometers, rocker and
  bogie angles from their encoders (``estimation.protection.attitude_limits``), and the
  keep-out zones against the estimated position grown by ``k`` times its 1σ
  (``estimation.protection.keepout``, ``estimation.protection.position_sigma``);
- after each VO step: the keep-out zones again on the updated position, and the slip
  check (``estimation.protection.slip_check``).

Everything here reads the flight software's own estimate and sensors, never the world's
truth: it is flight software (``estimation/`` imports nothing of the simulator).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from estimation.protection.attitude_limits import (
    first_over,
    roll_pitch_rad,
    smoothed_specific_force,
)
from estimation.protection.drive_time import lmst_h, past_time_of_day
from estimation.protection.halt import Halt
from estimation.protection.keepout import MAX_ZONES, KeepOutZone
from estimation.protection.limits import LIMITS, MobilityLimits, replace_limit
from estimation.protection.position_sigma import PositionUncertainty
from estimation.protection.slip_check import SlipWindow

FloatArray = NDArray[np.float64]
APPROACH_M = 0.005  # closer than a drive's start by this: approaching (estimate noise aside)
VoFail = Literal["halt", "continue"]


@dataclass(frozen=True)
class DriveLimits:
    """The limits one drive runs under: the rover's, with the command's overrides.
    ``lmst_limit_h`` ``None``: no time-of-day limit."""

    slip_limit: float
    vo_fail: VoFail
    timeout_s: float
    lmst_limit_h: float | None


@dataclass(frozen=True)
class Trip:
    """A check tripped at cycle ``index`` of a segment's series (0-based)."""

    index: int
    halt: Halt


class MobilityProtection:
    """The rover's mobility fault protection between commands (module docstring).
    ``lon_east_rad``: the landing site's longitude, for the time-of-day limit."""

    def __init__(self, lon_east_rad: float, limits: MobilityLimits | None = None) -> None:
        self.lon_east_rad = float(lon_east_rad)
        self.limits = limits if limits is not None else LIMITS
        self.zones: dict[str, KeepOutZone] = {}
        self.fault: Halt | None = None
        self.uncertainty = PositionUncertainty()

    # ---- checkpoint ----------------------------------------------------------------------

    def state(self) -> dict[str, Any]:
        """Plain data (a checkpoint)."""
        return {
            "limits": {k: getattr(self.limits, k) for k in self.limits.__dataclass_fields__},
            "zones": [z.as_dict() for z in self.zones.values()],
            "fault": None if self.fault is None else self.fault.as_dict(),
            "uncertainty": self.uncertainty.state(),
        }

    def load_state(self, state: Mapping[str, Any]) -> None:
        self.limits = MobilityLimits(**dict(state["limits"]))
        self.zones = {z["name"]: KeepOutZone.from_dict(z) for z in state["zones"]}
        self.fault = None if state["fault"] is None else Halt.from_dict(state["fault"])
        self.uncertainty.load_state(state["uncertainty"])

    # ---- the ground's commands -------------------------------------------------------------

    def set_limit(self, name: str, value: object) -> None:
        """``SET_PARAM param=mobility.<name>``; ``ValueError`` naming it, nothing changed."""
        self.limits = replace_limit(self.limits, name, value)

    def add_zone(self, zone: KeepOutZone) -> None:
        """``KEEPOUT_ADD``: a zone (one of the same name is replaced)."""
        if zone.name not in self.zones and len(self.zones) >= MAX_ZONES:
            raise ValueError(f"name: the table holds {MAX_ZONES} zones; clear one first")
        self.zones[zone.name] = zone

    def clear_zones(self, name: str) -> list[str]:
        """``KEEPOUT_CLEAR``: the zone ``name``, or ``all``; the names cleared."""
        if name == "all":
            cleared = sorted(self.zones)
            self.zones = {}
            return cleared
        if name not in self.zones:
            known = ", ".join(sorted(self.zones)) or "none"
            raise ValueError(f"name: no keep-out zone {name!r} (zones: {known})")
        del self.zones[name]
        return [name]

    def clear_fault(self) -> Halt | None:
        """``CLEAR_MOBILITY_FAULT``: mobility enabled again; the fault it cleared."""
        fault, self.fault = self.fault, None
        return fault

    def require_enabled(self, command: str) -> None:
        """``ValueError`` when a halt has disabled mobility."""
        if self.fault is not None:
            raise ValueError(
                f"{command}: mobility disabled since a halt ({self.fault.reason}); "
                "send CLEAR_MOBILITY_FAULT first"
            )

    def drive_limits(
        self,
        slip_limit: float | None = None,
        vo_fail: str | None = None,
        timeout_s: float | None = None,
        lmst_limit_h: float | None = None,
    ) -> DriveLimits:
        """The limits of a drive: the command's where it gives them, else the rover's."""
        vo = "halt" if vo_fail is None else vo_fail
        if vo not in ("halt", "continue"):
            raise ValueError(f"vo_fail: must be halt or continue, got {vo_fail!r}")
        return DriveLimits(
            slip_limit=self.limits.slip_limit if slip_limit is None else float(slip_limit),
            vo_fail="halt" if vo == "halt" else "continue",
            timeout_s=self.limits.drive_timeout_s if timeout_s is None else float(timeout_s),
            lmst_limit_h=lmst_limit_h,
        )

    def begin_drive(
        self, t_s: float, heading_3sigma_rad: float, limits: DriveLimits
    ) -> DriveMonitor:
        """A drive command starts now (``t_s``) with its ``limits``."""
        self.uncertainty.begin_drive(heading_3sigma_rad)
        return DriveMonitor(self, t_s, limits)


class DriveMonitor:
    """The checks of one drive command (module docstring)."""

    def __init__(self, protection: MobilityProtection, t_s: float, limits: DriveLimits) -> None:
        self.protection = protection
        self.limits = limits
        self.t_start_s = float(t_s)
        self.lmst_start_h = lmst_h(t_s, protection.lon_east_rad)
        self.window = SlipWindow()
        # each zone's clearance when the drive first checked it: a drive that starts within
        # a zone's margin (after a halt there) may move away, and halts only if it comes
        # closer than that
        self.start_clearance_m: dict[str, float] = {}

    @property
    def margin_m(self) -> float:
        """The keep-out margin now: ``k`` times the position's 1σ."""
        p = self.protection
        return p.limits.keepout_k_sigma * p.uncertainty.sigma_m

    def check_cycles(
        self,
        t_s: FloatArray,
        p_zone_s: Mapping[str, FloatArray],
        step_m: FloatArray,
        delta_velocity_b: FloatArray,
        dt_s: FloatArray,
        rocker_rad: FloatArray,
        bogie_rad: FloatArray,
        p_s: FloatArray,
    ) -> Trip | None:
        """The first cycle of a segment (N cycles) at which a check trips, or ``None``.

        ``t_s`` (N,) the cycles' times; ``p_zone_s`` each zone's name to the estimated
        positions (N, 2 or 3) in that zone's Site; ``step_m`` (N,) the odometry distance of
        each cycle; ``delta_velocity_b``, ``dt_s`` the IMU's (N, 3), (N,); ``rocker_rad``
        (N,), ``bogie_rad`` (N, 2) the suspension encoders; ``p_s`` (N, 3) the estimated
        positions in the current Site (where a halt is reported)."""
        p = self.protection
        n = len(t_s)
        sigma = np.atleast_1d(
            p.uncertainty.sigma_at(np.cumsum(step_m), p.limits.odometry_sigma_fraction)
        )
        first: list[Trip] = []

        def at(k: int, check: str, reason: str, values: dict[str, float]) -> None:
            first.append(Trip(k, Halt(check, reason, values, float(t_s[k]), _xyz(p_s[k]))))

        elapsed = np.asarray(t_s, dtype=np.float64) - self.t_start_s
        over = np.flatnonzero(elapsed > self.limits.timeout_s)
        if over.size:
            k = int(over[0])
            at(
                k,
                "timeout",
                f"drive timeout: {elapsed[k]:.0f} s > {self.limits.timeout_s:.0f} s",
                {"elapsed_s": float(elapsed[k]), "timeout_s": self.limits.timeout_s},
            )
        limit_h = self.limits.lmst_limit_h
        if limit_h is not None:
            k_lmst = self._first_past_lmst(t_s, limit_h)
            if k_lmst is not None:
                now = lmst_h(float(t_s[k_lmst]), p.lon_east_rad)
                at(
                    k_lmst,
                    "lmst",
                    f"time-of-day limit: {_hm(now)} LMST past {_hm(limit_h)}",
                    {"lmst_h": now, "limit_lmst_h": limit_h},
                )
        roll, pitch = roll_pitch_rad(smoothed_specific_force(delta_velocity_b, dt_s))
        worst = np.maximum(np.abs(roll), np.abs(pitch))
        k_tilt = first_over(worst, p.limits.tilt_limit_rad)
        if k_tilt is not None:
            r, q = float(roll[k_tilt]), float(pitch[k_tilt])
            at(
                k_tilt,
                "tilt",
                f"tilt limit: roll {math.degrees(r):.1f} deg, pitch {math.degrees(q):.1f} deg "
                f"> {math.degrees(p.limits.tilt_limit_rad):.1f} deg",
                {"roll_rad": r, "pitch_rad": q, "limit_rad": p.limits.tilt_limit_rad},
            )
        k_rocker = first_over(rocker_rad, p.limits.rocker_limit_rad)
        bogie_worst = np.max(np.abs(np.asarray(bogie_rad).reshape(n, -1)), axis=1)
        k_bogie = first_over(bogie_worst, p.limits.bogie_limit_rad)
        for k_s, name, values, limit in (
            (k_rocker, "rocker", rocker_rad, p.limits.rocker_limit_rad),
            (k_bogie, "bogie", bogie_worst, p.limits.bogie_limit_rad),
        ):
            if k_s is not None:
                angle = float(np.abs(values[k_s]))
                at(
                    k_s,
                    "suspension",
                    f"suspension limit: {name} {math.degrees(angle):.1f} deg "
                    f"> {math.degrees(limit):.1f} deg",
                    {f"{name}_rad": angle, "limit_rad": limit},
                )
        k_sigma = p.limits.keepout_k_sigma
        for name, positions in p_zone_s.items():
            zone = p.zones[name]
            for k in range(n):
                clearance = zone.clearance_m((float(positions[k][0]), float(positions[k][1])))
                margin = k_sigma * float(sigma[k])
                start = self.start_clearance_m.setdefault(name, clearance)
                if clearance <= margin and clearance < start - APPROACH_M:
                    at(
                        k,
                        "keepout",
                        f"keep-out zone {name}: {clearance:.2f} m away, within the margin "
                        f"{margin:.2f} m ({k_sigma:g} x position 1-sigma {sigma[k]:.2f} m)",
                        {"clearance_m": clearance, "margin_m": margin, "sigma_m": float(sigma[k])},
                    )
                    break
        if not first:
            return None
        return min(first, key=lambda trip: trip.index)

    def _first_past_lmst(self, t_s: FloatArray, limit_h: float) -> int | None:
        lon = self.protection.lon_east_rad
        for k, t in enumerate(np.asarray(t_s, dtype=np.float64)):
            if past_time_of_day(self.lmst_start_h, lmst_h(float(t), lon), limit_h):
                return k
        return None

    def sigma_along(self, step_m: FloatArray) -> FloatArray:
        """The position's 1σ at each of a segment's cycles (``step_m`` (N,), m each)."""
        p = self.protection
        sigma = p.uncertainty.sigma_at(np.cumsum(step_m), p.limits.odometry_sigma_fraction)
        out: FloatArray = np.atleast_1d(np.asarray(sigma, dtype=np.float64))
        return out

    def drove(self, distance_m: float) -> None:
        """A segment's (or its cut part's) odometry distance, m, grows the uncertainty."""
        p = self.protection
        p.uncertainty.drove(distance_m, p.limits.odometry_sigma_fraction)

    def check_zones_now(
        self, t_s: float, p_zone_s: Mapping[str, FloatArray], p_s: FloatArray
    ) -> Halt | None:
        """The keep-out check on the position now (after a VO update)."""
        p = self.protection
        margin = self.margin_m
        for name, position in p_zone_s.items():
            clearance = p.zones[name].clearance_m((float(position[0]), float(position[1])))
            start = self.start_clearance_m.setdefault(name, clearance)
            if clearance <= margin and clearance < start - APPROACH_M:
                return Halt(
                    "keepout",
                    f"keep-out zone {name}: {clearance:.2f} m away after the VO update, within "
                    f"the margin {margin:.2f} m",
                    {
                        "clearance_m": clearance,
                        "margin_m": margin,
                        "sigma_m": p.uncertainty.sigma_m,
                    },
                    t_s,
                    _xyz(p_s),
                )
        return None

    def after_vo_step(
        self, t_s: float, p_s: FloatArray, commanded_m: float, wheel_m: float, vo_m: float | None
    ) -> Halt | None:
        """A VO step's motions (``vo_m`` ``None``: VO failed); the slip check when due, and
        the halt on too many failures in a row when the command says ``vo_fail=halt``."""
        p, window = self.protection, self.window
        window.add_step(commanded_m, wheel_m, vo_m)
        failures = window.failures_in_row
        too_many = failures >= p.limits.vo_max_failures_in_row and vo_m is None
        if too_many and self.limits.vo_fail == "halt":
            return Halt(
                "vo_fail",
                f"VO failed {failures} steps in a row: slip unknown (vo_fail=halt)",
                {"failures_in_row": float(failures)},
                t_s,
                _xyz(p_s),
            )
        if not window.due(p.limits.slip_check_m):
            return None
        slip = window.slip()
        commanded = window.commanded_m
        window.restart()
        if slip is not None and slip > self.limits.slip_limit:
            return Halt(
                "slip",
                f"slip check: slip {100 * slip:.1f} % over {commanded:.2f} m "
                f"> limit {100 * self.limits.slip_limit:.0f} %",
                {"slip": slip, "slip_limit": self.limits.slip_limit, "commanded_m": commanded},
                t_s,
                _xyz(p_s),
            )
        return None


def _xyz(p: Any) -> tuple[float, float, float]:
    a = np.asarray(p, dtype=np.float64).ravel()
    return (float(a[0]), float(a[1]), float(a[2]) if a.size > 2 else 0.0)


def _hm(hours: float) -> str:
    minutes = round(hours * 60.0) % (24 * 60)
    return f"{minutes // 60:02d}:{minutes % 60:02d}"
