"""The viser 3D view: the one quaternion conversion against viser's own rotation code, the
wheels on the suspension's forward kinematics, the terrain patch against the terrain, the
scene following a real rover's frames, the same-origin proxy of viser's page and WebSocket;
and, with viewers speaking viser's wire protocol through the console's relay
(``tests.viser_wire``), each viewer scrubbing and following on its own, crafted GUI
messages that change no one else's view and break no callback, and what the relay passes."""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import msgspec
import numpy as np
import pytest
import trimesh
import uvicorn
import viser
import viser.transforms as vtf
from fastapi.testclient import TestClient
from scipy.spatial.transform import Rotation

from bench.vo.ground_map import to_u8
from estimation.vo.stereo_rig import NAVCAM
from sequences import commands as cmd
from server.app import ServerConfig, create_app, data_dir_url
from server.runtime import ROVERS, RoverRuntime
from server.scene3d.model import (
    TRACK_CHUNK,
    TRACK_RGB,
    RoverPose,
    Track,
    status_text,
    wheel_poses_b,
    wxyz_from_q,
)
from server.scene3d.proxy import MAX_VIEWER_MESSAGE_BYTES, refusal
from server.scene3d.scene import GROUND_NODE, HISTORY_EVERY_S, TRUTH_NODE, RoverScene
from server.scene3d.terrain_mesh import TERRAIN_HALF_M, TERRAIN_STEP_M, terrain_patch
from server.sinks import FrameBatch
from server.storage import Store
from sim.loop.downlink import downlink_fields
from sim.loop.session import RoverSession
from sim.rover.geometry import MER_GEOMETRY, wheel_kinematics
from sim.scoring.truth import merged, truth_fields
from sim.world.sites import make_terrain
from tests.server.test_server_restart import _free_port
from tests.viser_wire import WireViewer


def _wait(predicate: Any, timeout_s: float = 30.0) -> Any:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(0.05)
    raise AssertionError("timed out")


def test_a_yaw_of_90_deg_about_down_is_w_first_for_viser() -> None:
    q = Rotation.from_euler("z", 90.0, degrees=True).as_quat()  # [0, 0, s, c]
    assert wxyz_from_q(q) == pytest.approx((math.sqrt(0.5), 0.0, 0.0, math.sqrt(0.5)))


def test_wxyz_rotates_vectors_as_viser_does() -> None:
    rng = np.random.default_rng(4)
    for q in Rotation.random(20, random_state=rng).as_quat():
        v = rng.normal(size=3)
        viser_rotated = vtf.SO3(np.asarray(wxyz_from_q(q))).apply(v)
        np.testing.assert_allclose(viser_rotated, Rotation.from_quat(q).apply(v), atol=1e-12)


def test_each_wheel_sits_on_the_kinematics_with_its_axle_along_local_z() -> None:
    pose = RoverPose(
        p_w=np.zeros(3),
        q_w_b=np.array([0.0, 0.0, 0.0, 1.0]),
        rocker_rad=0.2,
        bogie_rad=np.array([-0.3, 0.1]),
        steer_rad=np.radians([20.0, -15.0, 10.0, -5.0]),
    )
    kin = wheel_kinematics(MER_GEOMETRY, pose.rocker_rad, pose.bogie_rad, pose.steer_rad)
    for i, (centre_b, q_b_wheel) in enumerate(wheel_poses_b(pose)):
        np.testing.assert_allclose(centre_b, kin.centre_b[i], atol=1e-12)
        local_z_b = Rotation.from_quat(q_b_wheel).apply([0.0, 0.0, 1.0])
        np.testing.assert_allclose(local_z_b, kin.axle_b[i], atol=1e-12)


