"""Checkpoints of the flight software (``state()`` / ``load_state()``, ``estimation.state``).

For each stateful class: run it, take ``state()`` at several points (mid-window, mid-Sunfind,
in Sungaze's gravity window and mid-Sungaze, with an acquisition command half done, in
Articulate and Mobility, mid-gyrocompass, after SET_PARAM), send the state through JSON
(arrays as lists), load it on a fresh object built from the same arguments, and feed both
the same inputs: every output is exactly equal. ``state()`` holds plain data only.
"""

from __future__ import annotations

import dataclasses
import enum
import json
import math
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from estimation.fusion.kinematic.ekf import KinematicEkf
from estimation.fusion.kinematic.slip_constraint import JointRates
from estimation.fusion.radio.ekf import RadioEkf
from estimation.sapp.aqf import AttitudeQuality
from estimation.sapp.hga_pointing import PointingKnowledge
from estimation.sapp.nate import (
    CONTROL_DT_S,
    DriveCommand,
    EncoderSample,
    ImuSample,
    Nate,
    NateMode,
    NateOutput,
)
from estimation.sapp.wheel_odometry import DriveKind
from tests.estimation.sapp.test_nate_camera import imu, rover

PLAIN = (type(None), bool, int, float, str)


def assert_plain(value: object, where: str = "state") -> None:
    """Plain data only: no object of ours (nor any other class), str keys, numeric arrays."""
    if isinstance(value, Mapping):
        assert type(value) is dict, where
        for key, item in value.items():
            assert isinstance(key, str), f"{where}: key {key!r}"
            assert_plain(item, f"{where}.{key}")
    elif isinstance(value, list):
        for i, item in enumerate(value):
            assert_plain(item, f"{where}[{i}]")
    elif isinstance(value, np.ndarray):
        assert value.dtype.kind in "biuf", f"{where}: dtype {value.dtype}"
    else:
        assert type(value) in PLAIN, f"{where}: {type(value).__name__}"
        assert not isinstance(value, enum.Enum), where


def through_json(state: dict[str, Any]) -> dict[str, Any]:
    """The state as a JSON checkpoint would bring it back: arrays as lists."""
    assert_plain(state)
    text = json.dumps(state, default=lambda a: a.tolist())
    out: dict[str, Any] = json.loads(text)
    return out


def assert_same(a: object, b: object, where: str = "output") -> None:
    """Exactly equal, field by field (arrays bit for bit, NaN equal to NaN)."""
    if dataclasses.is_dataclass(a) and not isinstance(a, type):
        assert type(a) is type(b), where
        for f in dataclasses.fields(a):
            assert_same(getattr(a, f.name), getattr(b, f.name), f"{where}.{f.name}")
    elif isinstance(a, dict):
        assert isinstance(b, dict) and a.keys() == b.keys(), where
        for key in a:
            assert_same(a[key], b[key], f"{where}.{key}")
    elif isinstance(a, np.ndarray):
        assert isinstance(b, np.ndarray) and a.shape == b.shape, where
        assert np.array_equal(a, b, equal_nan=True), where
    elif isinstance(a, tuple | list):
        assert isinstance(b, tuple | list) and len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            assert_same(x, y, f"{where}[{i}]")
    elif isinstance(a, float) and math.isnan(a):
        assert isinstance(b, float) and math.isnan(b), where
    else:
        assert a == b, f"{where}: {a!r} != {b!r}"


Step = Callable[[Nate], NateOutput | None]


def replay_from_checkpoints(
    make: Callable[[], Nate], steps: list[Step], also: set[int] | None = None
) -> set[str]:
    """Run ``steps`` on one NATE; after every 7th (and those in ``also``) checkpoint it,
    load the checkpoint on a fresh NATE and run the remaining steps on both, comparing
    every output and the final state. Returns the modes the checkpoints were taken in."""
    reference = make()
    outputs = [step(reference) for step in steps]
    modes = set()
    for k in sorted(set(range(0, len(steps), 7)) | (also or set())):
        original = make()
        for step in steps[: k + 1]:
            step(original)
        checkpoint = through_json(original.state())
        modes.add(original.mode.name)
        restored = make()
        restored.load_state(checkpoint)
        assert_same(restored.state(), original.state(), f"state after step {k}")
        for i, step in enumerate(steps[k + 1 :], start=k + 1):
            out_o, out_r = step(original), step(restored)
            assert_same(out_r, out_o, f"step {i} after a checkpoint at {k}")
            assert_same(out_o, outputs[i], f"step {i} (reference)")
        assert_same(restored.state(), original.state(), "final state")
    return modes


