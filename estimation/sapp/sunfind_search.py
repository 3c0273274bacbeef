"""Sunfind's search geometry, confirmation checks and heading update.

Ali et al. 2005, "Attitude and Position Estimation on the Mars Exploration Rovers"
(Ali et al. 2005), sec. 2.2.2 and Figure 2: eq. (2) the search guesses, eq. (3) the heading steps,
eq. (4) the final heading update. The state machine that moves the mast and takes the
images is not here; this module is the pure geometry it needs. The estimate ``q_b_ll``
(``^Bq^{LL}``) is assumed to have the right tilt (Nadir Update ran first); nothing here
changes the tilt.

Heading steps (eqs. 2-3). ``δq_i^{LL} = [0, 0, sin(iΔξ/2), cos(iΔξ/2)]`` is a rotation by
``iΔξ`` about LL Down, multiplied on the right: ``R_b_ll(q_i) = R_b_ll(q) Rz(iΔξ)``. So the
predicted body sun of guess ``i`` is ``p_b(i) = R_b_ll(q) Rz(iΔξ) sun_ll``: the expected sun
turned by ``iΔξ`` in azimuth (clockwise seen from above, North towards East) along the
cone of constant elevation ``e`` (Figure 2), then seen with the estimate. The nadir in body,
``R_b_ll(q_i) [0, 0, 1] = R_b_ll(q) [0, 0, 1]``, is the same for every guess (tilt kept). If
the estimate's tilt is right, the truth is exactly ``q_true = q ⊗ δq(ψ)`` for one heading
error ``ψ``, so the search has one unknown, ``ψ`` in ``[0, 2π)``.

The step Δξ ("varies with the camera field of view and the image elevation"), derived here.
Two directions on the cone ``e`` with azimuths ``φ`` apart are ``δ`` apart with
``sin(δ/2) = cos(e) sin(φ/2)`` (chord lengths: the cone is a circle of radius ``cos e``).
A square field of full width ``F`` holds every direction within ``F/2`` of the boresight
(the inscribed cone of the square image touches its edges), whatever the image roll, so
this holds for any rover tilt and mast pose. Keep a margin and count on the disk of radius
``r = (1 - overlap_fraction) F/2`` only. The cone arc between aims ``i`` and ``i+1`` is
nearest to one of them, at most ``Δξ/2`` in azimuth away, so it is covered when
``cos(e) sin(Δξ/4) <= sin(r/2)``, i.e.::

    Δξ_max = 4 asin(min(1, sin(r/2) / cos e))

``Δξ_max`` reaches 360 deg (one image sees the whole cone) when ``90° - e <= r/2`` about:
near the zenith the cone is smaller than the image. The number of guesses is
``N = ceil(2π / Δξ_max)``, and the step used is ``Δξ = 2π / N`` (evenly spaced, never
larger than ``Δξ_max``). The often-quoted ``2 asin(sin(r)/cos e)`` bounds the distance of
the *great-circle* midpoint between aims; the cone arc bulges away from it towards the
zenith, so that formula leaves a thin gap (0.06 deg at e = 60 deg, r = 8 deg) which this
one does not. If ``sun_ll`` is evaluated at each image's time (as IVP gives it), the search
moves with the sun and the coverage holds however long the search takes.

Defaults (the paper leaves every threshold to the ground, sec. 2):

- ``overlap_fraction = 0.25``: the usable radius is 6 deg of Pancam's 8 deg half field.
  The 2 deg margin absorbs the sun disk (0.19 deg radius at perihelion) and the sun
  finder's 4 px edge margin (0.06 deg, ``estimation.sapp.sunfind``), the tilt error after Nadir
  Update (about 0.05 deg per axis 1 sigma, ``estimation.sapp.nadir``) and the mast pointing
  error, together under 1 deg, twice over. 30 images at the horizon, 15 at e = 60 deg,
  6 at 80 deg and a single one above 87 deg.
- ``elevation_tolerance_rad = 2 deg``: the observed elevation errs by the tilt error plus
  the centroid and mast pointing errors (a few tenths of a degree at 3 sigma); 2 deg passes
  those with room and still rejects a false sun in three quarters of a 16 deg frame taken
  on the cone.
- ``motion_tolerance_rad = 0.05 deg`` (about 3 Pancam pixels): the sun moves at most about
  0.25 deg per minute (Mars turns 360 deg per 24.66 h), and a scene feature or an artefact
  not at infinity does not move with it. The observed motion is the angle between the two
  body sun vectors of a rover at rest, which no attitude error touches; only centroid and
  mast repointing errors enter. The check can only tell the sun from a fixed object if the
  expected motion exceeds the tolerance (``MotionCheck.discriminating``): space the
  confirming images by a minute or more.
- ``zenith_exclusion_rad = 5 deg``: the azimuth of a sun ``z`` from the zenith is blurred
  by a position error ``ε`` into a heading error of about ``ε / sin z``: 11.5 ``ε`` at
  5 deg, so 0.1 deg of tilt error costs about 1 deg of heading, still Coarse; closer in
  the update is skipped (sec. 2.2.2, "the heading cannot be determined").

Heading update (eq. 4). Observed ``sun_b`` taken to LL with the estimate,
``s_ll = R_ll_b(q) sun_b``, is ``Rz(ψ) sun_ll`` when the tilt is right, so
``ψ = az(s_ll) - az(sun_ll)`` and ``^Bq_+^{LL} = ^Bq_-^{LL} ⊗ δq(ψ)`` makes the predicted
body sun equal the observed one. The same ``ψ`` points each confirming image.

Elevation: ``el = asin(-s_ll · Down) = asin(-n_b · sun_b)`` with ``n_b = R_b_ll(q) Down``,
so it depends on the tilt only, never on the heading.

Flight software: numpy and scipy only; bad arguments raise ``ValueError`` naming the
parameter.

>>> plan = search_plan(math.radians(30.0))
>>> plan.n_guesses, round(math.degrees(plan.step_rad), 3)
(26, 13.846)
>>> q = np.array([0.0, 0.0, 0.0, 1.0])
>>> sun_ll = np.array([0.0, 1.0, -1.0]) / math.sqrt(2.0)  # East, 45 deg up
>>> g = search_guess(q, sun_ll, 1, math.pi / 2)  # turned 90 deg clockwise: South
>>> np.round(g.sun_b, 12).tolist(), round(math.degrees(g.mast_az_rad), 9)
([-0.707106781187, 0.0, -0.707106781187], 180.0)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from estimation.camera_model import PANCAM_FOV_RAD, mast_az_el_for
from estimation.checks import angle_between_rad, unit_quaternion, unit_vector
from estimation.quaternion import quat_canonical, quat_multiply

FloatArray = NDArray[np.float64]

DOWN_LL = np.array([0.0, 0.0, 1.0])  # LL z is Down (docs/CONVENTIONS.md)
_TWO_PI = 2.0 * math.pi
_STEP_SLACK = 1e-12  # 2π / Δξ_max = 30.000000000001 still means 30 guesses


@dataclass(frozen=True)
class SunfindSearchParams:
    """Sunfind geometry parameters; the defaults are argued in the module docstring."""

    fov_rad: float = PANCAM_FOV_RAD  # full width of the square field (Pancam 16 deg)
    overlap_fraction: float = 0.25  # of the half field kept as margin
    elevation_tolerance_rad: float = math.radians(2.0)
    motion_tolerance_rad: float = math.radians(0.05)
    zenith_exclusion_rad: float = math.radians(5.0)

    def __post_init__(self) -> None:
        if not (0.0 < self.fov_rad < math.pi):
            raise ValueError(f"fov_rad: must be in (0, pi), got {self.fov_rad}")
        if not (0.0 <= self.overlap_fraction < 1.0):
            raise ValueError(f"overlap_fraction: must be in [0, 1), got {self.overlap_fraction}")
        for name in ("elevation_tolerance_rad", "motion_tolerance_rad"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"{name}: must be positive and finite, got {value}")
        if not (0.0 <= self.zenith_exclusion_rad < 0.5 * math.pi):
            raise ValueError(
                f"zenith_exclusion_rad: must be in [0, pi/2), got {self.zenith_exclusion_rad}"
            )

    @property
    def footprint_radius_rad(self) -> float:
        """``r = (1 - overlap_fraction) F / 2``: the usable angular radius of one image."""
        return (1.0 - self.overlap_fraction) * 0.5 * self.fov_rad


@dataclass(frozen=True)
class SearchPlan:
    """Search of the cone at elevation ``sun_elev_rad``: ``n_guesses`` images ``step_rad``
    apart in azimuth (``= 2π / n_guesses <= max_step_rad``, the Δξ of eq. 3)."""

    sun_elev_rad: float
    max_step_rad: float
    step_rad: float
    n_guesses: int


@dataclass(frozen=True)
class SearchGuess:
    """Guess ``index`` (eq. 2): attitude ``q_b_ll``, predicted unit sun ``sun_b`` (3,) and
    the mast ``(mast_az_rad, mast_el_rad)`` that points Pancam at it."""

    index: int
    q_b_ll: FloatArray
    sun_b: FloatArray
    mast_az_rad: float
    mast_el_rad: float


@dataclass(frozen=True)
class ElevationCheck:
    """Confirmation-phase elevation check: observed and expected sun elevation (rad),
    ``error_rad = observed - expected``, and whether ``|error| <= tolerance``."""

    observed_elev_rad: float
    expected_elev_rad: float
    error_rad: float
    passed: bool


@dataclass(frozen=True)
class MotionCheck:
    """Confirmation-phase motion check: observed and expected sun motion between the two
    images (rad), ``error_rad = observed - expected``, ``passed`` if ``|error| <=
    tolerance``, ``discriminating`` if a sun standing still would have failed it."""

    observed_rad: float
    expected_rad: float
    error_rad: float
    passed: bool
    discriminating: bool


@dataclass(frozen=True)
class HeadingUpdate:
    """Eq. (4): the updated ``q_b_ll``, the correction ``delta_q_ll`` (right-multiplied),
    its angle ``delta_q_ll_angle_rad`` about LL Down (in ``(-π, π]``; minus the change of
    heading, as in ``estimation.sapp.gyrocompass``), and ``applied``
    (False near the zenith: estimate unchanged, Sunfind still succeeds)."""

    q_b_ll: FloatArray
    delta_q_ll: FloatArray
    delta_q_ll_angle_rad: float
    applied: bool


def elevation_rad(v_ll: ArrayLike) -> float:
    """Elevation above the horizon of LL direction ``v_ll`` (3,, any length), rad."""
    v = unit_vector(v_ll, "v_ll")
    return math.atan2(-v[2], math.hypot(v[0], v[1]))  # Down is +z: up is -z


def search_plan(sun_elev_rad: float, params: SunfindSearchParams | None = None) -> SearchPlan:
    """Δξ and the number of guesses that cover the cone at ``sun_elev_rad`` (module doc).

    >>> search_plan(math.radians(89.0)).n_guesses  # the cone fits in one image
    1
    """
    p = params if params is not None else SunfindSearchParams()
    if not (math.isfinite(sun_elev_rad) and abs(sun_elev_rad) <= 0.5 * math.pi):
        raise ValueError(f"sun_elev_rad: must be in [-pi/2, pi/2], got {sun_elev_rad}")
    r = p.footprint_radius_rad
    cos_e = math.cos(sun_elev_rad)
    ratio = 1.0 if cos_e <= math.sin(0.5 * r) else math.sin(0.5 * r) / cos_e
    max_step = 4.0 * math.asin(ratio)  # cos(e) sin(Δξ/4) <= sin(r/2)
    n = max(1, math.ceil(_TWO_PI / max_step - _STEP_SLACK))
    return SearchPlan(sun_elev_rad, max_step, _TWO_PI / n, n)


def heading_delta_quat(angle_rad: float) -> FloatArray:
    """``δq^{LL}`` of eq. (3): rotation by ``angle_rad`` about LL Down, ``[x, y, z, w]``.

    >>> heading_delta_quat(math.pi).round(12).tolist()
    [0.0, 0.0, 1.0, 0.0]
    """
    if not math.isfinite(angle_rad):
        raise ValueError(f"angle_rad: must be finite, got {angle_rad}")
    return np.array([0.0, 0.0, math.sin(0.5 * angle_rad), math.cos(0.5 * angle_rad)])  # eq. 3


def search_guess(q_b_ll: ArrayLike, sun_ll: ArrayLike, index: int, step_rad: float) -> SearchGuess:
    """Guess ``index`` of eq. (2) and where it puts the sun.

    ``q_b_ll`` is the current estimate (unit (4,)); ``sun_ll`` (3,, any length) the expected
    sun from IVP at the image time; ``step_rad`` the Δξ of ``search_plan``. Returns
    ``q_i = q ⊗ δq(i Δξ)`` (eqs. 2-3), ``p_b(i) = R_b_ll(q_i) sun_ll`` and the mast pose.
    """
    q = unit_quaternion(q_b_ll)
    s_ll = unit_vector(sun_ll, "sun_ll")
    if index < 0:
        raise ValueError(f"index: must be >= 0, got {index}")
    if not (math.isfinite(step_rad) and 0.0 < step_rad <= _TWO_PI):
        raise ValueError(f"step_rad: must be in (0, 2 pi], got {step_rad}")
    q_i = quat_canonical(quat_multiply(q, heading_delta_quat(index * step_rad)))  # eqs. 2-3
    sun_b: FloatArray = Rotation.from_quat(q_i).apply(s_ll)  # p(i) = R_b_ll(q_i) sun_ll
    az, el = mast_az_el_for(sun_b)
    return SearchGuess(index, q_i, sun_b, az, el)


def observed_elevation_rad(q_b_ll: ArrayLike, sun_b: ArrayLike) -> float:
    """Elevation of observed body sun ``sun_b`` (3,) in LL with the estimate's tilt, rad.

    ``el = asin(-n_b · sun_b)``, ``n_b = R_b_ll Down``: the heading plays no part.
    """
    n_b = Rotation.from_quat(unit_quaternion(q_b_ll)).apply(DOWN_LL)
    s_b = unit_vector(sun_b, "sun_b")
    return math.asin(max(-1.0, min(1.0, -float(np.dot(n_b, s_b)))))


def elevation_check(
    q_b_ll: ArrayLike,
    sun_b_obs: ArrayLike,
    sun_ll_expected: ArrayLike,
    params: SunfindSearchParams | None = None,
) -> ElevationCheck:
    """Sec. 2.2.2 elevation check of a potential sun ``sun_b_obs`` (3,) seen with estimate
    ``q_b_ll`` against the IVP sun ``sun_ll_expected`` (3,) at the image time."""
    p = params if params is not None else SunfindSearchParams()
    observed = observed_elevation_rad(q_b_ll, sun_b_obs)
    expected = elevation_rad(unit_vector(sun_ll_expected, "sun_ll_expected"))
    error = observed - expected
    return ElevationCheck(observed, expected, error, abs(error) <= p.elevation_tolerance_rad)


def motion_check(
    sun_b_obs_1: ArrayLike,
    sun_b_obs_2: ArrayLike,
    sun_ll_1: ArrayLike,
    sun_ll_2: ArrayLike,
    params: SunfindSearchParams | None = None,
) -> MotionCheck:
    """Sec. 2.2.2 motion check between the two confirming images of a rover at rest.

    ``sun_b_obs_1``/``_2`` (3,) are the observed body sun vectors, ``sun_ll_1``/``_2`` (3,)
    the IVP suns at the two image times. A rigid rotation keeps angles, so the observed
    motion ``angle(sun_b_1, sun_b_2)`` is compared directly with ``angle(sun_ll_1,
    sun_ll_2)``; no attitude enters.
    """
    p = params if params is not None else SunfindSearchParams()
    observed = angle_between_rad(
        unit_vector(sun_b_obs_1, "sun_b_obs_1"), unit_vector(sun_b_obs_2, "sun_b_obs_2")
    )
    expected = angle_between_rad(
        unit_vector(sun_ll_1, "sun_ll_1"), unit_vector(sun_ll_2, "sun_ll_2")
    )
    error = observed - expected
    tol = p.motion_tolerance_rad
    return MotionCheck(observed, expected, error, abs(error) <= tol, expected > tol)


def heading_correction_rad(q_b_ll: ArrayLike, sun_b_obs: ArrayLike, sun_ll: ArrayLike) -> float:
    """Angle ``ψ`` in ``(-π, π]`` about LL Down with ``R_b_ll(q ⊗ δq(ψ)) sun_ll`` at the
    azimuth of ``sun_b_obs``: ``ψ = az(R_ll_b(q) sun_b_obs) - az(sun_ll)`` (module doc).

    Raises ``ValueError`` if either sun is exactly at the zenith or nadir (no azimuth).
    """
    q = unit_quaternion(q_b_ll)
    s_obs_ll = Rotation.from_quat(q).inv().apply(unit_vector(sun_b_obs, "sun_b_obs"))
    s_ll = unit_vector(sun_ll, "sun_ll")
    if math.hypot(s_obs_ll[0], s_obs_ll[1]) < 1e-12:
        raise ValueError("sun_b_obs: is at the zenith or nadir, its azimuth is undefined")
    if math.hypot(s_ll[0], s_ll[1]) < 1e-12:
        raise ValueError("sun_ll: is at the zenith or nadir, its azimuth is undefined")
    # Azimuth clockwise from North = atan2(East, North); the difference, wrapped.
    diff = math.atan2(s_obs_ll[1], s_obs_ll[0]) - math.atan2(s_ll[1], s_ll[0])
    psi = math.atan2(math.sin(diff), math.cos(diff))
    return math.pi if psi == -math.pi else psi


def heading_update(
    q_b_ll: ArrayLike,
    sun_b_obs: ArrayLike,
    sun_ll: ArrayLike,
    params: SunfindSearchParams | None = None,
) -> HeadingUpdate:
    """Eq. (4): ``^Bq_+^{LL} = ^Bq_-^{LL} ⊗ δq^{LL}`` from a confirmed sun.

    ``q_b_ll`` is the estimate (right tilt), ``sun_b_obs`` (3,) the observed body sun and
    ``sun_ll`` (3,) the IVP sun at that image's time. When either sun is within
    ``zenith_exclusion_rad`` of the zenith the update is skipped (``applied=False``, the
    estimate returned unchanged).
    """
    p = params if params is not None else SunfindSearchParams()
    q = unit_quaternion(q_b_ll)
    limit = 0.5 * math.pi - p.zenith_exclusion_rad
    near_zenith = (
        elevation_rad(unit_vector(sun_ll, "sun_ll")) >= limit
        or observed_elevation_rad(q, sun_b_obs) >= limit
    )
    if near_zenith:  # sec. 2.2.2: heading not determinable, no update
        return HeadingUpdate(q, np.array([0.0, 0.0, 0.0, 1.0]), 0.0, False)
    psi = heading_correction_rad(q, sun_b_obs, sun_ll)
    delta_q = heading_delta_quat(psi)  # eq. 3 form, angle ψ
    q_new = quat_canonical(quat_multiply(q, delta_q))  # eq. 4
    return HeadingUpdate(q_new, delta_q, psi, True)
