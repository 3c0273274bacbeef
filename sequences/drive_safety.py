"""The ground's look at a sequence's drives against the rover's mobility fault protection
(``estimation.protection``): where a drive's nominal path meets a keep-out zone, where a
drive may halt on its own time limits, and the drives that come after one that may halt
(after a halt the rover refuses drives until ``CLEAR_MOBILITY_FAULT``).

The walk follows the nominal path, the pose the commands would give with no slip and no
estimate error, from the rover's reported estimate (``ValidationContext.p_s_est``,
``heading_rad``), through the Sites it plants, with the zones the rover reports it holds and
those the sequence adds or clears. The keep-out margin is predicted as the rover computes it
(``estimation.protection.position_sigma``: the odometry fraction of the distance, grown from
the reported uncertainty), so a path that passes within it may halt too. The limits are the
ones the rover reports holding (``ValidationContext.mobility_limits``; the flight defaults
otherwise) as the sequence's ``SET_PARAM param=mobility.<name>`` change them. With the
ground's terrain map in the context (``ValidationContext.terrain``) each drive's nominal path
is also set down on the map and its tilt checked against the tilt limit
(``sequences.terrain_check``). Slip is not predicted here: it depends on the ground, which a
rehearsal samples.
"""

from __future__ import annotations

import contextlib
import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from estimation.protection.drive_time import past_time_of_day
from estimation.protection.keepout import KeepOutZone, parse_polygon
from estimation.protection.limits import LIMITS, MobilityLimits, replace_limit
from sequences import commands as cmd
from sequences.model import SequenceStep
from sequences.terrain_check import TiltCheck

Warn = Callable[[SequenceStep, str, str], None]
ARC_POINTS = 24  # an arc's nominal path as a polyline of this many chords


@dataclass
class _Pose:
    x_m: float
    y_m: float
    heading_rad: float  # from North towards East