def test_nate_resumes_a_camera_acquisition_from_any_checkpoint() -> None:
    """GetFineAttitude on rendered Pancam frames: checkpoints in the Nadir window, in the
    Sunfind search, in Sungaze's gravity window and between Sungaze images."""
    sim, _ = rover()
    inputs: list[tuple[ImuSample, np.ndarray | None]] = []
    probe = Nate(sim.lat_rad, sim.lon_east_rad, sim.t_s)
    t0_s = sim.t_s
    probe.set_param("sungaze.use_gravity", True)
    probe.set_param("sungaze.timer_s", 200.0)
    probe.get_fine_attitude()
    while probe.busy:  # record the inputs the session would give
        req, hint = probe.camera_request, probe.wait_hint_s
        image = None
        if req is not None:
            sample = imu(sim.rest(max(hint, CONTROL_DT_S)))
            image = sim.pancam_sun_image(req.az_rad, req.el_rad).image
        elif hint <= CONTROL_DT_S:
            sample = imu(sim.rest_cycles(CONTROL_DT_S))
        else:
            sample = imu(sim.rest(hint))
        inputs.append((sample, image))
        probe.step(sample, image=image)

    def make() -> Nate:
        return Nate(sim.lat_rad, sim.lon_east_rad, t0_s)

    def command(nate: Nate) -> None:
        nate.set_param("sungaze.use_gravity", True)
        nate.set_param("sungaze.timer_s", 200.0)
        nate.get_fine_attitude()

    steps: list[Step] = [command]
    steps += [(lambda nate, s=sample, i=image: nate.step(s, image=i)) for sample, image in inputs]
    with_image = {k + 1 for k, (_, image) in enumerate(inputs) if image is not None}
    modes = replay_from_checkpoints(make, steps, with_image)
    assert {"NADIR_UPDATE", "SUNFIND", "SUNGAZE"} <= modes
    assert probe.aqf is AttitudeQuality.FINE


def test_nate_resumes_articulate_mobility_and_gyrocompass_from_any_checkpoint() -> None:
    """Synthetic sensors: a tilting Articulate, a Mobility arc with encoders, a Site, a
    gyrocompass span cut by checkpoints, and SET_PARAM carried in the state."""
    lat, lon, t0 = math.radians(-14.57), math.radians(175.47), 1.3e8
    rng = np.random.default_rng(5)

    def level(n: int, tilt: float = 0.0) -> list[ImuSample]:
        g = 3.711 * CONTROL_DT_S
        dv = np.array([g * math.sin(tilt), 0.0, -g * math.cos(tilt)])
        return [
            ImuSample(rng.normal(0.0, 1e-6, 3), dv + rng.normal(0.0, 1e-4, 3), CONTROL_DT_S)
            for _ in range(n)
        ]

    def cycles(samples: list[ImuSample], encoders: list[EncoderSample] | None = None) -> list[Step]:
        encs: list[EncoderSample | None] = list(encoders) if encoders else [None] * len(samples)
        return [
            (lambda nate, s=s, e=e: nate.step(s, e)) for s, e in zip(samples, encs, strict=True)
        ]

    def do(action: Callable[[Nate], object]) -> Step:
        def step(nate: Nate) -> None:
            action(nate)

        return step

    wheel = np.cumsum(np.full((40, 6), 0.02), axis=0)
    steer = np.array([0.3, 0.0, -0.3, 0.25, 0.0, -0.25])
    encoders = [EncoderSample(w, steer) for w in wheel]
    steps: list[Step] = [do(lambda n: n.nadir_update(window_s=6.0))]
    steps += cycles(level(48, 0.05))
    steps += [do(lambda n: n.set_param("articulate_window_s", 3.0)), do(lambda n: n.articulate())]
    steps += cycles(level(30, 0.05) + level(30, 0.08))
    steps += [do(lambda n: n.stop()), do(lambda n: n.plant_site())]
    steps += [do(lambda n: n.mobility(DriveCommand(DriveKind.ARC, 4.0)))]
    steps += cycles(level(40, 0.08), encoders)
    steps += [do(lambda n: n.set_drive(DriveCommand(DriveKind.STRAIGHT))), do(lambda n: n.stop())]
    steps += [do(lambda n: n.gyrocompass(duration_s=20.0))]
    steps += cycles(level(170, 0.08))
    modes = replay_from_checkpoints(lambda: Nate(lat, lon, t0), steps)
    assert {"NADIR_UPDATE", "ARTICULATE", "MOBILITY", "GYROCOMPASS", "IDLE"} <= modes
    final = Nate(lat, lon, t0)
    for step in steps:
        step(final)
    assert final.mode is NateMode.IDLE and len(final.sites) == 2
    assert final.params.articulate_window_s == 3.0