def test_the_terrain_patch_follows_the_ground_with_faces_up() -> None:
    terrain = make_terrain("gusev", 1)
    origin_world = np.array([3.0, -2.0, -0.3])
    mesh = terrain_patch(terrain, np.array([1.0, 2.0]), origin_world)
    vertices, faces = np.asarray(mesh.vertices, float), np.asarray(mesh.faces)
    n = round(2 * TERRAIN_HALF_M / TERRAIN_STEP_M) + 1
    assert vertices.shape == (n * n, 3)
    expected_z = -terrain.height_m(vertices[:, 0] + 3.0, vertices[:, 1] - 2.0) + 0.3
    np.testing.assert_allclose(vertices[:, 2], expected_z, atol=1e-5)  # float32 vertices
    assert len(faces) == 2 * (n - 1) ** 2
    assert len(np.unique(np.sort(faces, axis=1), axis=0)) == len(faces)  # each face once
    a, b, c = (vertices[faces[:, k]] for k in range(3))
    normals = np.cross(b - a, c - a)
    assert np.all(normals[:, 2] < 0.0)  # z is Down: every face looks up
    # a colour per vertex, brighter where the terrain's albedo is
    visual = mesh.visual
    assert isinstance(visual, trimesh.visual.ColorVisuals)
    rgb = np.asarray(visual.vertex_colors)[:, :3].astype(float).sum(axis=1)
    quarter = 0.25 * TERRAIN_STEP_M
    albedo = np.mean(
        [terrain.albedo(vertices[:, 0] + 3.0 + dn, vertices[:, 1] - 2.0 + de)
         for dn in (-quarter, quarter) for de in (-quarter, quarter)], axis=0,
    )  # fmt: skip
    assert np.corrcoef(rgb, albedo)[0, 1] > 0.5


def test_a_track_grows_only_with_motion_and_resends_only_its_last_chunk() -> None:
    track = Track()
    assert track.add([0.0, 0.0, 0.0])
    assert not track.add([0.01, 0.0, 0.0])
    assert track.add([0.2, 0.0, 0.0])
    assert {c: s.shape for c, s in track.take_dirty().items()} == {0: (1, 2, 3)}
    assert track.take_dirty() == {}
    for i in range(2, TRACK_CHUNK + 3):
        track.add([0.1 * i, 0.0, 0.0])
    chunks = track.take_dirty()
    assert sorted(chunks) == [0, 1]
    assert chunks[0].shape == (TRACK_CHUNK, 2, 3)
    np.testing.assert_allclose(chunks[1][0, 0], chunks[0][-1, 1])  # the chunks join
    track.add([1e3, 0.0, 0.0])
    assert sorted(track.take_dirty()) == [1]


@pytest.fixture(scope="module")
def scene(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[RoverScene, RoverRuntime]]:
    store = Store(data_dir_url(tmp_path_factory.mktemp("scene")))
    runtime = RoverRuntime(ROVERS["spirit"])
    rover_scene = RoverScene(runtime, store)
    rover_scene.start()
    try:
        yield rover_scene, runtime
    finally:
        rover_scene.stop()
        store.close()


def test_a_rover_without_frames_has_its_ground_drawn_at_start(
    scene: tuple[RoverScene, RoverRuntime],
) -> None:
    """The terrain is cut when the view starts, around where the rover stands, so the
    first live frame's draw (during a command's play-out) does not cut it."""
    rover_scene, runtime = scene
    assert rover_scene.frames_drawn == 0 and rover_scene._latest is None
    start_w = runtime.session.sim.drive_state.p_s - runtime.session.mission_origin_world
    assert rover_scene._terrain_centre is not None
    np.testing.assert_allclose(rover_scene._terrain_centre, start_w[:2], atol=TERRAIN_STEP_M)
    assert rover_scene.server is not None
    nodes = rover_scene.server.scene._handle_from_node_name
    assert GROUND_NODE in nodes and nodes[GROUND_NODE].visible  # the ground's map, shown
    assert TRUTH_NODE in nodes and not nodes[TRUTH_NODE].visible  # the truth beside it


def test_the_ground_map_is_drawn_again_when_a_pair_refines_it(
    scene: tuple[RoverScene, RoverRuntime],
) -> None:
    """A pair added to the rover's ground map (a new version) is drawn at the next draw
    without the rover moving; the truth view's toggle swaps the two terrains."""
    rover_scene, runtime = scene
    assert rover_scene.server is not None
    nodes = rover_scene.server.scene._handle_from_node_name
    before = nodes[GROUND_NODE]
    rig = NAVCAM.at_resolution(256)
    pair = runtime.session.sim.navcam_pair(0.0, math.radians(-35.0), rig=rig, noise=False)
    version = rover_scene.ground.version
    rover_scene.ground.add_pair(
        to_u8(pair.left), to_u8(pair.right), 256, 0.0, math.radians(-35.0),
        np.zeros(3), runtime.session.q_b_ll_true(),
    )  # fmt: skip
    assert rover_scene.ground.version == version + 1
    centre = rover_scene._terrain_centre
    assert centre is not None
    rover_scene._recut_terrain(np.array([centre[0], centre[1], 0.0]))
    assert rover_scene._ground_version == version + 1
    assert nodes[GROUND_NODE] is not before  # a new mesh under the same name
    assert rover_scene._terrain_centre is not None
    np.testing.assert_allclose(rover_scene._terrain_centre, centre)  # not re-cut elsewhere
    rover_scene.show_truth_terrain(True)
    assert nodes[TRUTH_NODE].visible and not nodes[GROUND_NODE].visible
    rover_scene.show_truth_terrain(False)
    assert nodes[GROUND_NODE].visible and not nodes[TRUTH_NODE].visible


