"""The viser 3D view of one rover: what the operator sees of the rover in its terrain.

One ``RoverScene`` per rover runs its own ``viser.ViserServer`` on a loopback port; the
FastAPI app proxies it under ``/viser/{rover}/`` (``server.scene3d.proxy``) so the console and
the 3D view share one origin. The scene shows

- the terrain as terrain looks (``server.scene3d.terrain_mesh``: albedo and hill shading per
  vertex), re-cut when the rover nears the patch's edge: the ground's own map
  (``server.terrain``: the orbital DEM refined by the stereo pairs that came down), drawn
  again when it changes, each viewer told how many pairs it holds; in the truth view the
  simulator's terrain too, in its place when a viewer ticks "Truth terrain" (for everyone);
- the rover model (``server.scene3d.model``: body, solar deck, mast and camera head, HGA,
  six wheels placed on their rocker and bogie angles and steered) at the true pose, and a
  translucent ghost at SAPP's estimated pose;
- the true and estimated traverses, the Site frames as labelled axes;
- the sun and Earth directions from the mast head, the HGA boresight from the dish;
- a time slider over the current sol: dragging it scrubs back through the stored frames;
  "Follow live" returns to the telemetry as it plays out.

Each viewer scrubs and follows on its own (``Viewer``): its controls and status are its
own (viser's per-client GUI), and while it replays it sees its own rover, ghost and
vectors, client-scoped nodes under the shared nodes' names, which viser shows that one
viewer instead of the shared ones. The live rover is drawn once for everyone, so a live
frame costs the same whatever the number of viewers, plus a few small GUI updates per
following viewer; a replaying viewer is not redrawn until it follows again. What a viewer
sends changes only its own elements (viser routes a GUI message to the sender's handles),
its callbacks check the values they get, and ``server.scene3d.proxy`` lets through only a
camera report or an input's new value.

A scene is in the truth view or not (``truth``). In the truth view it shows all of the above;
otherwise it is what a real ground system could draw from the downlink alone: the rover at
its estimated pose (on its encoders' joint angles), the estimated traverses and the Sites,
the terrain around the estimate; the true rover, its traverse, the true sun, Earth and
boresight and the position error are never made, so no node or message of theirs exists
for its viewers. With ``roverops serve --truth-view conductor`` each rover has both scenes,
each a viser server of its own, and the relay connects each viewer to the one its token
allows (``server.state.Server.scene_for``): viser sends a scene's nodes to all its clients.

Coordinates are the mission frame of the frames' ``p_mission_*`` (the first Site: x North,
y East, z Down, metres), drawn with -z up. Attitudes come from the frames' ``q_b_ll``: LL
and Site orientations differ by the curvature of Mars over the traverse (1e-5 rad per
100 m), far below what a screen shows. Frames arrive from the runtime thread; a scene
thread draws the newest one at most ``VIEW_RATE_HZ`` times a second, inside
``server.atomic()`` so the rover, ghost and vectors move together. A viewer's own
controls call back on viser's event loop, in the order it sent its messages; each
viewer's lock keeps its replay and the live draws of it apart.
"""

from __future__ import annotations

import contextlib
import io
import logging
import math
import threading
from collections.abc import Callable, Coroutine, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import viser

from server.runtime import RoverRuntime
from server.scene3d.marks import Marks
from server.scene3d.model import (
    GHOST_RGB,
    REPLAY_NODES,
    SIDE_RGB,
    TRACK_RGB,
    TRUE_RGB,
    FloatArray,
    RoverModel,
    RoverPose,
    Track,
    draw_vectors,
    status_text,
)
from server.scene3d.terrain_mesh import TERRAIN_STEP_M, ground_mesh, terrain_note, terrain_patch
from server.sinks import FrameBatch, live_frame, with_truth
from server.storage import Store
from server.terrain.feed import ground_feed
from server.terrain.service import GroundMapService
from sim.scoring.truth import TruthDict, merged
from sim.world.sites import make_terrain

log = logging.getLogger(__name__)

VIEW_RATE_HZ = 10.0  # the live telemetry rate of the console (server.hub.MAX_RATE_HZ)
TERRAIN_RECUT_M = 8.0  # re-cut when the rover is this far from the patch centre
HISTORY_EVERY_S = 5.0  # stored frames are read back at this spacing (traverses, slider)
CAMERA_OFFSET_W = np.array([-7.0, -5.0, -5.0])  # behind, to the left of and above the rover
NARROW_VIEW_PX = 1000  # a 3D view narrower than this starts with its controls minimized
SLIDER_LABEL = "Sol time (LMST h)"
TRUTH_TERRAIN_LABEL = "Truth terrain"
GROUND_NODE = "/terrain/ground"
TRUTH_NODE = "/terrain/truth"


