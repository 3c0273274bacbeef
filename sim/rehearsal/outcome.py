"""What one rehearsal run gives back: per sequence line, the figures the risk table gathers.

Plain data that pickles (a Dask worker returns it) and turns into JSON (``as_dict``). A run's
``*_true_*`` figures are its sampled world's truth (that world is one draw of what the ground
does not know: its truth is the prediction); its ``*_est_*`` figures are what the rover would
report in that world, to set beside what the rover does report when the sequence runs.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any

STATUSES = ("completed", "refused", "failed", "halted", "not_run")


@dataclass(frozen=True)
class StepOutcome:
    """One sequence step in one run. ``line`` is the step's line in the sequence text
    (1-based); ``status`` as ``sim.loop.session.CommandReport`` (``not_run``: an earlier
    step stopped the sequence) and ``reason`` its reason; ``start_t_s``, ``end_t_s`` when it
    started and ended (TT s);
    ``p_mission_true_m`` / ``p_mission_est_m`` the body origin at its end (North, East, m, in
    the mission frame), true (the sampled world's) and as the rover estimates it;
    ``heading_true_rad`` / ``heading_est_rad`` (from North towards East);
    ``max_tilt_true_deg`` the largest true tilt during the step; ``aqf``,
    ``imu_integration_s`` and ``position_sigma_m`` as the rover would report them at its end;
    ``hga_margin_deg`` the margin of an HGA pass (true pointing error against the beam's
    limit, deg; NaN when the step is no pass) and ``hga_margin_predicted_deg`` the rover's own
    prediction; ``keepouts_entered`` the zones the true footprint entered during the step;
    ``path_true_m`` the true traverse during the step (North, East; mission frame), thinned
    to a few points per metre (the 3D view's cloud of predicted traverses)."""

    line: int
    command: str
    status: str
    reason: str | None
    start_t_s: float
    end_t_s: float
    p_mission_true_m: tuple[float, float]
    p_mission_est_m: tuple[float, float]
    heading_true_rad: float
    heading_est_rad: float
    max_tilt_true_deg: float
    aqf: str
    imu_integration_s: float
    position_sigma_m: float
    hga_margin_deg: float = math.nan
    hga_margin_predicted_deg: float = math.nan
    keepouts_entered: tuple[str, ...] = ()
    path_true_m: tuple[tuple[float, float], ...] = ()

    def __post_init__(self) -> None:
        if self.status not in STATUSES:
            raise ValueError(f"status: must be one of {', '.join(STATUSES)}, got {self.status!r}")


@dataclass(frozen=True)
class RunOutcome:
    """One run of a campaign: its index and the seed it drew from, its steps in order, and
    the wall time it took on its worker (s, for progress estimates, never for results)."""

    run_index: int
    seed: int
    steps: tuple[StepOutcome, ...]
    wall_s: float = 0.0
    worker: str = ""
    extra: dict[str, Any] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready (NaN stays a float; the server writes it as null)."""
        return asdict(self)