def test_the_scene_follows_the_frames(
    scene: tuple[RoverScene, RoverRuntime],
) -> None:
    rover_scene, runtime = scene
    session = runtime.session
    session.execute(cmd.DriveStraight(distance_m=2.0))
    frames = merged_frames(session)
    assert len(frames) > 3
    rover_scene.publish("spirit", batch_of(frames))
    last = frames[-1]
    _wait(lambda: np.allclose(rover_scene.model.root.position, last["p_mission_true"]))
    np.testing.assert_allclose(rover_scene.ghost.root.position, last["p_mission_est"])
    q_w_b_true = Rotation.from_quat(last["q_b_ll_true"]).inv().as_quat()
    assert abs(np.dot(rover_scene.model.root.wxyz, wxyz_from_q(q_w_b_true))) == pytest.approx(1)
    moved = np.linalg.norm(np.subtract(last["p_mission_true"], frames[0]["p_mission_true"]))
    assert moved > 1.5
    # The slider reaches back to the sol's first frame (each viewer scrubs on its own:
    # test_a_viewer_who_scrubs_leaves_the_others_following).
    first = rover_scene.frame_at(frames[0]["lmst_h"])
    assert first is not None and first["t_s"] == frames[0]["t_s"]


def test_across_light_time_the_truth_is_live_and_the_rover_known_layer_waits(
    tmp_path_factory: pytest.TempPathFactory,
) -> None:
    """Truth records alone draw the true traverse at once; downlink records alone (when a
    pass brings them) draw the rover where it believes it is, newest last, and an older
    one a pass fills in is not drawn over a newer one."""
    store = Store(data_dir_url(tmp_path_factory.mktemp("scene_apart")))
    runtime = RoverRuntime(ROVERS["spirit"])
    rover_scene = RoverScene(runtime, store)
    runtime.session.execute(cmd.DriveStraight(distance_m=2.0))
    whole = batch_of(merged_frames(runtime.session))
    rover_scene.publish("spirit", FrameBatch([], whole.truth))
    assert rover_scene._latest is None and len(rover_scene._tracks["true"].points) > 3
    assert rover_scene._tracks["est"].points == []
    half = len(whole.downlink) // 2
    rover_scene.publish("spirit", FrameBatch(whole.downlink[half:], [], 9e9))
    latest = rover_scene._latest
    assert latest is not None and latest["t_s"] == whole.downlink[-1]["t_s"]
    assert latest["truth_t_s"] == whole.truth[-1]["t_s"] and latest["received_t_s"] == 9e9
    rover_scene.publish("spirit", FrameBatch(whole.downlink[:half], [], 9.5e9))  # filled in
    assert rover_scene._latest is not None and rover_scene._latest["t_s"] == latest["t_s"]
    text = status_text(rover_scene._latest, live=True, now_t_s=9e9 + 600.0)
    assert "data received 10 min ago" in text and "truth live" in text
    store.close()


def test_each_estimator_beside_sapp_is_a_traverse_of_its_own_colour(
    tmp_path_factory: pytest.TempPathFactory,
) -> None:
    store = Store(data_dir_url(tmp_path_factory.mktemp("scene_sides")))
    runtime = RoverRuntime(ROVERS["spirit"], estimators=("sapp", "kinematic_ekf", "radio_ekf"))
    rover_scene = RoverScene(runtime, store)
    rover_scene.start()
    try:
        runtime.session.execute(cmd.DriveStraight(distance_m=2.0))
        frames = merged_frames(runtime.session)
        rover_scene.publish("spirit", batch_of(frames))
        assert rover_scene.server is not None
        handles = rover_scene.server.scene._handle_from_node_name
        for name in ("kinematic_ekf", "radio_ekf"):
            node = _wait(lambda name=name: handles.get(f"/traverse_{name}/0"))
            assert tuple(np.asarray(node.colors).reshape(-1, 3)[0]) == TRACK_RGB[name]
            end = np.asarray(node.points)[-1, 1]  # the traverse's last vertex
            np.testing.assert_allclose(end, frames[-1]["estimators"][name]["p_mission"], atol=0.1)
    finally:
        rover_scene.stop()
        store.close()


