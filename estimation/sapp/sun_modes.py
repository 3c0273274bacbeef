"""Sunfind, Sungaze and Suncheck: NATE's camera modes as image-by-image procedures.

Ali et al. 2005, "Attitude and Position Estimation on the Mars Exploration Rovers":
sec. 2.2.2 (Sunfind: search phase eqs. 2-3, confirmation phase, final update eq. 4,
the near-zenith case), 2.2.3 (Sungaze: QUEST on observed and expected sun vectors in LL,
ten-minute timer, early stop at 1.5 deg 3σ, and a variation with an additional sensor),
2.3.2 (Suncheck). The geometry is in ``estimation.sapp.sunfind_search``, QUEST in
``estimation.sapp.quest``; this module sequences the images. The NATE state machine owns a
procedure while its mode runs, feeds it one sun-finder result per image, and applies the
outcome (estimate and Attitude Quality Flag) in one place when it finishes.

A procedure asks for an image with ``request`` (mast azimuth and elevation, body frame,
``estimation.camera_model.R_b_pancam``, and the earliest time the image may be taken) and
is answered with ``on_image(t_s, fix)``: the sun finder's result (``SunFix`` or ``None``)
for the image taken at ``t_s`` at that pointing. ``sun_ll(t_s)`` is IVP's expected sun at a
time (unit, LL). When the procedure is finished, ``request`` is ``None`` and ``result``
holds the outcome. The rover is stationary throughout (sec. 2.2: "necessary for the rover
to be stationary"), so the estimate is not propagated while a procedure runs.

Sungaze solves for a *correction* (the choice the paper's wording fixes): the observed sun
is taken to LL with the current estimate, ``b_i = R_ll_b(q̂) s_b,i``, and the expected one
is ``r_i = sun_ll(t_i)``; QUEST returns ``C = q_b_r`` with ``b ≈ R(C) r``, i.e. the rotation
from the true LL frame to the frame the estimate believes is LL. Then
``R_b_ll = R_b_ll(q̂) R(C)`` and the new estimate is ``q̂ ⊗ C``. QUEST's covariance is of
``θ`` with ``C_true = rotvec(θ) ⊗ C``: in the estimated-LL frame; its largest eigenvalue
(frame independent) gives the 3σ that is compared with the convergence threshold.

The gravity variation (``SungazeParams.use_gravity``) adds the averaged accelerometer
direction as a second QUEST observation: ``b = R_ll_b(q̂) down_b``, ``r = Down``, with the
accelerometer's angular σ. The sun alone needs the sun's motion (about 0.24 deg/min) to fix
the rotation about the sun line; the vertical fixes it from the first image.

Documented choices (the paper leaves them to the ground):

- Search-phase images are ``image_spacing_s`` apart (mast slew, exposure and readout:
  10 s), the two confirming images ``confirm_spacing_s`` apart (60 s, so that the sun's
  motion, about 0.24 deg, is well above the 0.05 deg motion tolerance and the check
  discriminates, ``sunfind_search.MotionCheck``).
- The search is over when every guess of the plan has been imaged ("until it has examined
  the entire search plane"); a rejected candidate resumes at the next guess. Sunfind fails
  then (AQF Unknown).
- Sungaze images are ``interval_s`` apart (20 s: 31 images in the ten minutes). An image in
  which the finder sees no sun is skipped. The per-image sun-vector σ is
  ``sun_sigma_rad`` (default 0.02 deg, about 1.3 Pancam pixels: a budget for what a real
  frame adds to the centroid, flat-field and distortion residuals, scattered light and the
  mast's thermal motion over ten minutes. With it Sungaze converges to 1.5 deg 3σ in
  about seven minutes, as on MER, where the timer was ten. The simulator's clean frames
  centroid to about 2.5e-5 deg per axis, so in simulation the covariance is conservative;
  docs/BENCHMARKS.md compares it with the true error).
- Suncheck takes one image where the estimate puts the sun; no sun in the image fails the
  check; otherwise the angle between observed and expected body sun is compared with
  ``tolerance_rad`` (default 2 deg). Its sanity check is the sun's elevation: a command
  with the sun below ``min_sun_elevation_rad`` is refused by NATE before anything starts.
- Sunfind and Suncheck end with the mast pointed at the last observed sun
  (``final_mast``), so that a Sungaze can follow ("leaves the camera pointed at the sun").

Flight software: numpy and scipy only; bad arguments raise ``ValueError`` naming the
parameter.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from estimation.camera_model import mast_az_el_for
from estimation.checks import angle_between_rad, unit_quaternion, unit_vector
from estimation.quaternion import quat_canonical, quat_multiply
from estimation.sapp.quest import QuestAccumulator, QuestSolution
from estimation.sapp.sunfind import SunFix
from estimation.sapp.sunfind_search import (
    DOWN_LL,
    SunfindSearchParams,
    elevation_check,
    heading_correction_rad,
    heading_delta_quat,
    heading_update,
    motion_check,
    search_guess,
    search_plan,
)
from estimation.state import params_state

FloatArray = NDArray[np.float64]
SunLL = Callable[[float], FloatArray]


def _positive(obj: object, *names: str) -> None:
    for name in names:
        value = getattr(obj, name)
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0.0):
            raise ValueError(f"{name}: must be positive and finite, got {value!r}")


@dataclass(frozen=True)
class SunfindParams:
    """Sunfind (sec. 2.2.2): geometry and checks (``search``) and image timing, s."""

    search: SunfindSearchParams = field(default_factory=SunfindSearchParams)
    image_spacing_s: float = 10.0
    confirm_spacing_s: float = 60.0

    def __post_init__(self) -> None:
        if not isinstance(self.search, SunfindSearchParams):
            raise ValueError("search: must be SunfindSearchParams")
        _positive(self, "image_spacing_s", "confirm_spacing_s")


@dataclass(frozen=True)
class SungazeParams:
    """Sungaze (sec. 2.2.3). ``timer_s`` (10 min), ``converge_3sigma_rad`` (1.5 deg) and
    ``early_stop`` are the paper's; ``use_gravity`` the variation with the accelerometers.
    ``gravity_sigma_rad``: angular σ of the averaged down vector (300 µg bias over
    3.711 m/s², as ``estimation.sapp.nadir``)."""

    timer_s: float = 600.0
    interval_s: float = 20.0
    converge_3sigma_rad: float = math.radians(1.5)
    early_stop: bool = True
    sun_sigma_rad: float = math.radians(0.02)
    use_gravity: bool = False
    gravity_sigma_rad: float = 300e-6 * 9.80665 / 3.711

    def __post_init__(self) -> None:
        _positive(
            self, "timer_s", "interval_s", "converge_3sigma_rad", "sun_sigma_rad",
            "gravity_sigma_rad",
        )  # fmt: skip
        for name in ("early_stop", "use_gravity"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"{name}: must be a bool, got {getattr(self, name)!r}")
        if self.interval_s > self.timer_s:
            raise ValueError("interval_s: must not exceed timer_s")


@dataclass(frozen=True)
class SuncheckParams:
    """Suncheck (sec. 2.3.2): the pass tolerance on the observed-vs-expected sun angle."""

    tolerance_rad: float = math.radians(2.0)

    def __post_init__(self) -> None:
        _positive(self, "tolerance_rad")
        if self.tolerance_rad >= math.pi:
            raise ValueError("tolerance_rad: must be below pi")


@dataclass(frozen=True)
class PancamRequest:
    """Point the mast at ``(az_rad, el_rad)`` (body frame) and take a sun image no earlier
    than ``not_before_t_s``; ``purpose`` names the step (for telemetry)."""

    az_rad: float
    el_rad: float
    not_before_t_s: float
    purpose: str


def _request_state(request: PancamRequest | None) -> dict[str, Any] | None:
    if request is None:
        return None
    return {
        "az_rad": request.az_rad,
        "el_rad": request.el_rad,
        "not_before_t_s": request.not_before_t_s,
        "purpose": request.purpose,
    }


def _request_from(state: Mapping[str, Any] | None) -> PancamRequest | None:
    if state is None:
        return None
    return PancamRequest(
        float(state["az_rad"]),
        float(state["el_rad"]),
        float(state["not_before_t_s"]),
        str(state["purpose"]),
    )


class SunOutcome(enum.Enum):
    """How a camera-mode procedure ended."""

    SUCCESS = "success"
    NEAR_ZENITH = "success, sun near the zenith: estimate not updated"
    CONVERGED = "converged"
    TIMER_CONVERGED = "timer expired, converged"
    NOT_CONVERGED = "timer expired, not converged"
    PLANE_SEARCHED = "sun not found: the whole search plane was imaged"
    PASSED = "check passed"
    NO_SUN = "no sun in the image"
    OUT_OF_TOLERANCE = "sun out of tolerance"


@dataclass(frozen=True)
class SunResult:
    """Outcome of a procedure. ``success``: whether the mode succeeded (for a check:
    passed); ``q_b_ll`` the estimate to adopt (the input one when nothing changes);
    ``updated`` whether it differs; ``final_mast`` the mast (az, el) it leaves, if on the
    sun; ``three_sigma_rad`` Sungaze's last 3σ (NaN otherwise); ``error_rad`` Suncheck's
    observed-vs-expected angle (NaN otherwise); ``n_images`` images taken; ``sun_seen``
    whether any image held an accepted sun; ``quest`` the last QUEST solution (Sungaze)."""

    outcome: SunOutcome
    success: bool
    q_b_ll: FloatArray
    updated: bool
    final_mast: tuple[float, float] | None
    n_images: int
    sun_seen: bool
    three_sigma_rad: float = math.nan
    error_rad: float = math.nan
    quest: QuestSolution | None = None


class Sunfind:
    """Sec. 2.2.2 as a procedure: search guesses (eqs. 2-3), elevation check, two
    confirming images with the motion check, final update (eq. 4)."""

    def __init__(self, q_b_ll: ArrayLike, t_s: float, sun_ll: SunLL, params: SunfindParams):
        self._q = unit_quaternion(q_b_ll)
        self._start_t_s = float(t_s)
        self._sun_ll = sun_ll
        self._p = params
        elev = math.asin(max(-1.0, min(1.0, -float(sun_ll(t_s)[2]))))
        self.plan = search_plan(elev, params.search)
        self._index = 0
        self._phase = "search"
        self._confirm: list[tuple[float, FloatArray]] = []
        self._psi = 0.0
        self._n_images = 0
        self._sun_seen = False
        self.result: SunResult | None = None
        self.request: PancamRequest | None = self._search_request(t_s)

    def state(self) -> dict[str, Any]:
        """A running Sunfind as plain data (``estimation.state``): its constructor's
        ``q_b_ll``, ``start_t_s`` and ``params``, and where the search is."""
        return {
            "q_b_ll": self._q.copy(),
            "start_t_s": self._start_t_s,
            "params": params_state(self._p),
            "index": self._index,
            "phase": self._phase,
            "confirm_t_s": [t for t, _ in self._confirm],
            "confirm_sun_b": [b.copy() for _, b in self._confirm],
            "psi_rad": self._psi,
            "n_images": self._n_images,
            "sun_seen": self._sun_seen,
            "request": _request_state(self.request),
        }

    def load_state(self, state: Mapping[str, Any]) -> None:
        """Load ``state()``'s output onto a Sunfind built from the same constructor
        arguments (a running one: a finished procedure is not kept)."""
        self._index = int(state["index"])
        self._phase = str(state["phase"])
        sun_b = [np.array(b, dtype=np.float64) for b in state["confirm_sun_b"]]
        self._confirm = [(float(t), b) for t, b in zip(state["confirm_t_s"], sun_b, strict=True)]
        self._psi = float(state["psi_rad"])
        self._n_images = int(state["n_images"])
        self._sun_seen = bool(state["sun_seen"])
        self.request = _request_from(state["request"])

    def _search_request(self, t_s: float) -> PancamRequest:
        guess = search_guess(self._q, self._sun_ll(t_s), self._index, self.plan.step_rad)
        return PancamRequest(guess.mast_az_rad, guess.mast_el_rad, t_s, f"search {self._index}")

    def _confirm_request(self, t_s: float, n: int) -> PancamRequest:
        q_guess = quat_multiply(self._q, heading_delta_quat(self._psi))  # eq. 2 with ψ
        sun_b = Rotation.from_quat(q_guess).apply(self._sun_ll(t_s))
        az, el = mast_az_el_for(sun_b)
        return PancamRequest(az, el, t_s, f"confirm {n}")

    def _resume_search(self, t_s: float) -> None:
        self._phase, self._confirm = "search", []
        self._index += 1
        if self._index >= self.plan.n_guesses:
            self._finish(SunOutcome.PLANE_SEARCHED, False, self._q, None)
        else:
            self.request = self._search_request(t_s + self._p.image_spacing_s)

    def _finish(
        self,
        outcome: SunOutcome,
        success: bool,
        q: FloatArray,
        mast: tuple[float, float] | None,
    ) -> None:
        updated = not np.array_equal(q, self._q)
        self.result = SunResult(outcome, success, q, updated, mast, self._n_images, self._sun_seen)
        self.request = None

    def on_image(self, t_s: float, fix: SunFix | None) -> None:
        """The sun finder's result for the image asked for by ``request``, taken at ``t_s``."""
        if self.request is None:
            raise ValueError("on_image: Sunfind has finished")
        self._n_images += 1
        sun_ll = self._sun_ll(t_s)
        if self._phase == "search":
            if fix is None:
                self._resume_search(t_s)
                return
            if not elevation_check(self._q, fix.sun_b, sun_ll, self._p.search).passed:
                self._resume_search(t_s)  # a false sun: back to the search
                return
            self._sun_seen = True
            self._phase = "confirm"
            self._psi = heading_correction_rad(self._q, fix.sun_b, sun_ll)
            self.request = self._confirm_request(t_s + self._p.image_spacing_s, 1)
            return
        if fix is None:
            self._resume_search(t_s)
            return
        self._confirm.append((t_s, fix.sun_b))
        self._psi = heading_correction_rad(self._q, fix.sun_b, sun_ll)
        if len(self._confirm) == 1:
            self.request = self._confirm_request(t_s + self._p.confirm_spacing_s, 2)
            return
        (t1, b1), (t2, b2) = self._confirm
        check = motion_check(b1, b2, self._sun_ll(t1), self._sun_ll(t2), self._p.search)
        if not check.passed:
            self._resume_search(t_s)  # sec. 2.2.2: "continues from the point it left off"
            return
        update = heading_update(self._q, b2, sun_ll, self._p.search)  # eq. 4
        outcome = SunOutcome.SUCCESS if update.applied else SunOutcome.NEAR_ZENITH
        self._finish(outcome, True, update.q_b_ll, mast_az_el_for(b2))


