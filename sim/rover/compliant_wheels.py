"""Wheel rotations of a compliant wheel controller: every wheel rolls without slip.

Balaram 2000 section 4 validates its kinematic estimator on a kinematic simulator (ROAMS)
whose wheels correspond to "a highly compliant control algorithm at each wheel minimizing
slip in the rolling direction": each wheel turns exactly as much as its contact point
needs to roll over the terrain, so the drive rates vary as the wheels climb and descend
(its Figure 5), and the averaged wheel odometry over-counts the distance the body moves
(the paper's 2 % on surface eq. 22). ``sim.rover.drive`` turns every wheel by the commanded
amount instead; this module recomputes the wheel angles of a settled truth trajectory as
the compliant controller would have turned them, so the encoders read what Rocky-7's
simulator gave its estimator.

Rolling without slip at wheel ``i`` (thin wheel, contact radius ``r``): the wheel
material at the contact point ``p = c + r d`` has no velocity along the rolling direction
``t = a × d`` (axle ``a``, unit ``d`` from the centre ``c`` to the contact). With the
wheel spinning forwards at ``ψ̇`` relative to its link (``-ψ̇ a``, as a forward roll turns
the bottom backwards) and the link turning at ``Ω_link``::

    t · (ċ + (Ω_link - ψ̇ a) × r d) = 0   =>   ψ̇ = t·ċ / r + Ω_link·a

Over one 8 Hz interval: ``Δψ = Δc · t_mid / r + (rotation of the link about the axle)``,
with ``t_mid`` the rolling direction halfway (second order in the step). Contact points
come from settling each truth pose again (``sim.rover.settle``, started from the truth).

Frames: Site ``s`` (x North, y East, z Down); wheel order ``WHEEL_NAMES``.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from sim.errors import InputError
from sim.rover.geometry import MER_GEOMETRY, STEERED_INDEX, RoverGeometry, wheel_kinematics
from sim.rover.settle import settle
from sim.rover.truth import TruthTrajectory
from sim.world.terrain import Terrain

FloatArray = NDArray[np.float64]

RESETTLE_TOL_M = 1e-6  # contact gaps of the re-settled poses (the truth settled to 1e-4)


def _unit(v: FloatArray) -> FloatArray:
    out: FloatArray = v / np.linalg.norm(v, axis=-1, keepdims=True)
    return out


def compliant_wheel_angles(
    terrain: Terrain,
    truth: TruthTrajectory,
    geometry: RoverGeometry = MER_GEOMETRY,
    sinkage_m: float = 0.0,
) -> FloatArray:
    """Cumulative wheel angles (N, 6), rad, of wheels that roll without slip along ``truth``.

    Starts from ``truth.wheel_angle_rad[0]``; positive rolls forward. ``sinkage_m`` is the
    wheel sinkage the truth was settled with (the contact radius is ``r - sinkage``).
    """
    n = len(truth)
    if n < 2:
        raise InputError("truth", "needs at least two samples")
    if not (np.isfinite(sinkage_m) and 0.0 <= sinkage_m < geometry.wheel_radius_m):
        raise InputError("sinkage_m", "must be in [0, wheel radius)")
    R_s_b = Rotation.from_quat(truth.q_s_b)
    yaw, pitch, roll = R_s_b.as_euler("ZYX").T
    guess = np.column_stack([truth.p_s[:, 2], roll, pitch, truth.rocker_rad, truth.bogie_rad])
    s = settle(
        terrain,
        truth.p_s[:, 0],
        truth.p_s[:, 1],
        yaw,
        guess=guess,
        steer_rad=truth.steer_rad,
        sinkage_m=sinkage_m,
        geometry=geometry,
        tol_m=RESETTLE_TOL_M,
    )
    if not np.all(s.converged):
        raise InputError("truth", f"{int(np.sum(~s.converged))} poses do not settle again")
    kin = wheel_kinematics(geometry, truth.rocker_rad, truth.bogie_rad, truth.steer_rad)
    R = R_s_b.as_matrix()  # (N, 3, 3)
    centre_s = truth.p_s[:, None, :] + np.einsum("nij,nwj->nwi", R, kin.centre_b)
    axle_s = np.einsum("nij,nwj->nwi", R, kin.axle_b)
    d = _unit(s.contact_s - centre_s)
    t = _unit(np.cross(axle_s, d))  # rolling direction, forwards
    t_mid = _unit(t[:-1] + t[1:])
    r = geometry.wheel_radius_m - sinkage_m
    rolled = np.sum(np.diff(centre_s, axis=0) * t_mid, axis=-1) / r

    # The link's own rotation about the axle: R_s_link = R_s_b Ry(link) (steering is a
    # rotation about the link's z, fixed during a primitive), relative between samples.
    sigma = np.zeros((n, 6))
    sigma[:, list(STEERED_INDEX)] = truth.steer_rad
    link_rotvec = np.zeros((n * 6, 3))
    link_rotvec[:, 1] = kin.link_rad.reshape(-1)
    link = Rotation.from_matrix(np.repeat(R, 6, axis=0)) * Rotation.from_rotvec(link_rotvec)
    quats = link.as_quat().reshape(n, 6, 4)
    rel = (
        Rotation.from_quat(quats[:-1].reshape(-1, 4)).inv()
        * Rotation.from_quat(quats[1:].reshape(-1, 4))
    ).as_rotvec()
    axle_link = np.stack([-np.sin(sigma), np.cos(sigma), np.zeros_like(sigma)], axis=-1)
    turned = np.sum(rel.reshape(n - 1, 6, 3) * axle_link[:-1], axis=-1)

    out: FloatArray = truth.wheel_angle_rad[0] + np.concatenate(
        [np.zeros((1, 6)), np.cumsum(rolled + turned, axis=0)]
    )
    return out


def with_compliant_wheels(
    terrain: Terrain,
    truth: TruthTrajectory,
    geometry: RoverGeometry = MER_GEOMETRY,
    sinkage_m: float = 0.0,
) -> TruthTrajectory:
    """``truth`` with its wheel angles replaced by ``compliant_wheel_angles``."""
    return replace(
        truth, wheel_angle_rad=compliant_wheel_angles(terrain, truth, geometry, sinkage_m)
    )