def test_viser_is_served_and_relayed_on_the_console_origin(
    tmp_path_factory: pytest.TempPathFactory,
) -> None:
    url = data_dir_url(tmp_path_factory.mktemp("proxy"))
    config = ServerConfig(database_url=url, operator_token="proxy-token", viewer_3d=True)
    with TestClient(create_app(config)) as client:
        page = client.get("/viser/spirit/")
        assert page.status_code == 200 and "<html" in page.text.lower()
        moved = client.get("/viser/spirit", follow_redirects=False)
        assert moved.status_code == 307 and moved.headers["location"] == "/viser/spirit/"
        assert client.get("/viser/curiosity/").status_code == 404
        assert client.get("/api/rovers/spirit/scene").json()["url"] == "/viser/spirit/"
        protocol = f"viser-v{viser.__version__}"
        with client.websocket_connect("/viser/spirit", subprotocols=[protocol]) as ws:
            assert ws.accepted_subprotocol == protocol
            first = ws.receive_bytes()  # viser's scene, msgpack
            assert len(first) > 0


def test_without_the_3d_view_its_routes_say_so(tmp_path_factory: pytest.TempPathFactory) -> None:
    url = data_dir_url(tmp_path_factory.mktemp("no3d"))
    with TestClient(create_app(ServerConfig(database_url=url))) as client:
        answer = client.get("/viser/spirit/")
        assert answer.status_code == 404 and "3D view is off" in answer.json()["detail"]


# ---- every viewer its own view (issue 13, defect 9) ------------------------------------------

SLIDER = "Sol time (LMST h)"
FOLLOW = "Follow live"


def merged_frames(session: RoverSession) -> list[dict[str, Any]]:
    """The session's frames, each downlink with its truth (``sim.scoring.truth.merged``)."""
    return [
        merged(d.as_dict(), t.as_dict())
        for d, t in zip(session.downlinks, session.truths, strict=True)
    ]


def batch_of(frames: list[dict[str, Any]]) -> FrameBatch:
    """``merged_frames`` as the runtime hands them to a sink: the two records apart (the
    events and side estimates with the downlink; a drive has no scored events)."""
    downlink_keys = set(downlink_fields())
    truth_keys = set(truth_fields()) - {"events", "estimators"}
    return FrameBatch(
        [{k: v for k, v in f.items() if k in downlink_keys} for f in frames],
        [{**{k: f[k] for k in truth_keys}, "events": [], "estimators": {}} for f in frames],
    )


@pytest.fixture(scope="module")
def drive() -> list[dict[str, Any]]:
    """The frames of a short drive, from a runtime of their own (one a simulated second)."""
    runtime = RoverRuntime(ROVERS["spirit"])
    runtime.session.execute(cmd.DriveStraight(distance_m=3.0))
    frames = merged_frames(runtime.session)
    assert frames[-1]["t_s"] - frames[0]["t_s"] > 4 * HISTORY_EVERY_S
    return frames


@dataclass
class Console:
    """The console's app served by uvicorn in a thread (clocks stopped: the test feeds the
    scene the frames it wants), and its WebSocket URL of Spirit's 3D view."""

    app: Any
    url: str

    @property
    def scene(self) -> RoverScene:
        scene: RoverScene = self.app.state.server.scenes["spirit"]
        return scene


@pytest.fixture
def console(tmp_path: Any) -> Iterator[Console]:
    config = ServerConfig(
        database_url=data_dir_url(tmp_path), operator_token="t", viewer_3d=True, start_clocks=False
    )
    app = create_app(config)
    port = _free_port()
    server = uvicorn.Server(uvicorn.Config(app, port=port, log_level="warning", lifespan="on"))
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    try:
        _wait(lambda: server.started)
        yield Console(app, f"ws://127.0.0.1:{port}/viser/spirit")
    finally:
        server.should_exit = True
        thread.join(timeout=30)


def _viewers(console: Console, count: int, live: bool = True) -> list[WireViewer]:
    """``count`` viewers, each with its controls (and the live status once there are
    frames)."""
    viewers = [WireViewer(console.url) for _ in range(count)]
    for v in viewers:
        _wait(lambda v=v: v.uuid(SLIDER) and (not live or "(live)" in v.status()))
    return viewers