class Sungaze:
    """Sec. 2.2.3 as a procedure: images at a fixed mast pointing every ``interval_s``,
    QUEST after each, early stop at the 3σ threshold or the timer (module docstring)."""

    def __init__(
        self,
        q_b_ll: ArrayLike,
        t_s: float,
        mast: tuple[float, float],
        sun_ll: SunLL,
        params: SungazeParams,
        down_b: ArrayLike | None = None,
    ):
        self._q = unit_quaternion(q_b_ll)
        # The estimate stays put while Sungaze runs: body to LL is built once, not per image.
        self._R_ll_b = Rotation.from_quat(self._q).inv()
        self._start_t_s = float(t_s)
        self._down_b = None if down_b is None else np.array(down_b, dtype=np.float64)
        self._sun_ll = sun_ll
        self._p = params
        self._t0: float | None = None  # the timer runs from the first image
        self._mast = mast
        self._acc = QuestAccumulator()
        self._n_images = 0
        self._n_sun = 0
        self._last: QuestSolution | None = None
        self.result: SunResult | None = None
        if params.use_gravity:
            if down_b is None:
                raise ValueError("down_b: the gravity variation needs an accelerometer average")
            self._acc.add(
                self._R_ll_b.apply(unit_vector(down_b, "down_b")),
                DOWN_LL,
                params.gravity_sigma_rad,
            )
        self.request: PancamRequest | None = PancamRequest(mast[0], mast[1], t_s, "sungaze 0")

    def state(self) -> dict[str, Any]:
        """A running Sungaze as plain data (``estimation.state``): its constructor's
        arguments and the QUEST sums so far."""
        return {
            "q_b_ll": self._q.copy(),
            "start_t_s": self._start_t_s,
            "mast": list(self._mast),
            "params": params_state(self._p),
            "down_b": None if self._down_b is None else self._down_b.copy(),
            "t0_s": self._t0,
            "quest": self._acc.state(),
            "n_images": self._n_images,
            "n_sun": self._n_sun,
            "request": _request_state(self.request),
        }

    def load_state(self, state: Mapping[str, Any]) -> None:
        """Load ``state()``'s output onto a Sungaze built from the same constructor
        arguments (a running one)."""
        self._t0 = None if state["t0_s"] is None else float(state["t0_s"])
        self._acc.load_state(state["quest"])
        self._n_images = int(state["n_images"])
        self._n_sun = int(state["n_sun"])
        # The last solution is QUEST on the sums as they were after the last sun image,
        # which are the sums now (nothing is added without a sun).
        self._last = self._acc.solve() if self._n_sun else None
        self.request = _request_from(state["request"])

    @property
    def three_sigma_rad(self) -> float:
        """The latest QUEST 3σ (largest axis), rad; inf before the attitude is observable."""
        if self._last is None or not self._last.observable:
            return math.inf
        return math.radians(self._last.three_sigma_deg)

    def on_image(self, t_s: float, fix: SunFix | None) -> None:
        """The sun finder's result for the image taken at ``t_s``."""
        if self.request is None:
            raise ValueError("on_image: Sungaze has finished")
        self._n_images += 1
        if self._t0 is None:
            self._t0 = t_s
        if fix is not None:
            self._n_sun += 1
            b_ll = self._R_ll_b.apply(fix.sun_b)  # observed, in LL
            self._acc.add(b_ll, self._sun_ll(t_s), self._p.sun_sigma_rad)  # expected: IVP
            self._last = self._acc.solve()
        converged = self.three_sigma_rad <= self._p.converge_3sigma_rad
        timer_out = t_s - self._t0 + self._p.interval_s > self._p.timer_s + 1e-9
        if converged and (self._p.early_stop or timer_out):
            self._finish(SunOutcome.CONVERGED if not timer_out else SunOutcome.TIMER_CONVERGED)
        elif timer_out:
            self._finish(SunOutcome.NOT_CONVERGED)
        else:
            n = self._n_images
            self.request = PancamRequest(
                self._mast[0], self._mast[1], t_s + self._p.interval_s, f"sungaze {n}"
            )

    def _finish(self, outcome: SunOutcome) -> None:
        success = outcome is not SunOutcome.NOT_CONVERGED
        q = self._q
        if success:
            assert self._last is not None
            q = quat_canonical(quat_multiply(self._q, self._last.q_b_r))  # q̂ ⊗ C
        self.result = SunResult(
            outcome,
            success,
            q,
            success,
            self._mast if self._n_sun else None,
            self._n_images,
            self._n_sun > 0,
            three_sigma_rad=self.three_sigma_rad,
            quest=self._last,
        )
        self.request = None


