"""The simulator's truth pinned against a recording: short drives on Gusev and Meridiani
(straight, arc, turn in place; rocks, slip and the encoders' random draws) agree with what
the simulator produced before its settling and height queries were compiled
(``truth_reference.npz`` beside this module).

Regenerate the recording only when the truth is meant to change:
``PYTHONPATH=. python tests/sim/rover/test_truth_reference.py`` writes it from the code of
the checkout it runs in. Positions and angles are compared to 1e-9 (m, rad), far below the
1e-6 the telemetry's equivalence asks; on the machine that recorded it the new code
reproduces it bit for bit (a different CPU or maths library may round ``sin`` and ``cos``
differently in the last bit, hence the tolerance). Encoder counts must be equal.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from sim.rover import drive
from sim.rover.slip import SlipModel
from sim.rover.truth import TruthTrajectory
from sim.sensors.encoders import EncoderParams, MobilityEncoders
from sim.world.sites import make_terrain

RECORDING = Path(__file__).with_name("truth_reference.npz")
TRUTH_FIELDS = ("p_s", "q_s_b", "rocker_rad", "bogie_rad", "slip")
TOL = 1e-9  # m and rad


def _drives(site: str) -> dict[str, np.ndarray]:
    """The recorded quantities of a few primitives in a row on ``site`` (seed 1)."""
    terrain = make_terrain(site, 1)
    rng_slip, rng_encoders = np.random.default_rng(7).spawn(2)
    slip = SlipModel(terrain.soil, rng_slip)
    encoders = MobilityEncoders(EncoderParams(), rng_encoders)
    state = drive.initial_state(terrain, 0.0, x_m=1.0, y_m=-2.0, yaw_rad=0.3, slip_model=slip)
    out: dict[str, np.ndarray] = {}
    steps = (
        ("straight", lambda s: drive.drive_straight(terrain, s, 1.5, slip)),
        ("turn", lambda s: drive.turn_in_place(terrain, s, -0.3, slip)),
        ("arc", lambda s: drive.drive_arc(terrain, s, 2.0, 0.3, slip)),
    )
    for name, primitive in steps:
        traj: TruthTrajectory
        traj, state = primitive(state)
        for f in TRUTH_FIELDS:
            out[f"{site}.{name}.{f}"] = getattr(traj, f)
        out[f"{site}.{name}.wheel_counts"] = encoders.read(traj).wheel_counts
    return out


def _record() -> dict[str, np.ndarray]:
    return {**_drives("gusev"), **_drives("meridiani")}


@pytest.fixture(scope="module")
def recorded() -> dict[str, np.ndarray]:
    with np.load(RECORDING) as data:
        return {k: data[k] for k in data.files}


@pytest.mark.parametrize("site", ["gusev", "meridiani"])
def test_short_drives_reproduce_the_recorded_truth(
    site: str, recorded: dict[str, np.ndarray]
) -> None:
    now = _drives(site)
    assert set(now) == {k for k in recorded if k.startswith(f"{site}.")}
    for key, value in now.items():
        if key.endswith("wheel_counts"):
            np.testing.assert_array_equal(value, recorded[key], err_msg=key)
        else:
            np.testing.assert_allclose(value, recorded[key], rtol=0.0, atol=TOL, err_msg=key)


if __name__ == "__main__":
    np.savez_compressed(RECORDING, **_record())
    sys.stdout.write(f"wrote {RECORDING}\n")
