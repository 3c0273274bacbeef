"""The side estimators of a session as one group: which run (``--estimators``), their drive
through each segment beside SAPP, and their pose in each telemetry frame
(``sim.loop.side.kinematic``, ``sim.loop.side.radio``)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from estimation.events import Event
from estimation.sapp.nate import NateSeries
from sim.errors import InputError
from sim.loop.downlink import ESTIMATORS
from sim.loop.rover_sim import RoverSim, Segment
from sim.loop.side.kinematic import (
    DriveInputs,
    KinematicEkfRunner,
    SideEstimate,
    SideRunner,
)
from sim.loop.side.radio import RadioEkfRunner

FloatArray = NDArray[np.float64]
Pose = tuple[FloatArray, FloatArray | None]


class SideEstimators:
    """The estimators that run beside SAPP (``estimators``: names from ``ESTIMATORS``, SAPP
    among them), in that order. A runner that fails stops, with an event saying why."""

    def __init__(
        self, sim: RoverSim, seed: int, x_m: float, y_m: float, estimators: Sequence[str]
    ) -> None:
        unknown = [e for e in estimators if e not in ESTIMATORS]
        if unknown or "sapp" not in estimators:
            raise InputError(
                "estimators", f"must include sapp, from {', '.join(ESTIMATORS)}; got {estimators!r}"
            )
        self.sim = sim
        self.runners: list[SideRunner] = []
        if "kinematic_ekf" in estimators:
            self.runners.append(KinematicEkfRunner(sim, seed))
        if "radio_ekf" in estimators:
            self.runners.append(RadioEkfRunner(sim, seed, x_m, y_m))
        # the poses of the drive segment whose frames are being made (None: at rest)
        self._in_segment: dict[str, Pose] | None = None

    def drive(
        self,
        seg: Segment,
        kind: str,
        args: tuple[float, ...],
        start: tuple[FloatArray, FloatArray],
        series: NateSeries,
        events: list[Event],
    ) -> dict[str, SideEstimate]:
        """Every runner through a drive segment; ``start`` SAPP's ``(p_mission, q_b_ll)``
        before it and ``series`` its cycles through it."""
        if not self.runners:
            return {}
        inputs = DriveInputs(
            kind=kind,
            args=args,
            wheel_rad=self.sim.encoders.wheel_angle_rad(seg.encoders.wheel_counts),
            steer_rad=seg.encoders.steer_rad,
            start=start,
            sapp_q_b_ll=np.vstack([start[1], series.q_b_ll]),
        )
        out: dict[str, SideEstimate] = {}
        for runner in list(self.runners):
            try:
                out[runner.name] = runner.drive(seg, inputs)
            except ValueError as exc:  # InputError and numpy's LinAlgError are ValueErrors
                # The rover has driven and SAPP has its result: a comparison estimator that
                # fails must not turn the drive into a refusal. It stops, and says why.
                self.runners.remove(runner)
                events.append(Event(f"{runner.name} stopped: {exc}", "estimator", "warning"))
        return out

    def at_sample(self, side: Mapping[str, SideEstimate] | None, i: int = 0) -> None:
        """Frames from now on are of sample ``i`` of the segment estimates ``side`` (``None``:
        of the rover at rest)."""
        if side is None:
            self._in_segment = None
            return
        self._in_segment = {
            n: (e.p_mission[i], None if e.q_b_ll is None else e.q_b_ll[i]) for n, e in side.items()
        }

    def frame_poses(self, t_s: float) -> dict[str, Pose]:
        """Each runner's pose ``(p_mission, q_b_ll or None)`` in the frame at ``t_s`` (a
        runner not started yet has none: it starts at the first drive). Their errors are the
        scorer's (``sim.scoring.scorer``)."""
        out: dict[str, Pose] = {}
        for runner in self.runners:
            if self._in_segment is None:  # at rest, up to this frame's time (the simulator
                runner.rest_until(t_s, self.sim.drive_state.p_s)  # may have run a chunk ahead)
                now = runner.estimate_now()
            else:
                now = self._in_segment.get(runner.name)
            if now is not None:
                out[runner.name] = now
        return out

    def state(self) -> dict[str, Any]:
        """The runners still running, by name, each with its state (plain data)."""
        return {"runners": {r.name: r.state() for r in self.runners}}

    def load_state(self, state: Mapping[str, Any]) -> None:
        """Load ``state`` onto the group built from the same configuration: the runners
        that had stopped are dropped."""
        saved = state["runners"]
        self.runners = [r for r in self.runners if r.name in saved]
        for runner in self.runners:
            runner.load_state(saved[runner.name])
        self._in_segment = None