class Suncheck:
    """Sec. 2.3.2 as a procedure: one image where the estimate puts the sun."""

    def __init__(self, q_b_ll: ArrayLike, t_s: float, sun_ll: SunLL, params: SuncheckParams):
        self._q = unit_quaternion(q_b_ll)
        self._start_t_s = float(t_s)
        self._sun_ll = sun_ll
        self._p = params
        guess = search_guess(self._q, sun_ll(t_s), 0, 2.0 * math.pi)  # the estimate's sun
        self.result: SunResult | None = None
        self.request: PancamRequest | None = PancamRequest(
            guess.mast_az_rad, guess.mast_el_rad, t_s, "suncheck"
        )

    def state(self) -> dict[str, Any]:
        """A waiting Suncheck as plain data: its constructor's arguments and its request."""
        return {
            "q_b_ll": self._q.copy(),
            "start_t_s": self._start_t_s,
            "params": params_state(self._p),
            "request": _request_state(self.request),
        }

    def load_state(self, state: Mapping[str, Any]) -> None:
        """Load ``state()``'s output onto a Suncheck built from the same arguments."""
        self.request = _request_from(state["request"])

    def on_image(self, t_s: float, fix: SunFix | None) -> None:
        """The sun finder's result for the image taken at ``t_s``."""
        if self.request is None:
            raise ValueError("on_image: Suncheck has finished")
        self.request = None
        if fix is None:
            self.result = SunResult(SunOutcome.NO_SUN, False, self._q, False, None, 1, False)
            return
        expected_b = Rotation.from_quat(self._q).apply(self._sun_ll(t_s))
        error = angle_between_rad(unit_vector(fix.sun_b, "sun_b"), expected_b)
        passed = error <= self._p.tolerance_rad
        outcome = SunOutcome.PASSED if passed else SunOutcome.OUT_OF_TOLERANCE
        mast = mast_az_el_for(fix.sun_b)
        self.result = SunResult(outcome, passed, self._q, False, mast, 1, True, error_rad=error)