def _at(viewer: WireViewer, name: str, p: Any) -> bool:
    """Whether ``viewer`` sees node ``name`` at ``p``."""
    position = viewer.position(name)
    return position is not None and bool(np.allclose(position, p))


def test_a_viewer_who_scrubs_leaves_the_others_following(
    console: Console, drive: list[dict[str, Any]]
) -> None:
    half = len(drive) // 2
    console.scene.publish("spirit", batch_of(drive[:half]))
    a, b = _viewers(console, 2)
    try:
        _wait(
            lambda: np.allclose(
                b.position("/rover") or [9e9] * 3, drive[half - 1]["p_mission_true"]
            )
        )
        a.set_value(SLIDER, drive[0]["lmst_h"])
        _wait(lambda: "(replay)" in a.status())
        assert a.value(FOLLOW) is False
        # A sees its own rover where it was at the start; B has no such node.
        _wait(lambda: _at(a, "/rover", drive[0]["p_mission_true"]))
        assert b.owners("/rover") == {""}

        console.scene.publish("spirit", batch_of(drive[half:]))
        last = drive[-1]
        _wait(lambda: _at(b, "/rover", last["p_mission_true"]))
        _wait(lambda: status_text(last, True) in b.status())
        assert b.value(FOLLOW) is True
        assert b.value(SLIDER) == pytest.approx(last["lmst_h"], abs=0.01)
        # A is left where it was: its rover, its slider, its status.
        np.testing.assert_allclose(a.position("/rover"), drive[0]["p_mission_true"])
        assert status_text(drive[0], False) in a.status()
        assert a.value(SLIDER) == pytest.approx(drive[0]["lmst_h"])

        a.set_value(FOLLOW, True)  # back to live: A's own rover goes, the shared one shows
        _wait(lambda: status_text(last, True) in a.status())
        _wait(lambda: a.owners("/rover") == {""})
        np.testing.assert_allclose(a.position("/rover"), last["p_mission_true"])
    finally:
        a.close()
        b.close()


def test_crafted_gui_messages_change_no_other_viewer_and_break_no_callback(
    console: Console, drive: list[dict[str, Any]]
) -> None:
    console.scene.publish("spirit", batch_of(drive))
    _wait(lambda: console.scene.frames_drawn > 0)
    last = drive[-1]
    a, b = _viewers(console, 2)
    try:
        b_state = {label: b.value(label) for label in (FOLLOW, SLIDER)}
        b_status = b.status()
        slider, follow = a.uuid(SLIDER), a.uuid(FOLLOW)
        crafted: list[dict[str, Any]] = [
            # another viewer's elements
            {"type": "GuiUpdateMessage", "uuid": b.uuid(SLIDER), "updates": {"value": 0.0}},
            {"type": "GuiUpdateMessage", "uuid": b.uuid(FOLLOW), "updates": {"value": False}},
            # the callbacks, the sync and the life of one's own elements
            {"type": "GuiUpdateMessage", "uuid": slider, "updates": {"update_cb": []}},
            {"type": "GuiUpdateMessage", "uuid": follow, "updates": {"update_cb": 0}},
            {"type": "GuiUpdateMessage", "uuid": slider, "updates": {"sync_cb": 1}},
            {"type": "GuiUpdateMessage", "uuid": slider, "updates": {"removed": True}},
            {"type": "GuiUpdateMessage", "uuid": slider, "updates": {"value": 1.0, "gui_api": 0}},
            # values of the wrong type or out of range
            {"type": "GuiUpdateMessage", "uuid": slider, "updates": {"value": math.nan}},
            {"type": "GuiUpdateMessage", "uuid": slider, "updates": {"value": -math.inf}},
            {"type": "GuiUpdateMessage", "uuid": slider, "updates": {"value": 1e300}},
            {"type": "GuiUpdateMessage", "uuid": slider, "updates": {"value": "nan"}},
            {"type": "GuiUpdateMessage", "uuid": slider, "updates": {"value": [1, 2]}},
            {"type": "GuiUpdateMessage", "uuid": follow, "updates": {"value": "no"}},
            {"type": "GuiUpdateMessage", "uuid": slider, "updates": "value"},
            {"type": "GuiUpdateMessage", "uuid": 5},
            # what a viewer has no business asking for
            {"type": "ShareUrlRequest"},
            {"type": "GuiFormDirtyMessage", "uuid": follow, "dirty": True},
            {"type": "NoSuchMessage"},
        ]
        for message in crafted:
            a.send(message)
        a.send_raw(b"\x00not msgpack")
        a.send_raw("text, not bytes")
        # The server still answers A's legitimate update ...
        a.set_value(SLIDER, drive[0]["lmst_h"])
        _wait(lambda: status_text(drive[0], False) in a.status())
        _wait(lambda: _at(a, "/rover", drive[0]["p_mission_true"]))
        a.set_value(FOLLOW, True)
        _wait(lambda: status_text(last, True) in a.status())
        assert a.connected
        # ... and B saw none of it.
        assert {label: b.value(label) for label in (FOLLOW, SLIDER)} == b_state
        assert b.status() == b_status and status_text(last, True) in b_status
        assert b.owners("/rover") == {""}
        np.testing.assert_allclose(b.position("/rover"), last["p_mission_true"])
    finally:
        a.close()
        b.close()


