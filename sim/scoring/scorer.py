"""The scorer: the truth record of each downlink frame, from the world and the downlink.

For the frames the recorder keeps (``sim.loop.frames``), the scorer takes the rover's
downlink figures (its attitude and mission position estimates, the HGA gimbal angles it would
command, the side estimators' poses) and the world's truth at the same cycles (the true
attitude, the position in the simulator's frame, the suspension and steering), and makes the
``Truth`` records: the true pose in the mission and current Site frames, the true sky, the
errors of the estimate, and the true error and margin of the HGA pointed from it
(``sim.rover.hga``). Position errors are in the mission frame (the first Site's), whose true
origin is where the rover started; the true Site origins are kept as the operators plant Sites.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from estimation.quaternion import quat_angle_between, quat_conjugate, quat_rotate
from estimation.sapp.hga_pointing import HGA_POINTING_REQUIREMENT_DEG
from sim.loop.sky import SkyNodes
from sim.rover.hga import hga_errors_deg
from sim.scoring.truth import Truth
from sim.world.mars_frames import earth_ll_truth, elevation_rad, sun_ll_truth

FloatArray = NDArray[np.float64]
SidePose = tuple[FloatArray, FloatArray | None]  # p_mission (3,), q_b_ll (4,) or None


@dataclass(frozen=True)
class DownlinkFigures:
    """The downlink figures of ``K`` kept cycles that are scored (rad and metres, arrays):
    ``t_s`` (K,), ``q_b_ll_est`` (K, 4), ``p_mission_est`` (K, 3), ``site_index`` (K),
    the HGA gimbal angles ``hga_az_rad``, ``hga_el_rad`` (K,) and their boresight in the body
    ``hga_boresight_b`` (K, 3), and each frame's side estimator poses ``side``."""

    t_s: FloatArray
    q_b_ll_est: FloatArray
    p_mission_est: FloatArray
    site_index: Sequence[int]
    hga_az_rad: FloatArray
    hga_el_rad: FloatArray
    hga_boresight_b: FloatArray
    side: Sequence[Mapping[str, SidePose]]


@dataclass(frozen=True)
class WorldTruth:
    """The world at the same ``K`` cycles: ``q_ll_b`` (K, 4) the true attitude, ``p_world``
    (K, 3) the position in the simulator's frame, and the joints ``rocker_rad`` (K,),
    ``bogie_rad`` (K, 2) and ``steer_rad`` (K, 4)."""

    q_ll_b: FloatArray
    p_world: FloatArray
    rocker_rad: FloatArray
    bogie_rad: FloatArray
    steer_rad: FloatArray


class Scorer:
    """Makes the truth records of a session's frames at a site (``lat_rad``,
    ``lon_east_rad``) whose rover started at ``p_start_world``."""

    def __init__(self, lat_rad: float, lon_east_rad: float, p_start_world: FloatArray) -> None:
        self._sky = SkyNodes(
            [
                lambda t: earth_ll_truth(t, lat_rad, lon_east_rad),
                lambda t: sun_ll_truth(t, lat_rad, lon_east_rad),
            ]
        )
        self.site_origins_true: list[FloatArray] = [np.array(p_start_world, dtype=np.float64)]

    def plant_site(self, p_world: FloatArray) -> None:
        """A Site was planted with the rover at ``p_world``: the new Site's true origin."""
        self.site_origins_true.append(np.array(p_world, dtype=np.float64))

    def score(self, est: DownlinkFigures, world: WorldTruth) -> list[Truth]:
        """The truth records of the ``K`` cycles (module docstring), for all K at once."""
        origins = self.site_origins_true
        q_ll_b = world.q_ll_b / np.linalg.norm(world.q_ll_b, axis=1, keepdims=True)
        q_b_ll_true = quat_conjugate(q_ll_b)
        earth_true, sun_true = self._sky.at(est.t_s)
        hga_error = hga_errors_deg(est.hga_az_rad, est.hga_el_rad, q_b_ll_true, earth_true)
        boresight_ll = quat_rotate(q_ll_b, est.hga_boresight_b)  # R_ll_b: true body to LL
        att_err_deg = np.degrees(quat_angle_between(est.q_b_ll_est, q_b_ll_true))
        p_mission_true = world.p_world - origins[0]
        last = len(origins) - 1
        p_s_true = world.p_world - np.array([origins[min(i, last)] for i in est.site_index])
        position_error = np.linalg.norm(est.p_mission_est - p_mission_true, axis=1)
        earth_up = elevation_rad(earth_true) > 0.0
        columns = (
            est.t_s.tolist(),
            q_b_ll_true.tolist(),
            p_s_true.tolist(),
            p_mission_true.tolist(),
            hga_error.tolist(),
            earth_up.tolist(),
            att_err_deg.tolist(),
            position_error.tolist(),
            np.degrees(world.rocker_rad).tolist(),
            np.degrees(world.bogie_rad).tolist(),
            np.degrees(world.steer_rad).tolist(),
            sun_true.tolist(),
            earth_true.tolist(),
            boresight_ll.tolist(),
        )
        out: list[Truth] = []
        for j, row in enumerate(zip(*columns, strict=True)):
            (t_j, q_j, p_s_j, p_m_j, hga_j, up_j, att_j, pos_j, rocker_j, bogie_j) = row[:10]
            steer_j, sun_j, earth_j, bore_j = row[10:]
            out.append(
                Truth(
                    t_s=t_j,
                    q_b_ll_true=q_j,
                    p_s_true=p_s_j,
                    p_mission_true=p_m_j,
                    hga_error_deg=hga_j,
                    hga_margin_deg=HGA_POINTING_REQUIREMENT_DEG - hga_j,
                    earth_up=up_j,
                    attitude_error_deg=att_j,
                    position_error_m=pos_j,
                    rocker_deg=rocker_j,
                    bogie_deg=bogie_j,
                    steer_deg=steer_j,
                    sun_ll_true=sun_j,
                    earth_ll_true=earth_j,
                    hga_boresight_ll_true=bore_j,
                    estimators=_side_errors(est.side[j], p_mission_true[j], q_b_ll_true[j]),
                )
            )
        return out

    # ---- checkpoint -----------------------------------------------------------------------

    def state(self) -> dict[str, Any]:
        """The true Site origins and the sky's nodes (plain data)."""
        return {
            "site_origins_true": [p.copy() for p in self.site_origins_true],
            "sky": self._sky.state(),
        }

    def load_state(self, state: Mapping[str, Any]) -> None:
        """Load ``state`` (``state()``) onto a scorer of the same site."""
        self.site_origins_true = [np.array(p, dtype=np.float64) for p in state["site_origins_true"]]
        self._sky.load_state(state["sky"])


def _side_errors(
    side: Mapping[str, SidePose], p_mission_true: FloatArray, q_b_ll_true: FloatArray
) -> dict[str, Any]:
    """Each side estimator's errors against the truth (position-only ones: no attitude)."""
    out: dict[str, Any] = {}
    for name, (p, q) in side.items():
        att = None if q is None else float(quat_angle_between(q, q_b_ll_true))
        out[name] = {
            "position_error_m": float(np.linalg.norm(p - p_mission_true)),
            "attitude_error_deg": None if att is None else math.degrees(float(att)),
        }
    return out