def guarded(
    what: str, callback: Callable[[viser.GuiEvent[Any]], None]
) -> Callable[[viser.GuiEvent[Any]], Coroutine[Any, Any, None]]:
    """``callback`` as viser runs a coroutine: on its event loop, one message's callback
    done before the next message's (its thread pool would run a drag's late value after a
    later "Follow live"), and what it raises logged, not lost."""

    async def run(event: viser.GuiEvent[Any]) -> None:
        try:
            callback(event)
        except Exception:
            log.exception("3D view: %s failed", what)

    return run


@dataclass
class Replay:
    """A viewer's own rover and ghost while it replays (its own vectors go with them; no
    ghost outside the truth view: the rover is drawn where it believes it is)."""

    model: RoverModel
    ghost: RoverModel | None


class Viewer:
    """One connected viewer: its own controls and status, and its own rover while it
    replays (module docstring). Built on viser's thread pool when the viewer connects; its
    controls call back on viser's event loop (``guarded``), live frames come from the scene
    thread, and ``lock`` keeps the two apart (neither waits for the other's thread)."""

    def __init__(self, scene: RoverScene, client: viser.ClientHandle) -> None:
        self.scene = scene
        self.client = client
        self.lock = threading.RLock()
        self.following = True
        self.replay: Replay | None = None
        self.shown: Mapping[str, Any] | None = None  # the frame this viewer sees
        self.shown_p: FloatArray | None = None  # its rover's position then (the chase)
        gui = client.gui
        self.status = gui.add_markdown(f"**{scene.rover}**")
        self.terrain_note = gui.add_markdown(terrain_note(scene.ground.version))
        self.follow = gui.add_checkbox("Follow live", True)
        self.chase = gui.add_checkbox(
            "Camera follows the rover", True, hint="keep your view's angle as the rover moves"
        )
        self.slider = gui.add_slider(SLIDER_LABEL, min=0.0, max=24.0, step=0.01, initial_value=0.0)
        self.follow.on_update(guarded("Follow live", self._on_follow))
        self.slider.on_update(guarded("the sol slider", self._on_slider))
        self.truth_terrain: viser.GuiCheckboxHandle | None = None
        if scene.truth:  # the truth terrain in place of the ground's map
            self.truth_terrain = gui.add_checkbox(
                TRUTH_TERRAIN_LABEL,
                False,
                hint="the simulator's terrain instead of the ground's map",
            )
            self.truth_terrain.on_update(guarded(TRUTH_TERRAIN_LABEL, self._on_truth_terrain))
        self.placed = False  # the controls' placement, decided on the first camera report
        client.camera.on_update(self._on_camera)

    def _on_camera(self, camera: viser.CameraHandle) -> None:
        """On the viewer's first camera report (it carries the view's size in pixels): a
        narrow view, as the one embedded in the console is, gets its controls minimized to
        their title bar (one click opens them) so that they do not cover the rover; a wide
        view, as a tab of its own is on a desktop, keeps them open."""
        if self.placed:
            return
        self.placed = True
        if 0 < camera.image_width < NARROW_VIEW_PX:
            self.client.gui.main_panel.minimize()

    # ---- what the viewer asks (viser's event loop) --------------------------------------

    def _on_follow(self, event: viser.GuiEvent[Any]) -> None:
        if event.client is None:  # our own update
            return
        if self.follow.value:  # viser made it a bool
            self.go_live()
        else:
            with self.lock:
                shown = self.shown
            if shown is not None:  # freeze the view where it is
                self.show_replay(shown)

    def _on_slider(self, event: viser.GuiEvent[Any]) -> None:
        if event.client is None:  # our own update while following
            return
        value = self.slider.value
        if not (isinstance(value, float) and math.isfinite(value)):
            log.warning("3D view: a sol time of %r ignored", value)
            with self.lock:
                shown = self.shown
            if shown is not None:
                self.slider.value = float(shown["lmst_h"])  # type: ignore[misc]  # viser's props
            return
        frame = self.scene.frame_at(value)
        if frame is None:
            return
        self.show_replay(frame)
        if not self.slider.min <= value <= self.slider.max:  # back onto the sol's span
            self.slider.value = float(frame["lmst_h"])  # type: ignore[misc]  # viser's props

    def _on_truth_terrain(self, event: viser.GuiEvent[Any]) -> None:
        if event.client is None or self.truth_terrain is None:
            return
        self.scene.show_truth_terrain(bool(self.truth_terrain.value))

    # ---- what the viewer sees ----------------------------------------------------------

    def show_live(self, frame: Mapping[str, Any], span: tuple[float, float] | None) -> None:
        """The live frame's status and slider, the camera carried along (the shared rover
        is drawn for everyone); nothing while this viewer replays."""
        p_w = np.asarray(frame[f"p_mission_{self.scene.pose}"], dtype=float)
        with self.lock:
            if not self.following:
                return
            with self.client.atomic():
                self._chase(p_w)
                self.status.content = status_text(frame, live=True, now_t_s=self.scene.runtime.t_s)
                if span is not None:
                    lo, hi = span
                    self.slider.min = math.floor(lo * 100.0) / 100.0
                    self.slider.max = max(math.ceil(hi * 100.0) / 100.0, self.slider.min + 0.01)
                    # At its end, on its step: the value changes once a step (36 s of the
                    # sol), not each frame. viser keeps one value for the viewer's moves and
                    # ours, and the callback reads it after viser set it: a write of ours
                    # between the two would replace the viewer's move.
                    self.slider.value = self.slider.max  # type: ignore[misc]  # viser's props
            self.shown = frame
        self.client.flush()

    def show_replay(self, frame: Mapping[str, Any]) -> None:
        """``frame`` for this viewer alone: its own rover, ghost and vectors shadow the
        shared ones; it stops following."""
        pose = RoverPose.from_frame(frame, self.scene.pose)
        truth = self.scene.truth
        with self.lock:
            if self.following:
                self.following = False
                self.follow.value = False  # type: ignore[misc]  # as above
                # A live update of the slider may have crossed the viewer's own move on
                # the wire: send its value back once (viser sends a value only when it
                # changes, hence the step aside first; the two coalesce in its buffer).
                value = self.slider.value
                self.slider.value = value + self.slider.step  # type: ignore[misc]
                self.slider.value = value  # type: ignore[misc]
            scene = self.client.scene
            if self.replay is None:
                self.replay = Replay(
                    RoverModel(scene, "/rover", TRUE_RGB, None),
                    RoverModel(scene, "/ghost", GHOST_RGB, 0.35) if truth else None,
                )
            with self.client.atomic():
                self._chase(pose.p_w)
                self.replay.model.show(pose)
                if self.replay.ghost is not None:
                    self.replay.ghost.show(RoverPose.from_frame(frame, "est"))
                if truth:
                    draw_vectors(scene, frame, pose)
                self.status.content = status_text(frame, live=False)
            self.shown = frame
        self.client.flush()

    def go_live(self) -> None:
        """Follow again: this viewer's own nodes go (the shared ones show again, as they
        are now), and it gets the live status at once."""
        with self.lock:
            if self.following:
                return
            self.following = True
            self.follow.value = True  # type: ignore[misc]  # as above
            for name in REPLAY_NODES if self.scene.truth else ("/rover",):
                self.client.scene.remove_by_name(name)
            self.replay = None
        frame, span = self.scene.live()
        if frame is not None:
            self.show_live(frame, span)

    def _chase(self, p_w: FloatArray) -> None:
        """Carry this viewer's camera along with its rover (its orbit and zoom kept:
        camera and look-at point move by the rover's displacement)."""
        last, self.shown_p = self.shown_p, p_w
        if last is None or not self.chase.value:
            return
        delta = p_w - last
        if float(np.linalg.norm(delta)) < 1e-3:
            return
        try:
            position = self.client.camera.position
        except AssertionError:  # the viewer has not reported its camera yet
            return
        self.client.camera.position = position + delta  # viser moves look_at with it


