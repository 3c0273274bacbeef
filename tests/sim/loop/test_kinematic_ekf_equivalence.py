"""The kinematic EKF (Balaram 2000) beside SAPP computes what it computed before issue 16
made it fast.

The reference, ``reference/kinematic_ekf_gusev.npz``, holds the inputs that
``kinematic_ekf_intervals`` was given on each drive segment of the session below (a short
straight drive over Gusev's rocks, a turn in place, an arc, a straight from steered wheels),
the filter's state before each segment, and what the filter held after every interval (state
``X`` and quaternion ``q_s_b``) and at each segment's end (covariance ``P``), as the code of
commit 63f964c computed them. It was written by running this module with ``--write`` on that
commit. Replaying the same inputs now must give the same filter to 1e-9 (the state's metres,
radians and metres per second, and the covariance's squares of them); the session's
simulator may change beneath it without changing this test.
"""

from __future__ import annotations

import copy
import sys
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

from estimation.fusion.kinematic.ekf import KinematicEkf
from sim.loop.side import kinematic
from sim.sensors.sun_sensor import SunSensorSamples

REFERENCE = Path(__file__).parent / "reference" / "kinematic_ekf_gusev.npz"
TOLERANCE = 1e-9
INPUTS = (
    "t_s", "v_c_b", "omega_c_b", "delta_angle_b", "frame_rate_s", "gamma_rad", "steer_rad",
    "wheel_rad", "sun_t_s", "sun_s_m", "sun_valid", "sun_ref_s",
)  # fmt: skip
STATE = ("q_s_b", "X", "P", "v_c_b", "omega_c_b")


def _arguments(ref: Any, i: int) -> tuple[Any, ...]:
    get = {name: ref[f"seg{i}_{name}"] for name in INPUTS}
    sun = SunSensorSamples(get["sun_t_s"], get["sun_s_m"], get["sun_valid"])
    return (
        get["t_s"], get["v_c_b"], get["omega_c_b"], get["delta_angle_b"], get["frame_rate_s"],
        get["gamma_rad"], get["steer_rad"], get["wheel_rad"], sun, get["sun_ref_s"],
    )  # fmt: skip


def _replay(ekf: KinematicEkf, args: tuple[Any, ...]) -> dict[str, Any]:
    X, q = [], []
    for _ in kinematic.kinematic_ekf_intervals(ekf, *args):
        X.append(ekf.X.copy())
        q.append(ekf.q_s_b.copy())
    return {"X_steps": np.array(X), "q_steps": np.array(q), "P_end": ekf.P.copy()}


def test_the_filter_replays_its_recorded_drives() -> None:
    ref = np.load(REFERENCE)
    worst = 0.0
    for i in range(int(ref["segments"])):
        ekf = kinematic._new_ekf(np.array([0.0, 0.0, 0.0, 1.0]), np.zeros(3))
        ekf.load_state({name: ref[f"seg{i}_state_{name}"] for name in STATE})
        got = _replay(ekf, _arguments(ref, i))
        for name, value in got.items():
            expected = ref[f"seg{i}_{name}"]
            assert value.shape == expected.shape, name
            worst = max(worst, float(np.max(np.abs(value - expected))))
    assert worst <= TOLERANCE


def _write() -> None:
    """Run the session and record the filter's inputs and outputs (module docstring)."""
    from estimation.sapp.aqf import AttitudeQuality
    from sequences import commands as cmd
    from sim.loop.session import RoverSession

    recorded: list[dict[str, Any]] = []
    original = kinematic.kinematic_ekf_intervals

    def recording(ekf: KinematicEkf, *args: Any) -> Any:
        state = copy.deepcopy(ekf.state())
        before = copy.deepcopy(args)
        yield from original(ekf, *args)
        recorded.append({"state": state, "args": before})

    kinematic.kinematic_ekf_intervals = recording  # type: ignore[assignment]
    session = RoverSession(
        "gusev",
        3,
        datetime(2004, 4, 14, 16, 30, 0, tzinfo=UTC),
        frame_every_s=1.0,
        estimators=("sapp", "kinematic_ekf"),
    )
    session.nate.load_attitude(session.q_b_ll_true(), AttitudeQuality.FINE)
    session.run(
        [
            cmd.DriveStraight(1.0),
            cmd.TurnInPlace(-10.0),
            cmd.DriveArc(3.0, 15.0),
            cmd.DriveStraight(0.5),
        ]
    )
    kinematic.kinematic_ekf_intervals = original
    out: dict[str, Any] = {"segments": len(recorded)}
    for i, rec in enumerate(recorded):
        args = rec["args"]
        sun = args[8]
        values = (*args[:8], sun.t_s, sun.s_m, sun.valid, args[9])
        out.update({f"seg{i}_{name}": v for name, v in zip(INPUTS, values, strict=True)})
        out.update({f"seg{i}_state_{name}": v for name, v in rec["state"].items()})
        ekf = kinematic._new_ekf(np.array([0.0, 0.0, 0.0, 1.0]), np.zeros(3))
        ekf.load_state(rec["state"])
        out.update({f"seg{i}_{k}": v for k, v in _replay(ekf, args).items()})
    REFERENCE.parent.mkdir(exist_ok=True)
    np.savez_compressed(REFERENCE, **out)


if __name__ == "__main__" and "--write" in sys.argv:
    _write()
