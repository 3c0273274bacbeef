"""NATE's mode procedures: what each mode does on entry and in each control cycle.

Ali et al. 2005, "Attitude and Position Estimation on the Mars Exploration Rovers": sec.
2.1 (the Attitude Quality Flag rules applied here), 2.2.1 (Nadir Update, eq. 1), 2.2.4 (the
Attitude Acquisition Machine), 2.3.1 (Nadir Check), 2.4 (the gyro counter), 2.4.1
(Articulate), 2.4.2 and 2.5 (Mobility, eqs. 5-7), sec. 5 (gyrocompassing). The documented
choices are in ``estimation.sapp.nate``'s docstring; ``Nate`` (there) adds the commands,
their checks and the control cycle's dispatch to the state and procedures kept here.
``state()`` and ``load_state()`` checkpoint all of it as plain data (``estimation.state``).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from estimation.camera_model import PANCAM, R_b_pancam
from estimation.events import Event, Severity, failure_severity
from estimation.ivp import mars_rotation_ll, sun_ll
from estimation.quaternion import (
    q_canonical,
    q_normalised,
    quat_canonical,
    quat_conjugate,
    quat_from_rotvec,
    quat_multiply,
)
from estimation.sapp.aqf import AttitudeQuality
from estimation.sapp.gyro_propagation import gyro_cycle
from estimation.sapp.gyrocompass import gyrocompass
from estimation.sapp.mobility import (
    mobility_cycles,
    tilt_of_estimates_deg,
    tilts_from_accelerometers_deg,
)
from estimation.sapp.nadir import (
    AccelAverager,
    NadirCheckOutcome,
    NadirCheckResult,
    NadirParams,
    NadirUpdateResult,
    check_average,
    nadir_check,
    nadir_update,
)
from estimation.sapp.nate_io import (
    Completed,
    DriveCommand,
    EncoderSeries,
    GyrocompassOutcome,
    ImuSeries,
    NateMode,
    NateParams,
    NateSeries,
)
from estimation.sapp.site_frames import SiteChain
from estimation.sapp.sun_modes import (
    PancamRequest,
    Suncheck,
    SuncheckParams,
    Sunfind,
    Sungaze,
    SunResult,
)
from estimation.sapp.sunfind import find_sun
from estimation.sapp.wheel_odometry import (
    DriveKind,
    arc_centre_b,
    odometry_step,
    propagate_heading,
    propagate_position,
)
from estimation.state import array_copy, load_params, params_state

FloatArray = NDArray[np.float64]

IDENTITY_Q = np.array([0.0, 0.0, 0.0, 1.0])

# A Nadir Check that fails drops the flag (error); one that aborts could not judge (warning).
_CHECK_SEVERITY: dict[NadirCheckOutcome, Severity] = {
    NadirCheckOutcome.PASSED: "info",
    NadirCheckOutcome.FAILED: "error",
    NadirCheckOutcome.ABORTED: "warning",
}


def _rotation_onto(u_b: FloatArray, v_b: FloatArray) -> FloatArray:
    """``δq^B`` turning unit ``u_b`` onto unit ``v_b`` about ``u_b × v_b`` (sec. 2.2.1, the
    form of eq. 1's correction); identity if parallel (opposite cannot occur for a relative
    tilt of a settled rover; it also returns identity rather than guess an axis)."""
    axis = np.cross(u_b, v_b)  # sec. 2.2.1: about n^B x g^B
    angle = math.atan2(float(np.linalg.norm(axis)), float(np.dot(u_b, v_b)))
    if float(np.linalg.norm(axis)) < 1e-15:
        return IDENTITY_Q.copy()
    return quat_from_rotvec(axis / np.linalg.norm(axis) * angle)


class NateProcedures:
    """NATE's state and its mode procedures (module docstring); ``Nate`` is the machine."""

    def __init__(
        self,
        lat_rad: float,
        lon_east_rad: float,
        t_s: float,
        params: NateParams | None = None,
    ) -> None:
        for name, value in (("lon_east_rad", lon_east_rad), ("t_s", t_s)):
            if not (isinstance(value, (int, float)) and math.isfinite(value)):
                raise ValueError(f"{name}: must be finite, got {value!r}")
        self._lat_rad, self._lon_east_rad = float(lat_rad), float(lon_east_rad)
        self._omega_mars_ll = mars_rotation_ll(lat_rad)  # sec. 2.4.1, from IVP
        o_x, o_y, o_z = self._omega_mars_ll.tolist()
        self._omega_tuple = (o_x, o_y, o_z)  # the same, for the per-cycle float math
        sun_ll(float(t_s), self._lat_rad, self._lon_east_rad)  # validates the site
        self._t_s = float(t_s)
        self._params = params if params is not None else NateParams()
        self._q_b_ll = IDENTITY_Q.copy()
        self._p_s = np.zeros(3)
        self._sites = SiteChain()
        self._aqf = AttitudeQuality.UNKNOWN  # sec. 2.1: "the initial value after landing"
        self._mode = NateMode.IDLE
        self._gyro_counter_s = 0.0
        self._imu_integration_s = 0.0
        self._averager: AccelAverager | None = None
        self._check_tolerance_rad = self._params.nadir.check_tolerance_rad
        self._ref_down_ll: FloatArray | None = None  # Articulate's reference vertical
        self._q_entry_b_ll = IDENTITY_Q.copy()  # estimate at Articulate entry
        self._drive = DriveCommand()
        self._use_gyros = True
        self._last_wheel_rad: FloatArray | None = None
        self._procedure: Sunfind | Sungaze | Suncheck | None = None
        self._mast: tuple[float, float] | None = None  # mast (az, el) if on the sun
        self._acquisition: str | None = None  # the Attitude Acquisition Machine's command
        self._pending: list[NateMode] = []  # its primitives still to run
        self._gyro_sum_b = np.zeros(3)  # gyrocompassing: delta angles, time covered
        self._gyro_sum_s = 0.0
        self._gyro_span_s = 0.0
        self._events: list[Event] = []

    # ---- checkpoints (estimation.state) ----------------------------------------------

    def state(self) -> dict[str, Any]:
        """Everything NATE will need after a restart, as plain data: the parameters (they
        change with SET_PARAM), the mode, estimate, flag, Sites, clock and counters, and
        whatever a mode holds mid-way (an accelerometer window, a camera procedure, the
        rest of an acquisition command, a gyrocompass span, Mobility's drive)."""
        procedure = self._procedure
        return {
            "params": params_state(self._params),
            "t_s": self._t_s,
            "mode": self._mode.name,
            "q_b_ll": self._q_b_ll.copy(),
            "p_s": self._p_s.copy(),
            "sites": self._sites.state(),
            "aqf": self._aqf.name,
            "gyro_counter_s": self._gyro_counter_s,
            "imu_integration_s": self._imu_integration_s,
            "averager": None if self._averager is None else self._averager.state(),
            "check_tolerance_rad": self._check_tolerance_rad,
            "ref_down_ll": array_copy(self._ref_down_ll),
            "q_entry_b_ll": self._q_entry_b_ll.copy(),
            "drive_kind": self._drive.kind.name,
            "drive_radius_m": self._drive.radius_m,
            "drive_drag_wheel": self._drive.drag_wheel,
            "use_gyros": self._use_gyros,
            "last_wheel_rad": array_copy(self._last_wheel_rad),
            "procedure": None if procedure is None else procedure.state(),
            "mast": None if self._mast is None else list(self._mast),
            "acquisition": self._acquisition,
            "pending": [mode.name for mode in self._pending],
            "gyro_sum_b": self._gyro_sum_b.copy(),
            "gyro_sum_s": self._gyro_sum_s,
            "gyro_span_s": self._gyro_span_s,
        }

    def load_state(self, state: Mapping[str, Any]) -> None:
        """Load ``state()``'s output onto a NATE built with the same site and start time."""
        self._params = load_params(self._params, state["params"])
        self._t_s = float(state["t_s"])
        self._mode = NateMode[state["mode"]]
        self._q_b_ll = np.array(state["q_b_ll"], dtype=np.float64)
        self._p_s = np.array(state["p_s"], dtype=np.float64)
        self._sites.load_state(state["sites"])
        self._aqf = AttitudeQuality[state["aqf"]]
        self._gyro_counter_s = float(state["gyro_counter_s"])
        self._imu_integration_s = float(state["imu_integration_s"])
        self._averager = None
        if state["averager"] is not None:
            self._averager = AccelAverager(self._params.nadir)
            self._averager.load_state(state["averager"])
        self._check_tolerance_rad = float(state["check_tolerance_rad"])
        self._ref_down_ll = array_copy(state["ref_down_ll"])
        self._q_entry_b_ll = np.array(state["q_entry_b_ll"], dtype=np.float64)
        kind = DriveKind[state["drive_kind"]]
        drag = state.get("drive_drag_wheel")  # absent in checkpoints before wheel drag
        self._drive = DriveCommand(kind, float(state["drive_radius_m"]), drag)
        self._use_gyros = bool(state["use_gyros"])
        self._last_wheel_rad = array_copy(state["last_wheel_rad"])
        self._procedure = None
        if state["procedure"] is not None:
            self._procedure = self._procedure_from(state["procedure"])
        mast = state["mast"]
        self._mast = None if mast is None else (float(mast[0]), float(mast[1]))
        self._acquisition = state["acquisition"]
        self._pending = [NateMode[name] for name in state["pending"]]
        self._gyro_sum_b = np.array(state["gyro_sum_b"], dtype=np.float64)
        self._gyro_sum_s = float(state["gyro_sum_s"])
        self._gyro_span_s = float(state["gyro_span_s"])
        self._events = []

    def _procedure_from(self, state: Mapping[str, Any]) -> Sunfind | Sungaze | Suncheck:
        """The camera mode's procedure rebuilt from its constructor arguments, then loaded;
        the mode says which procedure it is."""
        q, t0 = state["q_b_ll"], float(state["start_t_s"])
        procedure: Sunfind | Sungaze | Suncheck
        if self._mode is NateMode.SUNFIND:
            params = load_params(self._params.sunfind, state["params"])
            procedure = Sunfind(q, t0, self.sun_ll_at, params)
        elif self._mode is NateMode.SUNGAZE:
            gaze = load_params(self._params.sungaze, state["params"])
            mast = (float(state["mast"][0]), float(state["mast"][1]))
            procedure = Sungaze(q, t0, mast, self.sun_ll_at, gaze, state["down_b"])
        elif self._mode is NateMode.SUNCHECK:
            check = load_params(self._params.suncheck, state["params"])
            procedure = Suncheck(q, t0, self.sun_ll_at, check)
        else:
            raise ValueError(f"state: a camera procedure in mode {self._mode.name}")
        procedure.load_state(state)
        return procedure

    def sun_ll_at(self, t_s: float) -> FloatArray:
        """IVP's sun in LL at ``t_s`` (unit (3,))."""
        out: FloatArray = sun_ll(t_s, self._lat_rad, self._lon_east_rad)
        return out

    def _start_nadir_update(self, nadir: NadirParams) -> None:
        self._averager = AccelAverager(nadir)
        self._mode = NateMode.NADIR_UPDATE

    def _start_sunfind(self) -> None:
        self._procedure = Sunfind(self._q_b_ll, self._t_s, self.sun_ll_at, self._params.sunfind)
        self._mode = NateMode.SUNFIND

    def _start_sungaze(self, gravity: bool) -> None:
        self._mode = NateMode.SUNGAZE
        if gravity:  # first one accelerometer window, then the images
            self._averager = AccelAverager(self._params.nadir)
            self._procedure = None
        else:
            self._begin_sungaze_images(None)

    def _begin_sungaze_images(self, down_b: FloatArray | None) -> None:
        p = dataclasses.replace(self._params.sungaze, use_gravity=down_b is not None)
        mast = self._mast if self._mast is not None else (0.0, 0.0)  # stowed: looks ahead
        self._procedure = Sungaze(self._q_b_ll, self._t_s, mast, self.sun_ll_at, p, down_b)

    def _start_suncheck(self, params: SuncheckParams) -> None:
        self._procedure = Suncheck(self._q_b_ll, self._t_s, self.sun_ll_at, params)
        self._mode = NateMode.SUNCHECK

    def _acquire_sequence(self, name: str, steps: list[NateMode]) -> None:
        self._acquisition, self._pending = name, steps[1:]
        self._start_primitive(steps[0])

    def _start_primitive(self, mode: NateMode) -> None:
        if mode is NateMode.NADIR_UPDATE:
            self._start_nadir_update(self._params.nadir)
        elif mode is NateMode.SUNFIND:
            self._start_sunfind()
        elif mode is NateMode.SUNCHECK:
            self._start_suncheck(self._params.suncheck)
        elif mode is NateMode.SUNGAZE:
            self._start_sungaze(self._params.sungaze.use_gravity)
        else:  # pragma: no cover - the sequences above hold only these
            raise AssertionError(mode)

    def _set_attitude(self, q_b_ll: FloatArray, aqf: AttitudeQuality) -> None:
        """The one place an acquisition's result is adopted."""
        self._q_b_ll, self._aqf = q_b_ll, aqf
        if aqf is AttitudeQuality.FINE:
            self._gyro_counter_s = 0.0
            self._imu_integration_s = 0.0

    def _articulate_averager(self) -> AccelAverager:
        p = dataclasses.replace(self._params.nadir, window_s=self._params.articulate_window_s)
        return AccelAverager(p)

    def _after_primitive(self, completed: Completed) -> None:
        """The Attitude Acquisition Machine (sec. 2.2.4): next primitive or abort."""
        if self._acquisition is None:
            return
        proceed = completed.success
        suncheck_done = self._mode is NateMode.IDLE and self._pending == [NateMode.SUNGAZE]
        if self._acquisition == "SuncheckSungaze" and suncheck_done:
            assert isinstance(completed, SunResult)
            proceed = completed.sun_seen  # Sungaze needs only the sun in the field
            if proceed and not completed.success:
                text = (
                    f"SuncheckSungaze: Suncheck failed ({completed.outcome.value}): "
                    "Sungaze on the sun it saw"
                )
                self._events.append(Event(text, "acquisition", "warning"))  # degraded
        if proceed and self._pending:
            self._start_primitive(self._pending.pop(0))
            return
        verdict = "done" if proceed else "aborted"
        text = f"{self._acquisition} {verdict}: AQF {self._aqf.paper_name}"
        self._events.append(Event(text, "acquisition", "info" if proceed else "error"))
        self._acquisition, self._pending = None, []

    def _acquire(
        self, dv_b: FloatArray, dt: float, valid: bool
    ) -> NadirUpdateResult | NadirCheckResult | None:
        averager = self._averager
        assert averager is not None
        x, y, z = dv_b.tolist()
        averager.add_sample((x, y, z), dt, valid)
        if not averager.full:
            return None
        average = averager.average()
        result: NadirUpdateResult | NadirCheckResult
        if self._mode is NateMode.NADIR_UPDATE:
            result = nadir_update(self._q_b_ll, average, self._params.nadir)  # eq. (1)
            self._q_b_ll = result.q_b_ll  # unchanged on failure (sec. 2.2.1)
            failure = result.failure
            verdict = "succeeded" if failure is None else f"failed: {failure.value}"
            self._events.append(
                Event(f"Nadir Update {verdict}", "nadir", failure_severity(failure is None))
            )
        else:
            nadir = dataclasses.replace(
                self._params.nadir, check_tolerance_rad=self._check_tolerance_rad
            )
            result = nadir_check(self._q_b_ll, average, self._aqf, nadir)  # sec. 2.3.1
            self._events.append(
                Event(
                    f"Nadir Check: {result.outcome.value}", "nadir", _CHECK_SEVERITY[result.outcome]
                )
            )
        self._aqf = result.aqf
        self._averager = None
        self._check_tolerance_rad = self._params.nadir.check_tolerance_rad
        self._mode = NateMode.IDLE
        return result

    def _sungaze_gravity_window(self, dv_b: FloatArray, dt: float, valid: bool) -> None:
        averager = self._averager
        assert averager is not None
        x, y, z = dv_b.tolist()
        averager.add_sample((x, y, z), dt, valid)
        if not averager.full:
            return
        average = averager.average()
        self._averager = None
        failure = check_average(average, self._params.nadir)
        if failure is not None:
            text = f"Sungaze: gravity average unusable ({failure.value}), sun only"
            self._events.append(Event(text, "sungaze", "warning"))
            self._begin_sungaze_images(None)
        else:
            self._begin_sungaze_images(average.down_b)

    def _camera_image(self, request: PancamRequest, image: ArrayLike) -> SunResult | None:
        procedure = self._procedure
        assert procedure is not None
        R_b_cam = R_b_pancam(request.az_rad, request.el_rad)
        fix = find_sun(image, PANCAM, R_b_cam, self._params.finder)
        procedure.on_image(self._t_s, fix)
        if procedure.result is None:
            return None
        return self._finish_camera(procedure.result)

    def _finish_camera(self, result: SunResult) -> SunResult:
        """Apply a camera mode's outcome: the AQF rules of sec. 2.2.2, 2.2.3 and 2.3."""
        mode = self._mode
        if mode is NateMode.SUNFIND:
            if result.success:
                self._set_attitude(result.q_b_ll, AttitudeQuality.COARSE)
            else:
                self._aqf = AttitudeQuality.UNKNOWN  # estimate unchanged
            text = f"Sunfind: {result.outcome.value} ({result.n_images} images)"
            self._events.append(Event(text, "sunfind", failure_severity(result.success)))
        elif mode is NateMode.SUNGAZE:
            if result.success:
                self._set_attitude(result.q_b_ll, AttitudeQuality.FINE)  # resets counters
            else:
                self._aqf = AttitudeQuality.UNKNOWN  # no update
            text = (
                f"Sungaze: {result.outcome.value}, 3σ {math.degrees(result.three_sigma_rad):.2f} "
                f"deg after {result.n_images} images"
            )
            self._events.append(Event(text, "sungaze", failure_severity(result.success)))
        else:
            if not result.success:
                self._aqf = AttitudeQuality.UNKNOWN  # the estimate is never changed
            err = math.degrees(result.error_rad)
            text = f"Suncheck: {result.outcome.value} (error {err:.2f} deg)"
            self._events.append(Event(text, "suncheck", failure_severity(result.success)))
        self._mast = result.final_mast
        self._procedure = None
        self._mode = NateMode.IDLE
        return result

    def _gyrocompass_step(
        self, d_theta_b: FloatArray, dt: float, valid: bool
    ) -> GyrocompassOutcome | None:
        if valid:
            self._gyro_sum_b += d_theta_b
            self._gyro_sum_s += dt
        else:
            self._gyro_span_s += dt  # an invalid sample extends the span
        if self._gyro_sum_s < self._gyro_span_s * (1.0 - 1e-9):
            return None
        self._mode = NateMode.IDLE
        p = self._params
        try:
            result = gyrocompass(
                self._gyro_sum_b,
                self._gyro_sum_s,
                self._q_b_ll,
                self._lat_rad,
                params=p.gyrocompass,
            )
        except ValueError as exc:
            self._events.append(Event(f"Gyrocompass refused: {exc}", "gyrocompass", "error"))
            return GyrocompassOutcome(None, str(exc), False)
        mismatch = abs(result.horizontal_rate_rad_s / result.expected_horizontal_rate_rad_s - 1.0)
        if mismatch > p.gyrocompass_rate_tolerance:
            reason = (
                f"measured horizontal rate is {100 * mismatch:.0f} % off Mars' (limit "
                f"{100 * p.gyrocompass_rate_tolerance:.0f} %): the rover moved or a gyro failed"
            )
            self._events.append(Event(f"Gyrocompass refused: {reason}", "gyrocompass", "error"))
            return GyrocompassOutcome(None, reason, False)
        # The 3σ assumes a measured tilt (Nadir Update): without one, never Coarse.
        tilt_known = self._aqf >= AttitudeQuality.TILT_ONLY
        coarse = tilt_known and result.heading_3sigma_rad <= p.gyrocompass_coarse_3sigma_rad
        # The heading is now the gyrocompass's: Coarse if good enough, else TiltOnly at best.
        aqf = AttitudeQuality.COARSE if coarse else min(self._aqf, AttitudeQuality.TILT_ONLY)
        self._set_attitude(result.q_b_ll, aqf)
        text = (
            f"Gyrocompass: heading {math.degrees(result.heading_rad):.1f} deg, 3σ "
            f"{math.degrees(result.heading_3sigma_rad):.1f} deg, AQF {self._aqf.paper_name}"
        )
        self._events.append(Event(text, "gyrocompass"))
        return GyrocompassOutcome(result, None, coarse)

    def _propagate_gyros(self, d_theta_b: FloatArray, dt: float, valid: bool) -> None:
        if not valid:
            return  # the driver flagged the sample: not integrated (nor counted as IMU time)
        x, y, z, w = self._q_b_ll.tolist()
        d_x, d_y, d_z = d_theta_b.tolist()
        q = gyro_cycle(q_normalised((x, y, z, w)), (d_x, d_y, d_z), dt, self._omega_tuple)
        self._q_b_ll = np.array(q_canonical(q))  # sec. 2.4.1
        self._imu_integration_s += dt

    def _mobility_series(self, imu: ImuSeries, encoders: EncoderSeries | None) -> NateSeries:
        """Mobility through a series of cycles at once (``estimation.sapp.mobility``): what
        ``_cycle`` does cycle by cycle, with the same state after it."""
        track = mobility_cycles(
            self._q_b_ll,
            self._p_s,
            self._imu_integration_s,
            self._last_wheel_rad,
            imu,
            encoders,
            self._drive,
            self._use_gyros,
            self._omega_mars_ll,
        )
        n = len(imu)
        t_s = self._t_s + np.cumsum(imu.dt_s)
        counter_s = self._gyro_counter_s + np.cumsum(imu.dt_s)  # sec. 2.4, every cycle
        aqf = [self._aqf] * n
        if self._aqf is AttitudeQuality.FINE:  # sec. 2.4: Fine drops to Coarse
            late = np.flatnonzero(counter_s > self._params.fine_to_coarse_s)
            if len(late):
                aqf[int(late[0]) :] = [AttitudeQuality.COARSE] * (n - int(late[0]))
        if n:
            self._q_b_ll, self._p_s = track.q_b_ll[-1].copy(), track.p_s[-1].copy()
            self._imu_integration_s = float(track.imu_integration_s[-1])
            self._gyro_counter_s, self._t_s = float(counter_s[-1]), float(t_s[-1])
            self._aqf = aqf[-1]
        self._last_wheel_rad = track.last_wheel_rad
        self._events = []
        return NateSeries(
            t_s=t_s,
            q_b_ll=track.q_b_ll,
            p_s=track.p_s,
            tilt_est_deg=tilt_of_estimates_deg(track.q_b_ll),
            tilt_accel_deg=tilts_from_accelerometers_deg(imu),
            imu_integration_s=track.imu_integration_s,
            gyro_counter_s=counter_s,
            aqf=aqf,
            mode=[NateMode.MOBILITY] * n,
            site_index=[self._sites.current.index] * n,
            completed=[None] * n,
            acquisition=[self._acquisition] * n,
            camera_request=[None] * n,
            events=[()] * n,
        )

    def _count(self, dt: float) -> None:
        self._gyro_counter_s += dt  # sec. 2.4: incremented each Articulate/Mobility cycle
        if (
            self._aqf is AttitudeQuality.FINE
            and self._gyro_counter_s > self._params.fine_to_coarse_s
        ):
            self._aqf = AttitudeQuality.COARSE  # sec. 2.4: Fine drops to Coarse

    def _articulate_tilt(self, dv_b: FloatArray, dt: float, valid: bool) -> None:
        averager = self._averager
        assert averager is not None
        x, y, z = dv_b.tolist()
        averager.add_sample((x, y, z), dt, valid)
        if not averager.full:
            return
        average = averager.average()
        self._averager = self._articulate_averager()
        if check_average(average, self._params.nadir) is not None:
            return  # sanity check failed (sec. 2.2.1): no correction from this window
        if self._ref_down_ll is None:  # sec. 2.4.1: the reference vertical, kept in LL
            R_ll_b_entry = Rotation.from_quat(quat_conjugate(self._q_entry_b_ll))
            self._ref_down_ll = R_ll_b_entry.apply(average.down_b)
            return
        R_b_ll = Rotation.from_quat(self._q_b_ll)
        ref_b = R_b_ll.apply(self._ref_down_ll)  # reference with the latest estimate
        dq_b = _rotation_onto(ref_b, average.down_b)  # relative tilt, sec. 2.4.1
        q = quat_multiply(dq_b, self._q_b_ll)  # eq. (1)'s form: δq^B ⊗ q
        self._q_b_ll = quat_canonical(q / np.linalg.norm(q))

    def _q_s_b(self) -> FloatArray:
        """``q_s_b`` for wheel odometry: the Site has LL's orientation, so conj(q_b_ll)."""
        return quat_conjugate(self._q_b_ll)

    def _odometry(self, wheel_rad: FloatArray, steer_rad: FloatArray) -> None:
        last, self._last_wheel_rad = self._last_wheel_rad, wheel_rad
        if last is None:
            return  # first reading: the reference only
        drive = self._drive
        centre = arc_centre_b(drive.radius_m) if drive.kind is DriveKind.ARC else None
        step = odometry_step(  # eqs. (5)-(7), over the driven wheels
            drive.kind, wheel_rad - last, steer_rad, centre, drag_wheel=drive.drag_wheel
        )
        q_s_b = self._q_s_b()
        if not self._use_gyros:  # sec. 2.4.2 off-nominal submode: attitude from odometry
            q_s_b = propagate_heading(q_s_b, step.delta_heading_rad)
            self._q_b_ll = quat_canonical(quat_conjugate(q_s_b))
        self._p_s = propagate_position(self._p_s, q_s_b, step.delta_p_b)  # sec. 2.5