class RoverScene:
    """One rover's 3D view (module docstring): listens to the runtime's played-out frames;
    with the truth, or from the downlink alone (``truth`` False)."""

    def __init__(
        self,
        runtime: RoverRuntime,
        store: Store,
        truth: bool = True,
        ground: GroundMapService | None = None,
    ) -> None:
        self.runtime = runtime
        self.store = store
        self.truth = truth
        self.feed = ground_feed(runtime, store, ground)  # the ground's map, fed with the pairs
        self.ground = self.feed.service
        self._pairs_came = threading.Event()  # an image product reached the ground
        self._ground_version = -1  # the ground map's version drawn
        self._truth_shown = False  # the truth terrain in place of the ground's map
        self.pose = "true" if truth else "est"  # the pose the solid rover is drawn at
        self.rover = runtime.spec.name
        # The scene's own terrain (same site and seed: the same ground); the simulator's
        # tile cache belongs to the runtime thread.
        self.terrain = make_terrain(runtime.spec.site, runtime.spec.seed)
        self.origin_world = np.asarray(runtime.session.mission_origin_world, dtype=float)
        self.server: viser.ViserServer | None = None
        self._lock = threading.Lock()
        self._latest: Mapping[str, Any] | None = None
        self._live_truth: TruthDict | None = None  # across light time (``_take_apart``)
        self._dirty = threading.Event()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._tracks = {"true": Track(), "est": Track()} if truth else {"est": Track()}
        self.marks = Marks(self.terrain, self.origin_world, truth)  # keep-out zones, halts
        self._sites: dict[int, FloatArray] = {}
        self._new_sites: list[int] = []
        self._terrain_centre: FloatArray | None = None
        self._sol_frames: list[Mapping[str, Any]] = []  # the current sol, for the slider
        self._shown_p: FloatArray | None = None  # the live rover's position last drawn
        self.viewers: dict[int, Viewer] = {}  # by viser's client id
        self.frames_drawn = 0

    @property
    def port(self) -> int:
        if self.server is None:
            raise RuntimeError("the 3D view is not started")
        return self.server.get_port()

    # ---- life cycle ------------------------------------------------------------------

    def start(self) -> None:
        """Start viser on a free loopback port, draw the stored history, then follow."""
        # viser prints a banner with its loopback port whatever ``verbose`` says; operators
        # use the proxied /viser/{rover}/ instead, so the banner would only mislead.
        with contextlib.redirect_stdout(io.StringIO()):
            server = viser.ViserServer(host="127.0.0.1", port=0, label=self.rover, verbose=False)
        self.server = server
        # No share button: it would open a public tunnel to this view, past the console.
        server.gui.configure_theme(show_share_button=False)
        server.scene.set_up_direction("-z")
        # viser's default shadows come from a light that is not the sun: they would mislead
        # (and cost SwiftShader dearly); the sun arrow shows where the sun is.
        server.scene.configure_default_lights(enabled=True, cast_shadow=False)
        self.model = RoverModel(server.scene, "/rover", TRUE_RGB, None)
        self.ghost = RoverModel(server.scene, "/ghost", GHOST_RGB, 0.35) if self.truth else None
        server.on_client_connect(self._connect)
        server.on_client_disconnect(self._disconnect)
        for frame in self._history():
            self._take(frame)
        if self._latest is not None:
            self._draw(self._latest)
        elif self.truth:  # no frame yet: the ground is cut now, not by the first live draw
            session = self.runtime.session
            p_w = np.asarray(session.sim.drive_state.p_s, dtype=float) - self.origin_world
            self._recut_terrain(p_w)
        else:  # the rover knows it is where its mission frame begins
            self._recut_terrain(np.zeros(3))
        self.runtime.sinks.append(self)
        self._thread = threading.Thread(target=self._run, name=f"scene-{self.rover}", daemon=True)
        self._thread.start()
        self._pairs_came.set()  # the pairs stored before (a restart): taken on the scene's thread
        self._dirty.set()

    def stop(self) -> None:
        self._stop.set()
        self._dirty.set()
        if self._thread is not None:
            self._thread.join(timeout=5)
        if self in self.runtime.sinks:
            self.runtime.sinks.remove(self)
        if self.server is not None:
            self.server.stop()

    def _history(self) -> list[dict[str, Any]]:
        """Stored frames, decimated, for the traverses and the slider after a restart, and
        the last one stored (decimation may have passed it over)."""
        frames = self.store.frames(
            self.rover, -math.inf, math.inf, HISTORY_EVERY_S, with_truth=self.truth
        )
        last = with_truth(
            self.store.last_frame(self.rover),
            self.store.last_truth(self.rover) if self.truth else None,
        )
        if last is not None and (not frames or last["t_s"] > frames[-1]["t_s"]):
            frames.append(last)
        return frames

    # ---- viewers (viser's thread pool) --------------------------------------------------

    def _connect(self, client: viser.ClientHandle) -> None:
        try:
            viewer = Viewer(self, client)
            with self._lock:
                self.viewers[client.client_id] = viewer
            if self._shown_p is not None:  # start looking at the rover where it is now
                client.camera.position = tuple(self._shown_p + CAMERA_OFFSET_W)
                client.camera.look_at = tuple(self._shown_p)
            frame, span = self.live()
            if frame is not None:
                viewer.show_live(frame, span)
        except Exception:
            log.exception("3D view of %s: a viewer's controls failed", self.rover)

    def _disconnect(self, client: viser.ClientHandle) -> None:
        with self._lock:  # viser drops the viewer's own elements itself
            self.viewers.pop(client.client_id, None)

    def live(self) -> tuple[Mapping[str, Any] | None, tuple[float, float] | None]:
        """The newest frame and the slider's span over the current sol."""
        with self._lock:
            return self._latest, self._slider_span()

    def frame_at(self, lmst_h: float) -> Mapping[str, Any] | None:
        """The stored frame of the current sol nearest ``lmst_h``."""
        with self._lock:
            frames = list(self._sol_frames)
        if not frames:
            return None
        times = np.array([f["lmst_h"] for f in frames])
        return frames[int(np.argmin(np.abs(times - lmst_h)))]

    # ---- frames in (runtime thread) ----------------------------------------------------

    def publish(self, rover: str, batch: FrameBatch) -> None:
        """A frame sink (``server.sinks``): keep the traverses and the newest frame; note
        the pairs that came (the map takes them from storage, on the scene's thread)."""
        if batch.images:
            self._pairs_came.set()
        with self._lock:
            if batch.paired:
                for d, t in zip(batch.downlink, batch.truth, strict=True):
                    self._take(merged(d, t) if self.truth else d)
            else:
                self._take_apart(batch)
        self._dirty.set()

    def _take_apart(self, batch: FrameBatch) -> None:
        """Across light time: the downlink as it reaches the ground (older records that a
        pass fills in are not drawn over newer ones), the truth live (``live_frame``)."""
        if batch.truth:
            if not self.truth:
                return
            self._live_truth = batch.truth[-1]
            for t in batch.truth:
                self._tracks["true"].add(t["p_mission_true"])
            if self._latest is not None:
                self._latest = live_frame(self._latest, self._live_truth)
            return
        for d in sorted(batch.downlink, key=lambda d: d["t_s"]):
            if self._latest is None or d["t_s"] > self._latest["t_s"]:
                shown = live_frame(d, self._live_truth) if self.truth else dict(d)
                self._take({**shown, "received_t_s": batch.received_t_s}, true_track=False)

    def _take(self, f: Mapping[str, Any], true_track: bool = True) -> None:
        self._latest = f
        self.marks.take(f)
        if self.truth and true_track:
            self._tracks["true"].add(f["p_mission_true"])
        self._tracks["est"].add(f["p_mission_est"])
        for name, side in (f.get("estimators") or {}).items():  # roverops serve --estimators
            self._tracks.setdefault(name, Track()).add(side["p_mission"])
        site = int(f["site_index"])
        if site not in self._sites:
            # The Site's origin as the flight software defines it: where the estimate was
            # when it was planted (mission position minus position in the Site).
            self._sites[site] = np.asarray(f["p_mission_est"], float) - np.asarray(
                f["p_s_est"], float
            )
            self._new_sites.append(site)
        if self._sol_frames and int(f["sol"]) != int(self._sol_frames[-1]["sol"]):
            self._sol_frames = []
        if not self._sol_frames or f["t_s"] - self._sol_frames[-1]["t_s"] >= HISTORY_EVERY_S:
            self._sol_frames.append(f)

    # ---- drawing (scene thread) --------------------------------------------------------

    def _run(self) -> None:
        period = 1.0 / VIEW_RATE_HZ
        while not self._stop.is_set():
            self._dirty.wait()
            if self._stop.is_set():
                return
            self._dirty.clear()
            if self._pairs_came.is_set():
                self._pairs_came.clear()
                try:  # the ground's map takes the pairs stored since (redrawn by the next draw)
                    self.feed.catch_up()
                except Exception:  # a map that cannot take a pair must not end the view
                    log.exception("3D view of %s: the ground map's pairs failed", self.rover)
            with self._lock:
                latest = self._latest
            if latest is not None:
                try:
                    self._draw(latest)
                except Exception:  # a drawing error must not end the view
                    log.exception("3D view of %s: drawing failed", self.rover)
            self._stop.wait(period)

    def _draw(self, frame: Mapping[str, Any]) -> None:
        """The live frame: the shared rover, ghost, vectors, traverses and Sites once for
        everyone, then each following viewer's status and slider."""
        server = self.server
        assert server is not None
        pose = RoverPose.from_frame(frame, self.pose)
        with self._lock:
            tracks = {k: t.take_dirty() for k, t in self._tracks.items()}
            new_sites = [(i, self._sites[i]) for i in self._new_sites]
            self._new_sites = []
            slider_span = self._slider_span()
            viewers = list(self.viewers.values())
        self._recut_terrain(pose.p_w)
        with server.atomic():
            self.model.show(pose)
            with self._lock:
                self.marks.draw(server.scene, dict(self._sites))
            if self.ghost is not None:  # the truth view: the estimate beside the truth
                self.ghost.show(RoverPose.from_frame(frame, "est"))
                draw_vectors(server.scene, frame, pose)
            for which, chunks in tracks.items():
                rgb = TRACK_RGB.get(which, SIDE_RGB)
                for chunk, segs in chunks.items():
                    server.scene.add_line_segments(
                        f"/traverse_{which}/{chunk}", segs, rgb, thickness=0.03
                    )
            for index, origin in new_sites:
                server.scene.add_frame(
                    f"/site_{index}", axes_length=1.0, axes_radius=0.02, position=tuple(origin)
                )
                server.scene.add_label(
                    f"/site_{index}/label", f"Site {index}", position=(0.0, 0.0, -0.3)
                )
        server.flush()  # send now rather than at viser's next 1/60 s window
        self._shown_p = pose.p_w
        for viewer in viewers:
            try:
                viewer.show_live(frame, slider_span)
            except Exception:  # one viewer (gone, say) must not cost the others their frame
                log.exception("3D view of %s: a viewer's live frame failed", self.rover)
        self.frames_drawn += 1

    def _recut_terrain(self, p_w: FloatArray) -> None:
        """Draw the terrain around ``p_w`` when the rover nears the patch's edge, and the
        ground's map again whenever it has changed (its ``version``)."""
        centre = self._terrain_centre
        moved = centre is None or float(np.linalg.norm(p_w[:2] - centre)) >= TERRAIN_RECUT_M
        version = self.ground.version
        if not moved and version == self._ground_version:
            return
        assert self.server is not None
        if moved or centre is None:
            centre = np.round(p_w[:2] / TERRAIN_STEP_M) * TERRAIN_STEP_M  # vertices on a grid
        mesh = ground_mesh(self.ground.ground_map(), centre)
        truth = (
            terrain_patch(self.terrain, centre, self.origin_world) if self.truth and moved else None
        )
        with self.server.atomic():
            self.server.scene.add_mesh_trimesh(
                GROUND_NODE, mesh, visible=not self._truth_shown, cast_shadow=False
            )
            if truth is not None:
                self.server.scene.add_mesh_trimesh(
                    TRUTH_NODE, truth, visible=self._truth_shown, cast_shadow=False
                )
        self._terrain_centre = centre
        self._ground_version = version
        for viewer in list(self.viewers.values()):
            viewer.terrain_note.content = terrain_note(version)
        if moved:  # new viewers start behind and above the rover, looking at it (-z is up)
            self.server.initial_camera.look_at = tuple(p_w)
            self.server.initial_camera.position = tuple(p_w + CAMERA_OFFSET_W)

    def show_truth_terrain(self, shown: bool) -> None:
        """The truth view: the simulator's terrain in place of the ground's map, or back (for
        every viewer of this scene: viser shares its nodes)."""
        if not self.truth or self.server is None:
            return
        self._truth_shown = shown
        handles = self.server.scene._handle_from_node_name
        with self.server.atomic():
            for name, visible in ((GROUND_NODE, not shown), (TRUTH_NODE, shown)):
                handle = handles.get(name)
                if handle is not None:
                    handle.visible = visible

    def _slider_span(self) -> tuple[float, float] | None:
        if not self._sol_frames or self._latest is None:
            return None
        return float(self._sol_frames[0]["lmst_h"]), float(self._latest["lmst_h"])