@dataclass
class DriveSafety:
    """The walk of the module docstring; ``step`` is called for each step with its
    predicted start time and duration (``sequences.validate``)."""

    warn: Warn
    lmst_h: Callable[[float], float]
    pose: _Pose | None = None
    site_index: int = 0
    sigma_m: float = 0.0
    zones: dict[str, tuple[KeepOutZone, str]] = field(default_factory=dict)  # name: (zone, whence)
    site_origins: dict[int, tuple[float, float]] = field(default_factory=dict)
    may_halt: str | None = None  # "line N's drive ..." while no CLEAR_MOBILITY_FAULT came
    limits: MobilityLimits = LIMITS
    tilt: TiltCheck | None = None  # with a terrain map in the context

    @classmethod
    def start(cls, warn: Warn, context: Any) -> DriveSafety:
        """From a ``ValidationContext``: the pose, zones, uncertainty and fault it reports."""
        p, heading = getattr(context, "p_s_est", None), getattr(context, "heading_rad", None)
        site = int(getattr(context, "site_index", 0))
        walk = cls(warn, context.lmst_h, site_index=site)
        limits = getattr(context, "mobility_limits", None)
        if isinstance(limits, MobilityLimits):
            walk.limits = limits
        walk.tilt = TiltCheck.start(warn, context)
        if p is not None and heading is not None:
            walk.pose = _Pose(float(p[0]), float(p[1]), float(heading))
        walk.site_origins[site] = (0.0, 0.0)
        walk.sigma_m = float(getattr(context, "position_sigma_m", 0.0) or 0.0)
        for zone in getattr(context, "keepout_zones", ()):
            walk.zones[zone.name] = (zone, "held by the rover")
        fault = getattr(context, "mobility_fault", None)
        if fault:
            walk.may_halt = f"the rover's mobility is disabled since a halt ({fault})"
        return walk

    def step(self, step: SequenceStep, start_t_s: float, duration_s: float) -> None:
        c = step.command
        if isinstance(c, cmd.KeepoutAdd):
            self._add_zone(step, c)
        elif isinstance(c, cmd.KeepoutClear):
            names = list(self.zones) if c.zone == "all" else [c.zone]
            for name in names:
                self.zones.pop(name, None)
        elif isinstance(c, cmd.ClearMobilityFault):
            self.may_halt = None
        elif isinstance(c, cmd.PlantSite):
            self._plant()
        elif isinstance(c, cmd.SetParam) and c.param.startswith("mobility."):
            with contextlib.suppress(ValueError):  # the dictionary reported it
                self.limits = replace_limit(self.limits, c.param.removeprefix("mobility."), c.value)
        elif isinstance(c, cmd.DriveStraight | cmd.DriveArc | cmd.TurnInPlace | cmd.DriveTo):
            self._drive(step, c, start_t_s, duration_s)

    # ---- the steps -----------------------------------------------------------------------

    def _add_zone(self, step: SequenceStep, c: cmd.KeepoutAdd) -> None:
        if c.polygon_m is not None:
            zone = KeepOutZone.polygon(c.zone, self.site_index, parse_polygon(c.polygon_m))
        else:
            assert c.x_m is not None and c.y_m is not None and c.radius_m is not None
            zone = KeepOutZone.circle(c.zone, self.site_index, c.x_m, c.y_m, c.radius_m)
        self.zones[c.zone] = (zone, f"added at line {step.line}" if step.line else "added")

    def _plant(self) -> None:
        origin = self.site_origins.get(self.site_index)
        self.site_index += 1
        if self.pose is None or origin is None:
            self.site_origins.pop(self.site_index, None)
            return
        self.site_origins[self.site_index] = (origin[0] + self.pose.x_m, origin[1] + self.pose.y_m)
        self.pose = _Pose(0.0, 0.0, self.pose.heading_rad)

    def _drive(self, step: SequenceStep, c: Any, start_t_s: float, duration_s: float) -> None:
        line = f"line {step.line}" if step.line else "an earlier step"
        if self.may_halt is not None:
            self.warn(
                step,
                "drive-after-halt",
                f"this drive follows {self.may_halt}; after a halt mobility stays disabled "
                "until CLEAR_MOBILITY_FAULT and this drive would be refused",
            )
        reasons: list[str] = []
        timeout = c.timeout_s if c.timeout_s is not None else self.limits.drive_timeout_s
        if duration_s > float(timeout):
            reasons.append(
                f"its timeout of {float(timeout):g} s (it needs about {duration_s:.0f} s)"
            )
            self.warn(step, "drive-timeout", f"the drive needs about {duration_s:.0f} s, more "
                      f"than its timeout of {float(timeout):g} s: it will halt")  # fmt: skip
        if c.lmst_limit_h is not None:
            start_h, end_h = self.lmst_h(start_t_s), self.lmst_h(start_t_s + duration_s)
            if past_time_of_day(start_h, end_h, float(c.lmst_limit_h)) or duration_s >= 88775.0:
                reasons.append("its time-of-day limit")
                self.warn(step, "lmst-limit", f"the drive runs past its time-of-day limit "
                          f"({_hm(float(c.lmst_limit_h))} LMST): it will halt")  # fmt: skip
        origin = self.site_origins.get(self.site_index)
        if self.tilt is not None and self.pose is not None and origin is not None:
            pose = (self.pose.x_m, self.pose.y_m, self.pose.heading_rad)
            tilted = self.tilt.drive(step, c, pose, origin, self.limits.tilt_limit_rad)
            if tilted is not None:
                reasons.append(tilted)
        path = self._path(c)
        if path is not None:
            for name, (zone, whence) in sorted(self.zones.items()):
                clearance, where = self._clearance(zone, path)
                if clearance is None:
                    continue
                if clearance <= 0.0:
                    reasons.append(f"keep-out zone {name}")
                    self.warn(
                        step,
                        "keepout-crossing",
                        f"the nominal path crosses keep-out zone {name} ({whence}) "
                        f"{where}: the drive will halt before it",
                    )
                elif clearance <= self.limits.keepout_k_sigma * self.sigma_m:
                    reasons.append(f"the margin of keep-out zone {name}")
            self.pose = _Pose(*path[-1], self.pose.heading_rad if self.pose else 0.0)
            self.pose.heading_rad = self._heading_after(c, path)
        if reasons:
            self.may_halt = f"{line}'s drive, which may halt on {', '.join(reasons)}"

    # ---- the nominal path ----------------------------------------------------------------

    def _path(self, c: Any) -> list[tuple[float, float]] | None:
        """The nominal path in the current Site, from the pose; ``None``: pose unknown.
        The uncertainty grows along it (``sigma_m``)."""
        pose = self.pose
        if pose is None:
            return None
        x, y, h = pose.x_m, pose.y_m, pose.heading_rad
        points = [(x, y)]
        if isinstance(c, cmd.DriveStraight):
            d = float(c.distance_m)
            points.append((x + d * math.cos(h), y + d * math.sin(h)))
        elif isinstance(c, cmd.DriveArc):
            r, a = float(c.radius_m), math.radians(float(c.angle_deg))
            sign = 1.0 if r > 0 else -1.0  # > 0 centre on the right: turning clockwise
            cx, cy = (
                x + abs(r) * math.cos(h + sign * math.pi / 2),
                y + abs(r) * math.sin(h + sign * math.pi / 2),
            )
            start = math.atan2(y - cy, x - cx)
            for k in range(1, ARC_POINTS + 1):
                ang = start + sign * a * k / ARC_POINTS
                points.append((cx + abs(r) * math.cos(ang), cy + abs(r) * math.sin(ang)))
        elif isinstance(c, cmd.DriveTo):
            points.append((float(c.x_m), float(c.y_m)))
        length = sum(math.dist(a, b) for a, b in itertools.pairwise(points))
        self.sigma_m = math.hypot(self.sigma_m, self.limits.odometry_sigma_fraction * length)
        return points

    def _heading_after(self, c: Any, path: list[tuple[float, float]]) -> float:
        h = self.pose.heading_rad if self.pose else 0.0
        if isinstance(c, cmd.TurnInPlace):
            return h + math.radians(float(c.angle_deg))
        if isinstance(c, cmd.DriveArc):
            return h + math.copysign(math.radians(float(c.angle_deg)), float(c.radius_m))
        if isinstance(c, cmd.DriveTo) and len(path) > 1:
            (x0, y0), (x1, y1) = path[0], path[-1]
            return math.atan2(y1 - y0, x1 - x0) if (x0, y0) != (x1, y1) else h
        return h

    def _clearance(
        self, zone: KeepOutZone, path: list[tuple[float, float]]
    ) -> tuple[float | None, str]:
        """The path's least clearance from ``zone`` (in the zone's Site), and where."""
        here, there = self.site_origins.get(self.site_index), self.site_origins.get(zone.site_index)
        if here is None or there is None:
            return None, ""  # the Sites' offsets are not known to the ground
        dx, dy = here[0] - there[0], here[1] - there[1]
        shifted = [(x + dx, y + dy) for x, y in path]
        if len(shifted) == 1:
            return zone.clearance_m(shifted[0]), "where it turns"
        chords = list(itertools.pairwise(shifted))
        best = min(zone.path_clearance_m(a, b) for a, b in chords)
        if best > 0.0:
            return best, ""
        along = 0.0
        for i, (a, b) in enumerate(chords):
            if zone.path_clearance_m(a, b) <= 0.0:
                t = _entry(zone, a, b)
                (x0, y0), (x1, y1) = path[i], path[i + 1]
                x, y = x0 + t * (x1 - x0), y0 + t * (y1 - y0)
                along += t * math.dist(a, b)
                break
            along += math.dist(a, b)
        return best, (
            f"(entering it {along:.2f} m from the drive's start, at ({x:.1f}, {y:.1f}) m "
            f"in Site {self.site_index})"
        )


def _entry(zone: KeepOutZone, a: tuple[float, float], b: tuple[float, float]) -> float:
    """Where along the chord ``a``-``b`` (0 to 1) it first meets ``zone``, to a millimetre or
    so: the clearance of the part ``a``-``a + t (b - a)`` only shrinks as ``t`` grows."""
    if zone.clearance_m(a) <= 0.0:
        return 0.0
    lo, hi = 0.0, 1.0
    for _ in range(20):
        mid = 0.5 * (lo + hi)
        end = (a[0] + mid * (b[0] - a[0]), a[1] + mid * (b[1] - a[1]))
        lo, hi = (lo, mid) if zone.path_clearance_m(a, end) <= 0.0 else (mid, hi)
    return hi


def _hm(hours: float) -> str:
    minutes = round(hours * 60.0) % (24 * 60)
    return f"{minutes // 60:02d}:{minutes % 60:02d}"
