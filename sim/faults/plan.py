"""A rover's fault plan: the conductor's faults, scheduled, applied, and revealed.

``FaultPlan`` keeps each fault with its id, the simulation time it is due (``at_t_s``), the
time it was applied (``applied_t_s``, ``None`` while pending) and whether the conductor has
revealed it for the debrief. The session applies the faults that are due at the start of
each command it executes (``RoverSession.execute``): a fault takes effect at the first
command, or the runtime's first idle step (at most ``IDLE_STEP_S``, 10 s, apart at a finite
clock speed), that starts at or after its time; a command running when it falls due runs to
its end unfaulted. Each fault applied adds an event (kind ``fault``) to the next truth
record (``FrameRecorder.truth_events``), never to the downlink: the rover reports only what
its sensors then measure.

The effects, on the simulator's truth and sensors only (``apply_fault``): gyro and
accelerometer bias steps on the IMU (``Ln200Imu.add_bias_step``), failed Navcams, Pancam
dust and a stuck HGA on the hardware's condition (``sim.faults.condition``); a sand trap as a
soil patch (``RoverSim.add_soil_patch``, ``sim.world.soil_patches.sand_trap``) and a failed or
stalled wheel motor as a wheel dragged on every drive (``RoverSim.failed_wheel``).

The server's request threads add and reveal while the clock thread applies, so the plan
holds a lock of its own; its ``state()`` is plain data, part of the session's checkpoint.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Mapping
from dataclasses import replace
from typing import TYPE_CHECKING, Any

import numpy as np

from estimation.events import Event
from estimation.ivp import earth_ll
from estimation.sapp.hga_pointing import point_hga
from sim.errors import InputError
from sim.faults.records import (
    AXES,
    AccelBias,
    Fault,
    GyroBias,
    HgaStuck,
    NavcamFailure,
    PancamDust,
    SandTrap,
    ScheduledFault,
    WheelFault,
)
from sim.sensors.imu import DEG_PER_H_TO_RAD_S, STANDARD_GRAVITY_M_S2
from sim.world.soil_patches import sand_trap

if TYPE_CHECKING:
    from sim.loop.context import LoopContext


class FaultPlan:
    """A rover's faults (module docstring)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._entries: list[ScheduledFault] = []

    def add(self, fault: Fault, at_t_s: float) -> ScheduledFault:
        """Schedule ``fault`` at ``at_t_s`` (TT s; a time already past: at once)."""
        if not isinstance(fault, Fault):
            raise InputError("fault", f"must be a sim.faults.records.Fault, got {fault!r}")
        if not math.isfinite(at_t_s):
            raise InputError("at_t_s", f"must be finite, got {at_t_s}")
        with self._lock:
            entry = ScheduledFault(len(self._entries) + 1, fault, float(at_t_s))
            self._entries.append(entry)
            return entry

    def entries(self) -> list[ScheduledFault]:
        """Every fault, in the order added."""
        with self._lock:
            return list(self._entries)

    def reveal(self) -> int:
        """Mark every fault revealed (the debrief); returns how many were not yet."""
        with self._lock:
            fresh = sum(1 for e in self._entries if not e.revealed)
            self._entries = [replace(e, revealed=True) for e in self._entries]
            return fresh

    def apply_due(self, loop: LoopContext) -> list[ScheduledFault]:
        """Apply the faults due by the simulator's clock now; each adds a truth event."""
        now = loop.sim.t_s
        with self._lock:
            due = [e for e in self._entries if not e.applied and e.at_t_s <= now + 1e-6]
        done = []
        for entry in due:
            try:
                apply_fault(entry.fault, loop)
            except InputError as exc:
                entry = replace(entry, applied_t_s=now, error=str(exc))
                text = f"fault #{entry.fault_id} not applied: {exc}"
            else:
                entry = replace(entry, applied_t_s=now)
                text = f"fault #{entry.fault_id} injected: {entry.fault.describe()}"
            loop.recorder.truth_events.append(Event(text, "fault", "warning"))
            with self._lock:
                self._entries = [
                    replace(entry, revealed=e.revealed) if e.fault_id == entry.fault_id else e
                    for e in self._entries
                ]
            done.append(entry)
        return done

    def state(self) -> list[dict[str, Any]]:
        """Plain data (the session's checkpoint)."""
        with self._lock:
            return [e.as_dict() for e in self._entries]

    def load_state(self, state: list[Mapping[str, Any]]) -> None:
        """Load ``state()``."""
        with self._lock:
            self._entries = [ScheduledFault.from_dict(e) for e in state]


def apply_fault(fault: Fault, loop: LoopContext) -> None:
    """The fault's effect on the simulator's truth and sensors now (module docstring)."""
    sim = loop.sim
    if isinstance(fault, GyroBias):
        step = _axis(fault.axis) * fault.bias_deg_per_h * DEG_PER_H_TO_RAD_S
        sim.imu.add_bias_step(gyro_rad_s=step)
    elif isinstance(fault, AccelBias):
        step = _axis(fault.axis) * fault.bias_ug * 1e-6 * STANDARD_GRAVITY_M_S2
        sim.imu.add_bias_step(accel_m_s2=step)
    elif isinstance(fault, NavcamFailure):
        sim.condition.navcam_failed = True
    elif isinstance(fault, PancamDust):
        sim.condition.pancam_tau = fault.tau
    elif isinstance(fault, HgaStuck):
        if sim.condition.hga_stuck_rad is None:  # stuck already: it stays where it stuck
            # the angles the rover commands now (sim.loop.frames: from its estimate and IVP)
            command = point_hga(loop.nate.q_b_ll, earth_ll(sim.t_s, sim.lat_rad,
                                                           sim.lon_east_rad))  # fmt: skip
            sim.condition.hga_stuck_rad = (float(command.az_rad), float(command.el_rad))
    elif isinstance(fault, SandTrap):
        origin = loop.recorder.scorer.site_origins_true[0]  # the mission frame's, true
        centre = (float(origin[0]) + fault.x_m, float(origin[1]) + fault.y_m)
        patch = sand_trap(centre[0], centre[1], fault.radius_m)
        sim.add_soil_patch(f"sand trap at {fault.x_m:g}, {fault.y_m:g} m", patch)
    elif isinstance(fault, WheelFault):  # stalled or failed, the motor gives no torque: dragged
        sim.failed_wheel = fault.wheel.lower()
    else:  # a kind added to the records without its effect
        raise InputError("kind", f"{fault.kind} has no effect in sim.faults.plan")


def _axis(axis: str) -> np.ndarray:
    out = np.zeros(3)
    out[AXES.index(axis)] = 1.0
    return out