def test_a_viewer_s_state_goes_with_its_connection(console: Console) -> None:
    a, b = _viewers(console, 2, live=False)
    try:
        _wait(lambda: len(console.scene.viewers) == 2)
        a.close()
        _wait(lambda: len(console.scene.viewers) == 1)
        (left,) = console.scene.viewers.values()
        assert console.scene.server is not None
        assert list(console.scene.server.get_clients()) == [left.client.client_id]
    finally:
        b.close()
    _wait(lambda: not console.scene.viewers)


CAMERA = {
    "type": "ViewerCameraMessage", "wxyz": [1.0, 0.0, 0.0, 0.0], "position": [0.0, 0.0, 0.0],
    "fov": 1.0, "near": 0.01, "far": 100.0, "image_height": 10, "image_width": 10,
    "look_at": [1.0, 0.0, 0.0], "up_direction": [0.0, 0.0, -1.0],
}  # fmt: skip


@pytest.mark.parametrize(
    "message",
    [
        CAMERA,
        {"type": "GuiUpdateMessage", "uuid": "u", "updates": {"value": 1.5}},
        {"type": "GuiUpdateMessage", "uuid": "u", "updates": {"value": True}},
        {"type": "GuiUpdateMessage", "uuid": "u", "updates": {"value": math.nan}},  # the callback's
    ],
)
def test_the_relay_passes_what_a_viewer_sends(message: dict[str, Any]) -> None:
    assert refusal(msgspec.msgpack.encode(message)) is None


@pytest.mark.parametrize(
    "message,why",
    [
        ({"type": "GuiUpdateMessage", "uuid": "u", "updates": {"update_cb": []}}, "not update_cb"),
        ({"type": "GuiUpdateMessage", "uuid": "u", "updates": {"value": 1, "removed": 1}}, "ed"),
        ({"type": "GuiUpdateMessage", "uuid": "u", "updates": {}}, "value only"),
        ({"type": "GuiUpdateMessage", "uuid": "u", "updates": [1]}, "value only"),
        ({"type": "GuiUpdateMessage", "uuid": "u", "updates": {"value": "1"}}, "number or a flag"),
        ({"type": "GuiUpdateMessage", "uuid": "u", "updates": {"value": [1]}}, "number or a flag"),
        ({"type": "GuiUpdateMessage", "uuid": 1, "updates": {"value": 1}}, "other than"),
        ({"type": "GuiUpdateMessage", "uuid": "u", "updates": {"value": 1}, "x": 1}, "other than"),
        ({"type": "ShareUrlRequest"}, "not a message this view accepts"),
        ({"type": "GuiFormDirtyMessage", "uuid": "u", "dirty": True}, "not a message"),
        ({"type": "FileTransferStartUpload"}, "not a message"),
        ({"no": "type"}, "not a message"),
        ({**CAMERA, "camera_cb": []}, "camera_cb"),
        ([1, 2], "not a message"),
    ],
)
def test_the_relay_drops_what_no_viewer_of_this_view_sends(message: Any, why: str) -> None:
    reason = refusal(msgspec.msgpack.encode(message))
    assert reason is not None and why in reason


def test_the_relay_drops_frames_that_are_not_viser_messages() -> None:
    assert refusal("text") == "a text frame (viser speaks binary msgpack)"
    assert refusal(b"\xc1") == "not msgpack"
    assert refusal(b"\x00" * (MAX_VIEWER_MESSAGE_BYTES + 1)) is not None
