"""Rocker-bogie geometry and quasi-static settling.

Six wheels on the ground is checked independently of the solver: each settled wheel's rim
is rebuilt from the reported attitude and joint angles and sampled all round, and its
least vertical clearance over the terrain must be within 2 mm of zero (the acceptance
figure) on eq22 and on the rocky gusev heightmap.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from sim.errors import InputError
from sim.rover.geometry import MER_GEOMETRY, RoverGeometry, wheel_kinematics
from sim.rover.settle import Settled, settle
from sim.world.sites import make_terrain
from sim.world.terrain import BEDROCK, GUSEV_SOIL, Eq22Terrain, FlatTerrain, PlaneTerrain, Soil

FloatArray = NDArray[np.float64]
G = MER_GEOMETRY
ACCEPT_M = 2e-3  # acceptance: every wheel within 2 mm of the ground


class BumpTerrain(PlaneTerrain):
    """Level ground with a smooth bump ``height`` tall (sigma 10 cm) at ``(x0, y0)``; NaN
    heights beyond ``x > nan_beyond_m``."""

    def __init__(self, x0: float, y0: float, height: float, nan_beyond_m: float = 1e9) -> None:
        super().__init__(0.0, 0.0)
        self.x0, self.y0, self.h, self.nan_beyond = x0, y0, height, nan_beyond_m

    def height_m(self, x_m: ArrayLike, y_m: ArrayLike) -> FloatArray:
        x, y = np.broadcast_arrays(np.asarray(x_m, float), np.asarray(y_m, float))
        h = self.h * np.exp(-((x - self.x0) ** 2 + (y - self.y0) ** 2) / (2 * 0.1**2))
        out: FloatArray = np.where(x > self.nan_beyond, np.nan, h)
        return out

    def gradient(self, x_m: ArrayLike, y_m: ArrayLike) -> tuple[FloatArray, FloatArray]:
        x, y = np.broadcast_arrays(np.asarray(x_m, float), np.asarray(y_m, float))
        h = self.height_m(x, y)
        return -h * (x - self.x0) / 0.1**2, -h * (y - self.y0) / 0.1**2


def rim_clearance(
    terrain: object, s: Settled, steer: ArrayLike | None = None, sinkage_m: float = 0.0
) -> FloatArray:
    """Least vertical clearance (m) of each wheel's whole rim over the terrain, (N, 6).

    Independent of the solver: the rims are rebuilt with scipy's rotation from ``q_s_b``
    and the forward kinematics, and sampled every 0.5° all round.
    """
    R = Rotation.from_quat(s.q_s_b).as_matrix()
    kin = wheel_kinematics(G, s.rocker_rad, s.bogie_rad, steer)
    centre = s.p_s[:, None, :] + np.einsum("nij,nkj->nki", R, kin.centre_b)
    axle = np.einsum("nij,nkj->nki", R, kin.axle_b)
    u1 = np.cross(axle, [1.0, 0.0, 0.0])
    u1 /= np.linalg.norm(u1, axis=-1, keepdims=True)
    u2 = np.cross(axle, u1)
    r = G.wheel_radius_m - sinkage_m
    out = np.full(centre.shape[:2], np.inf)
    for t in np.array_split(np.linspace(0.0, 2.0 * np.pi, 720, endpoint=False), 8):
        c, sn = np.cos(t)[:, None], np.sin(t)[:, None]
        p = centre[:, :, None, :] + r * (c * u1[:, :, None, :] + sn * u2[:, :, None, :])
        f = -p[..., 2] - terrain.height_m(p[..., 0], p[..., 1])  # type: ignore[attr-defined]
        out = np.minimum(out, f.min(axis=-1))
    return out


# ---- geometry -----------------------------------------------------------------------


def test_zero_angles_put_the_wheels_at_the_documented_places() -> None:
    k = wheel_kinematics(G, 0.0, [0.0, 0.0])
    xs = [G.x_front_m, G.x_middle_m, G.x_rear_m]
    want = np.array(
        [[x, -G.track_m / 2, G.wheel_centre_z_m] for x in xs]
        + [[x, G.track_m / 2, G.wheel_centre_z_m] for x in xs]
    )
    np.testing.assert_allclose(k.centre_b, want, atol=1e-15)
    np.testing.assert_allclose(k.axle_b, np.tile([0.0, 1.0, 0.0], (6, 1)), atol=1e-15)
    assert G.body_height_m == pytest.approx(0.30)


def test_links_are_rigid_and_the_differential_mirrors_the_rockers() -> None:
    rng = np.random.default_rng(1)
    pivot = np.array([G.rocker_pivot_x_m, G.rocker_pivot_z_m])
    bogie0 = np.array([G.bogie_pivot_x_m, G.bogie_pivot_z_m]) - pivot
    k0 = wheel_kinematics(G, 0.0, [0.0, 0.0])

    def xz(k: object, i: int) -> FloatArray:
        out: FloatArray = k.centre_b[i, [0, 2]]  # type: ignore[attr-defined]
        return out

    for _ in range(20):
        rocker, bogie = rng.uniform(-0.5, 0.5), rng.uniform(-0.8, 0.8, 2)
        k = wheel_kinematics(G, rocker, bogie)
        for side, rho in ((0, rocker), (1, -rocker)):  # the right rocker mirrors the left
            c, s = math.cos(rho), math.sin(rho)
            b = pivot + np.array([c * bogie0[0] + s * bogie0[1], -s * bogie0[0] + c * bogie0[1]])
            front, middle, rear = 3 * side, 3 * side + 1, 3 * side + 2
            for i, centre, ref in ((front, pivot, pivot), (middle, b, None), (rear, b, None)):
                d = np.linalg.norm(xz(k, i) - centre)
                d0 = np.linalg.norm(xz(k0, i) - (pivot if ref is not None else pivot + bogie0))
                assert d == pytest.approx(d0, abs=1e-12)
            assert np.linalg.norm(xz(k, middle) - xz(k, rear)) == pytest.approx(
                G.x_middle_m - G.x_rear_m, abs=1e-12
            )
    up = wheel_kinematics(G, 0.1, [0.0, 0.0]).centre_b
    down = wheel_kinematics(G, -0.1, [0.0, 0.0]).centre_b
    assert up[0, 2] < k0.centre_b[0, 2]  # left front rises (z is down)
    # The differential: the right side turns by the negative angle, mirrored in y.
    np.testing.assert_allclose(up[3:], down[:3] * [1.0, -1.0, 1.0], atol=1e-15)


def test_kinematic_derivatives_match_finite_differences() -> None:
    q = np.array([0.12, -0.3, 0.25])
    steer = np.array([0.2, -0.4, 0.3, 0.1])
    k = wheel_kinematics(G, q[0], q[1:], steer)
    h = 1e-6
    for j in range(3):
        dq = np.zeros(3)
        dq[j] = h
        kp = wheel_kinematics(G, q[0] + dq[0], q[1:] + dq[1:], steer)
        km = wheel_kinematics(G, q[0] - dq[0], q[1:] - dq[1:], steer)
        np.testing.assert_allclose(
            (kp.centre_b - km.centre_b) / (2 * h), k.dcentre_dq[..., j], atol=1e-9
        )
        np.testing.assert_allclose((kp.axle_b - km.axle_b) / (2 * h), k.daxle_dq[..., j], atol=1e-9)


def test_steering_turns_the_corner_axles_about_body_z() -> None:
    k = wheel_kinematics(G, 0.0, [0.0, 0.0], [np.pi / 2, 0.0, -np.pi / 6, 0.0])
    np.testing.assert_allclose(k.axle_b[0], [-1.0, 0.0, 0.0], atol=1e-15)  # LF rolls right
    np.testing.assert_allclose(k.axle_b[3], [0.5, math.sqrt(3) / 2, 0.0], atol=1e-15)
    np.testing.assert_allclose(k.axle_b[1], [0.0, 1.0, 0.0], atol=1e-15)  # middles unsteered


# ---- settling: exact cases ----------------------------------------------------------


@pytest.mark.parametrize("soil", [BEDROCK, GUSEV_SOIL])
def test_flat_ground_gives_the_geometric_body_height(soil: Soil) -> None:
    yaw = np.linspace(-3.0, 3.0, 7)
    s = settle(FlatTerrain(soil), np.linspace(-5, 5, 7), np.zeros(7), yaw)
    height = G.wheel_centre_z_m + G.wheel_radius_m - soil.sinkage_m
    assert np.all(s.ok)
    np.testing.assert_allclose(s.p_s[:, 2], -height, atol=1e-12)  # z Down
    for a in (s.roll_rad, s.pitch_rad, s.rocker_rad, s.bogie_rad):
        np.testing.assert_allclose(a, 0.0, atol=1e-12)
    np.testing.assert_allclose(s.contact_s[..., 2], 0.0, atol=1e-12)


def test_attitude_follows_the_heading_convention() -> None:
    s = settle(FlatTerrain(), [0.0, 0.0], [0.0, 0.0], [0.0, np.pi / 2])
    rot = Rotation.from_quat(s.q_s_b)
    np.testing.assert_allclose(rot[0].apply([1.0, 0.0, 0.0]), [1.0, 0.0, 0.0], atol=1e-12)
    # Heading 90° is facing East: body x (forward) is Site +y, body y (right) Site -x.
    np.testing.assert_allclose(rot[1].apply([1.0, 0.0, 0.0]), [0.0, 1.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(rot[1].apply([0.0, 1.0, 0.0]), [-1.0, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(rot[1].apply([0.0, 0.0, 1.0]), [0.0, 0.0, 1.0], atol=1e-12)


@pytest.mark.parametrize("start_off", [False, True])
def test_on_a_plane_the_body_lies_parallel_to_it(start_off: bool) -> None:
    a, b = math.tan(math.radians(20.0)), -math.tan(math.radians(8.0))
    plane = PlaneTerrain(a, b, 0.3)
    yaw = np.deg2rad([0.0, 37.0, 90.0, 180.0, -120.0])
    x, y = np.array([0.0, 3.0, -2.0, 1.0, 4.0]), np.array([0.0, -1.0, 2.0, 5.0, 0.5])
    # Either the default start (a plane fitted under the wheels, exact here) or one 5 cm
    # and 0.1 rad off in every unknown, which Newton has to walk back.
    guess = None
    if start_off:
        z = -(plane.height_m(x, y) + G.body_height_m * math.sqrt(1 + a * a + b * b))
        guess = np.column_stack([z + 0.05, np.full((5, 5), [0.1, -0.1, 0.1, -0.1, 0.1])])
    s = settle(plane, x, y, yaw, guess=guess)
    assert np.all(s.ok)
    along = a * np.cos(yaw) + b * np.sin(yaw)  # slopes along and across the heading
    across = -a * np.sin(yaw) + b * np.cos(yaw)
    norm = np.sqrt(1.0 + a * a + b * b)
    tol = 2e-4 if start_off else 1e-9  # from afar: within the 0.1 mm gap tolerance
    np.testing.assert_allclose(s.pitch_rad, np.arctan(along), atol=tol)
    np.testing.assert_allclose(s.roll_rad, -np.arcsin(across / norm), atol=tol)
    for joint in (s.rocker_rad, s.bogie_rad):
        np.testing.assert_allclose(joint, 0.0, atol=tol)
    down = np.array([a, b, 1.0]) / norm  # the plane's downward normal, Site frame
    body_z = Rotation.from_quat(s.q_s_b).apply([0.0, 0.0, 1.0])
    np.testing.assert_allclose(body_z, np.tile(down, (5, 1)), atol=tol)
    # The body origin stands the flat-ground height off the plane, along its normal.
    elevation = -s.p_s[:, 2] - plane.height_m(x, y)
    np.testing.assert_allclose(elevation / norm, G.body_height_m, atol=tol)


def test_uphill_and_across_a_20_degree_slope() -> None:
    plane = PlaneTerrain(math.tan(math.radians(20.0)), 0.0)  # rises to the North
    s = settle(plane, [0.0, 0.0], [0.0, 0.0], [0.0, np.pi / 2])
    assert math.degrees(s.pitch_rad[0]) == pytest.approx(20.0, abs=1e-9)  # nose up
    assert s.roll_rad[0] == pytest.approx(0.0, abs=1e-12)
    # Facing East the ground rises to the left: right side down is positive roll.
    assert math.degrees(s.roll_rad[1]) == pytest.approx(20.0, abs=1e-9)
    assert s.pitch_rad[1] == pytest.approx(0.0, abs=1e-12)


# ---- settling: six wheels down on rough ground ---------------------------------------


def test_eq22_six_wheels_within_2_mm() -> None:
    rng = np.random.default_rng(22)
    n = 300
    x, y = rng.uniform(-1.5, 1.5, n), rng.uniform(-1.5, 1.5, n)
    yaw, steer = rng.uniform(-np.pi, np.pi, n), rng.uniform(-0.4, 0.4, (n, 4))
    terrain = Eq22Terrain()
    s = settle(terrain, x, y, yaw, steer_rad=steer)
    assert np.all(s.ok)
    assert np.max(np.abs(s.gap_m)) < 1e-4  # the solver's own tolerance
    clearance = rim_clearance(terrain, s, steer)
    assert np.max(np.abs(clearance)) < ACCEPT_M
    assert np.max(np.abs(clearance)) < 2e-4  # smooth ground: much better than accepted
    assert np.ptp(s.rocker_rad) > 0.02  # the suspension really worked


def test_gusev_six_wheels_within_2_mm() -> None:
    terrain = make_terrain("gusev", 1)
    rng = np.random.default_rng(5)
    n = 400
    x, y = rng.uniform(-25.0, 25.0, n), rng.uniform(-25.0, 25.0, n)
    s = settle(terrain, x, y, rng.uniform(-np.pi, np.pi, n))
    # ~1 pose in 10,000 jams a wheel against a steep rock face; none of these 400 may.
    assert np.all(s.ok)
    clearance = rim_clearance(terrain, s, sinkage_m=terrain.soil.sinkage_m)[s.ok]
    assert np.max(np.abs(clearance)) < ACCEPT_M
    # A straight path across rocks, settled as a path (warm-started between poses).
    d = np.arange(800) * 0.0375 / 8.0
    path = settle(
        terrain, 3.0 + 0.8 * d, -2.0 + 0.6 * d, np.full(800, math.atan2(0.6, 0.8)), along_path=True
    )
    assert np.all(path.ok)
    clearance = rim_clearance(terrain, path, sinkage_m=terrain.soil.sinkage_m)
    assert np.max(np.abs(clearance)) < ACCEPT_M


def test_path_mode_agrees_with_pose_by_pose() -> None:
    terrain = Eq22Terrain()
    d = np.arange(200) * 0.0047
    x, y, yaw = -0.5 + 0.8 * d, -0.4 + 0.6 * d, np.full(200, 0.64)
    a = settle(terrain, x, y, yaw)
    b = settle(terrain, x, y, yaw, along_path=True)
    assert np.all(a.ok) and np.all(b.ok)
    np.testing.assert_allclose(a.p_s, b.p_s, atol=2e-4)
    np.testing.assert_allclose(a.unknowns()[:, 1:], b.unknowns()[:, 1:], atol=1e-3)


def test_a_previous_solution_is_a_good_start() -> None:
    terrain = Eq22Terrain()
    rng = np.random.default_rng(4)
    x, y, yaw = rng.uniform(-1, 1, 50), rng.uniform(-1, 1, 50), rng.uniform(-3, 3, 50)
    first = settle(terrain, x, y, yaw)
    again = settle(terrain, x, y, yaw, guess=first)
    assert np.all(again.ok)
    np.testing.assert_allclose(again.unknowns(), first.unknowns(), atol=2e-4)
    assert again.iterations.sum() <= first.iterations.sum()


# ---- failures are flagged ------------------------------------------------------------


def test_impossible_poses_are_flagged_not_hidden() -> None:
    # A 60 cm bump under the left middle wheel needs the bogie past its stop; a 1 m one
    # cannot be straddled at all; NaN heights beyond x = 50 m.
    g = G
    tall = BumpTerrain(g.x_middle_m, -g.track_m / 2, 0.6, nan_beyond_m=50.0)
    s = settle(tall, [0.0, 10.0, 60.0], [0.0, 10.0, 0.0], [0.0, 0.0, 0.0])
    assert s.converged[0] and not s.within_limits[0] and not s.ok[0]
    assert abs(s.bogie_rad[0, 0]) > g.bogie_limit_rad
    assert s.ok[1]  # the same call settles a good pose next to it
    assert not s.converged[2] and not s.ok[2]  # the terrain answers NaN there
    assert np.all(np.isnan(s.q_s_b[2]))
    pillar = settle(BumpTerrain(g.x_middle_m, -g.track_m / 2, 1.0), 0.0, 0.0, 0.0)
    assert not pillar.converged[0] and not pillar.ok[0]


def test_a_bogie_turned_on_end_is_not_a_stance() -> None:
    # The six contact equations under the 1 m pillar have a root with the left bogie turned
    # 1.63 rad (past a quarter turn): its middle wheel high on one flank of the pillar, its
    # rear wheel on the other. Whether Newton from the plane fit reaches it within 60
    # iterations depended on the last bits of the BLAS kernel; started next to it, Newton
    # reaches it on any machine, and it must still not count as a converged pose.
    g = G
    pillar = BumpTerrain(g.x_middle_m, -g.track_m / 2, 1.0)
    near_root = [-0.4216, 0.1809, -0.1956, -0.1988, 1.6344, 0.0]
    s = settle(pillar, 0.0, 0.0, 0.0, guess=near_root)
    assert np.max(np.abs(s.gap_m)) < 1e-4  # a root of the contact equations ...
    assert abs(s.bogie_rad[0, 0]) > math.pi / 2  # ... with the bogie on end
    assert not s.converged[0] and not s.ok[0]
    # A joint short of a quarter turn is only past its stop: the 60 cm bump's 1.22 rad.
    tall = settle(BumpTerrain(g.x_middle_m, -g.track_m / 2, 0.6), 0.0, 0.0, 0.0)
    assert tall.converged[0] and not tall.within_limits[0]


def test_bad_input_names_the_parameter() -> None:
    flat = FlatTerrain()
    with pytest.raises(InputError, match="y_m"):
        settle(flat, [0.0, 1.0], [0.0], [0.0, 0.0])
    with pytest.raises(InputError, match="x_m"):
        settle(flat, [np.nan], [0.0], [0.0])
    with pytest.raises(InputError, match="sinkage_m"):
        settle(flat, 0.0, 0.0, 0.0, sinkage_m=0.2)
    with pytest.raises(InputError, match="steer_rad"):
        settle(flat, 0.0, 0.0, 0.0, steer_rad=[0.0, 0.0])
    with pytest.raises(InputError, match="guess"):
        settle(flat, [0.0, 1.0], [0.0, 0.0], [0.0, 0.0], guess=np.zeros((3, 6)))
    with pytest.raises(InputError, match="wheel_radius_m"):
        RoverGeometry(wheel_radius_m=-0.13)
    with pytest.raises(InputError, match="x_middle_m"):
        RoverGeometry(x_middle_m=0.9)
