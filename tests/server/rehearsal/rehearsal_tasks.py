"""Small run functions for the campaign's tests, imported by the Dask workers by name.

``kinematic_run`` is a real, cheap rehearsal run: it parses the sequence, draws a start
around the reported estimate (its reported σ and the prior's heading σ for its AQF) and a
slip for each drive from a generator seeded by the campaign's seed and the run's index, and
dead-reckons each ``DRIVE_STRAIGHT`` (the estimate ignores slip, as wheel odometry does).
Its outcome depends on nothing else, so a campaign's result must not depend on the workers.
``failing_run`` raises at ``FAIL_AT``; ``gated_run`` waits, from run ``GATE_FROM`` on, for a
Dask ``Event`` the test sets (a run held without a timed sleep).
"""

from __future__ import annotations

import math
import os
import threading

import numpy as np

from sequences.commands import DriveStraight
from sequences.language import parse
from sim.rehearsal.inputs import RehearsalInputs
from sim.rehearsal.outcome import RunOutcome, StepOutcome

FAIL_AT = 3
GATE_FROM = 2
GATE_EVENT = "rehearsal-test-gate"
STEP_S = 60.0  # a step's duration, s
SPEED_M_S = 0.05
WARMED = {"count": 0}


def warm_up() -> None:
    """What a worker runs once before the campaign (here: it records that it ran)."""
    WARMED["count"] += 1


def warmed() -> int:
    return WARMED["count"]


def worker_settings() -> tuple[str | None, int, int, int]:
    """NUMBA_NUM_THREADS in the environment, Numba's thread count, and the nice values of
    the process and of the calling thread."""
    import numba

    return (
        os.environ.get("NUMBA_NUM_THREADS"),
        int(numba.get_num_threads()),
        os.getpriority(os.PRIO_PROCESS, 0),
        os.getpriority(os.PRIO_PROCESS, threading.get_native_id()),
    )


def kinematic_run(inputs: RehearsalInputs, run_index: int, campaign_seed: int) -> RunOutcome:
    rng = np.random.default_rng([campaign_seed, run_index])
    start = inputs.start
    sigma_m = start.position_sigma_m
    n0, e0 = start.p_mission_est[0], start.p_mission_est[1]
    p_true = np.array([n0, e0]) + sigma_m * rng.standard_normal(2)
    p_est = np.array([n0, e0])
    x, y, z, w = start.q_b_ll_est
    heading_est = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    heading_true = heading_est + inputs.priors.heading_sigma_rad(start.aqf) * rng.standard_normal()
    t_s = start.t_s
    steps = []
    for step in parse(inputs.sequence_text).steps:
        command = step.command
        t0 = t_s
        path = [(float(p_true[0]), float(p_true[1]))]
        if isinstance(command, DriveStraight):
            slip = float(np.clip(0.05 + 0.03 * rng.standard_normal(), 0.0, 0.5))
            d_true = command.distance_m * (1.0 - slip)
            for k in range(1, 5):
                f = d_true * k / 4
                path.append(
                    (
                        float(p_true[0] + f * math.cos(heading_true)),
                        float(p_true[1] + f * math.sin(heading_true)),
                    )
                )
            p_true = np.array(path[-1])
            p_est = p_est + command.distance_m * np.array(
                [math.cos(heading_est), math.sin(heading_est)]
            )
            t_s += command.distance_m / SPEED_M_S
        else:
            t_s += STEP_S
        steps.append(
            StepOutcome(
                line=step.line,
                command=command.describe(),
                status="completed",
                reason=None,
                start_t_s=t0,
                end_t_s=t_s,
                p_mission_true_m=(float(p_true[0]), float(p_true[1])),
                p_mission_est_m=(float(p_est[0]), float(p_est[1])),
                heading_true_rad=heading_true,
                heading_est_rad=heading_est,
                max_tilt_true_deg=float(abs(3.0 + rng.standard_normal())),
                aqf=start.aqf,
                imu_integration_s=start.imu_integration_s + (t_s - start.t_s),
                position_sigma_m=sigma_m,
                path_true_m=tuple(path),
            )
        )
    return RunOutcome(run_index=run_index, seed=campaign_seed, steps=tuple(steps))


def failing_run(inputs: RehearsalInputs, run_index: int, campaign_seed: int) -> RunOutcome:
    if run_index == FAIL_AT:
        raise RuntimeError(f"the world of run {run_index} has no ground")
    return kinematic_run(inputs, run_index, campaign_seed)


def gated_run(inputs: RehearsalInputs, run_index: int, campaign_seed: int) -> RunOutcome:
    if run_index >= GATE_FROM:
        from distributed import Event

        Event(GATE_EVENT).wait()
    return kinematic_run(inputs, run_index, campaign_seed)