def assert_resumes(
    make: Callable[[], Any], run: Callable[[Any, Any], Any], inputs: Any, cuts: tuple[int, ...]
) -> None:
    """For each cut ``k``: run ``inputs[: k + 1]`` on a filter, load its state (through
    JSON) on a fresh one, run the rest on both: equal outputs and equal final state."""
    for k in cuts:
        original = make()
        run(original, inputs[: k + 1])
        restored = make()
        restored.load_state(through_json(original.state()))
        assert_same(run(restored, inputs[k + 1 :]), run(original, inputs[k + 1 :]))
        assert_same(restored.state(), original.state())


def test_pointing_knowledge_resumes() -> None:
    history = [
        (AttitudeQuality.TILT_ONLY, 0.0, None),
        (AttitudeQuality.FINE, 10.0, 1.2),
        (AttitudeQuality.FINE, 500.0, None),
        (AttitudeQuality.COARSE, 1200.0, None),
        (AttitudeQuality.FINE, 1300.0, None),
        (AttitudeQuality.UNKNOWN, 1400.0, None),
    ]
    for k in range(len(history)):
        original = PointingKnowledge()
        for aqf, imu_s, sigma in history[: k + 1]:
            original.update(aqf, imu_s, sigma)
        restored = PointingKnowledge()
        restored.load_state(through_json(original.state()))
        for aqf, imu_s, sigma in history[k + 1 :]:
            assert restored.update(aqf, imu_s, sigma) == original.update(aqf, imu_s, sigma)
        assert restored.state() == original.state()


def test_kinematic_ekf_resumes() -> None:
    rng = np.random.default_rng(7)
    q0 = np.array([0.0, 0.0, 0.0, 1.0])

    def make() -> KinematicEkf:
        return KinematicEkf(q0, np.zeros(3), estimate_bias=True)

    joints = JointRates(
        gamma_rad=np.array([0.02, -0.01, 0.015]),
        gamma_rate_rad_s=np.zeros(3),
        sigma_rad=np.zeros(6),
        sigma_rate_rad_s=np.zeros(6),
        psi_rate_rad_s=np.full(6, 0.0375 / 0.13),
    )
    inputs = [(rng.normal(0.0, 1e-4), rng.normal(0.0, 0.01, 2)) for _ in range(12)]

    def run(ekf: KinematicEkf, items: list[tuple[float, np.ndarray]]) -> list[object]:
        out: list[object] = []
        for gyro, sun in items:
            ekf.set_command([0.0375, 0.0, 0.0], [0.0, 0.0, 0.001])
            ekf.propagate(0.125)
            out.append(ekf.update_gyro(gyro))
            out.append(ekf.update_sun(sun, [0.6, 0.0, -0.8]))
            out.append(ekf.update_slip(joints))
            out.append(ekf.estimate())
        return out

    assert_resumes(make, run, inputs, (0, 5, 11))


def test_radio_ekf_resumes() -> None:
    rng = np.random.default_rng(11)

    def make() -> RadioEkf:
        return RadioEkf(math.radians(-1.95), math.radians(354.47), 0.02, 0.01)

    inputs = [
        (
            rng.normal(0.0, 0.01, 3) + np.array([0.0, 0.0, -3.711]),
            rng.normal(0.0, 0.01, 3),
            rng.normal(),
        )
        for _ in range(15)
    ]

    def run(ekf: RadioEkf, items: list[tuple[np.ndarray, np.ndarray, float]]) -> list[object]:
        out: list[object] = []
        for f_b, euler, noise in items:
            ekf.propagate(1.0, f_b, euler, 0.0)
            out.append(ekf.update_yaw_rate(1e-4 * noise))
            out.append(ekf.update_velocity([0.02, 0.01 + 1e-3 * noise], 0.01))
            out.append(ekf.estimate())
        return out

    assert_resumes(make, run, inputs, (0, 7, 14))
