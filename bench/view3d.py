"""``roverops bench view3d``: what the viser 3D view of a rover (``server.scene3d``) costs.

The scene runs in this process: a ``RoverScene`` on Spirit's runtime (its clock not
started), its own viser server on a loopback port, an empty in-memory store. It is fed the
frames of a real drive in order, each kept as ``publish`` keeps it, and each is then drawn
by calling ``_draw`` directly, so a timing is the scene thread's work for one frame.

- ``view_draw_ms_median``, ``view_draw_ms_p95`` (and ``_max``): wall time of ``_draw`` per
  frame of a ``drive_m`` DRIVE_STRAIGHT (one frame per simulated second) with no viewer
  connected: viser only buffers the messages. Every frame counts, the draws that re-cut the
  terrain (``view_draw_recuts``, one per ``TERRAIN_RECUT_M`` driven) included.
- ``..._1_client``: the same with one viewer, a WebSocket straight to viser's port
  (subprotocol ``viser-v<version>``, no browser) that reports a camera (so that viser
  counts it as a client and the scene gives it its own controls) and that a thread of this
  process drains, keeping every message. viser serialises on its own event-loop thread, so
  a draw's time now includes that work competing for the interpreter lock (and the
  viewer's receiving);
  ``view_draw_to_client_ms_*`` runs from the draw's start until the viewer holds its last
  byte (viser holds a window of messages for 1/60 s before it sends it). The viewer
  connects once the first frame is drawn (what it downloads then is
  ``view_initial_scene_bytes_1_client``); after each draw the bench waits until the viewer
  has its messages and then nothing for ``QUIET_S``, so draws do not pile up (the scene
  thread draws at most ``VIEW_RATE_HZ`` times a second).
- ``view_bytes_per_draw_1_client``: bytes the viewer received per drawn frame, median over
  the draws that did not re-cut the terrain; the initial scene is not a draw.
  ``view_bytes_last_draw_1_client``: the drive's last draw (the traverses, sent whole each
  draw, grow with the distance driven). A viser message belongs to the draw during whose
  span viser serialised it: its ``timestampSec`` is this process's ``time.perf_counter()``.
- ``view_terrain_recut_s_median``: ``_recut_terrain`` forced (``_terrain_centre`` reset)
  at ``recuts`` positions ``TERRAIN_RECUT_M`` apart on the drive's line past its end, as if
  the rover drove on: ``terrain_patch`` (building the terrain tiles new at the patch's
  leading edge), the mesh handed to viser, until the viewer holds it.
  ``view_terrain_cut_s_median`` is the call alone, ``view_terrain_patch_s_median``
  ``terrain_patch`` alone at the same positions once their tiles exist, and
  ``view_terrain_bytes_1_client`` what a viewer receives per re-cut.
- ``sol_sim_wall_s_3d``, ``sol_sim_wall_s_no_3d``, ``view_sol_wall_ratio``:
  ``bench.server.measure_sol`` through ``roverops serve`` (a subprocess) with the 3D
  views on (``ROVEROPS_NO_3D=0``, no viewer connected) and off (``ROVEROPS_NO_3D=1``),
  medians of ``sol_repeats`` runs each, interleaved, each on a new server and database.
  ``view_sol_frames_drawn``: how many frames the server's scene had drawn when the sol
  completed (median).

- ``signin_with_view_s``, ``command_round_trip_with_view_s``: the console in Chromium with
  software WebGL (SwiftShader, as on a machine without a GPU; the browser tests' flags)
  against a ``roverops serve`` with the 3D view on, the view shown and drawing (its scene
  loaded in the frame): from the click on "Sign in" until the header names who signed in,
  and from a click on Pause (or Resume) until the header's clock says so; medians over
  ``console_repeats`` fresh pages (two round trips each). What the operator waits for,
  clicks included (issue 21: the view shared the page's thread and a sign-in took 9-110 s).

Output contract: ``bench.result``.
"""

from __future__ import annotations

import bisect
import contextlib
import io
import math
import re
import statistics
import tempfile
import threading
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import msgspec  # viser's own dependencies: its wire format is zstd-compressed msgpack
import numpy as np
import viser
import zstandard
from numpy.typing import NDArray
from websockets.exceptions import ConnectionClosed
from websockets.typing import Subprotocol

from bench.result import bench_result
from bench.server import measure_sol
from bench.server_process import RunningServer, running_server
from sequences import commands as cmd
from server.runtime import ROVERS, RoverRuntime
from server.scene3d.scene import TERRAIN_RECUT_M, VIEW_RATE_HZ, RoverScene
from server.scene3d.terrain_mesh import TERRAIN_STEP_M, terrain_patch
from server.storage import Store
from sim.errors import InputError
from sim.scoring.truth import merged

FloatArray = NDArray[np.float64]

ROVER = "spirit"
QUIET_S = 0.03  # a viewer that received nothing this long has a whole draw (viser: 1/60 s)
SETTLE_TIMEOUT_S = 60.0  # a viewer still receiving after this long is stuck, not busy
WINDOW_HEADER_BYTES = 16  # viser's window: two little-endian uint64 lengths first

TARGETS: dict[str, dict[str, float]] = {
    # a draw must fit the live telemetry rate (10 frames a second)
    "view_draw_ms_p95_1_client": {"le": 1000.0 / VIEW_RATE_HZ},
    # the console answers an operator within a second with the view drawing beside it
    "signin_with_view_s": {"le": 1.0},
    "command_round_trip_with_view_s": {"le": 1.0},
}
CHROMIUM_ARGS = [
    "--no-sandbox", "--disable-gpu", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
    "--disable-background-networking", "--disable-component-update", "--disable-sync",
    "--no-first-run",
]  # fmt: skip  # WebGL in software, as without a GPU
CONSOLE_TIMEOUT_MS = 180_000  # a console that takes this long is broken, not slow
SCENE_LOADED = "() => !!window.__viserMutable?.nodeRefFromName?.['/terrain/ground']"


# ---- a viewer without a browser -------------------------------------------------------------

CAMERA_REPORT = {  # viser's ViewerCameraMessage, as its client sends it
    "type": "ViewerCameraMessage",
    "wxyz": (1.0, 0.0, 0.0, 0.0),
    "position": (-7.0, -5.0, -5.0),
    "fov": 1.0,
    "near": 0.01,
    "far": 1000.0,
    "image_height": 600,
    "image_width": 800,
    "look_at": (0.0, 0.0, 0.0),
    "up_direction": (0.0, 0.0, -1.0),
}


@dataclass(frozen=True)
class Window:
    """One WebSocket message from viser (a window of its messages) and when it arrived
    (``time.perf_counter()``)."""

    received_s: float
    data: bytes


def window_stamp(data: bytes) -> tuple[float, int]:
    """When viser serialised a window (its ``time.perf_counter()``) and how many messages
    it holds. viser's wire format (``viser.infra._infra._message_producer``): the msgpack
    length and the compressed length (little-endian uint64), the zstd-compressed msgpack
    ``{"messages", "timestampSec", "binaryBufferLengths"}``, then raw binary buffers.
    ValueError naming the problem for anything else."""
    if len(data) < WINDOW_HEADER_BYTES:
        raise ValueError(f"a viser window of {len(data)} bytes is shorter than its header")
    inner_len = int.from_bytes(data[:8], "little")
    packed_len = int.from_bytes(data[8:WINDOW_HEADER_BYTES], "little")
    if WINDOW_HEADER_BYTES + packed_len > len(data):
        raise ValueError(
            f"a viser window of {len(data)} bytes claims {packed_len} compressed bytes"
        )
    packed = data[WINDOW_HEADER_BYTES : WINDOW_HEADER_BYTES + packed_len]
    try:
        inner = zstandard.ZstdDecompressor().decompress(packed, max_output_size=inner_len)
        payload = msgspec.msgpack.decode(inner)
    except (zstandard.ZstdError, msgspec.DecodeError) as error:
        raise ValueError(f"a viser window that does not decode: {error}") from None
    if not isinstance(payload, dict) or not {"timestampSec", "messages"} <= payload.keys():
        raise ValueError("a viser window without timestampSec and messages")
    return float(payload["timestampSec"]), len(payload["messages"])


class Viewer:
    """A WebSocket straight to viser's port whose messages a thread keeps; decoding waits
    until the measurement is over, so the thread takes little from the draws."""

    def __init__(self, port: int) -> None:
        from websockets.sync.client import connect

        self.windows: list[Window] = []
        self._ws = connect(
            f"ws://127.0.0.1:{port}",
            subprotocols=[Subprotocol(f"viser-v{viser.__version__}")],
            compression=None,  # viser serves without permessage-deflate
            max_size=None,  # a terrain patch is a few MB in one window
            proxy=None,
            open_timeout=30.0,
        )
        self._thread = threading.Thread(target=self._drain, name="bench-viewer", daemon=True)
        self._thread.start()
        # viser counts a client as connected (its own controls, the camera chase) once it
        # has reported its camera, as a browser does at once.
        self._ws.send(msgspec.msgpack.encode(CAMERA_REPORT))

    def _drain(self) -> None:
        with contextlib.suppress(ConnectionClosed):
            for message in self._ws:
                data = message if isinstance(message, bytes) else message.encode()
                self.windows.append(Window(time.perf_counter(), data))

    def settle(self, at_least: int = 0) -> None:
        """Return once the viewer holds ``at_least`` windows and received nothing for
        ``QUIET_S``; RuntimeError if the connection ends or it never goes quiet."""
        deadline = time.monotonic() + SETTLE_TIMEOUT_S
        seen = -1
        while seen != len(self.windows) or seen < at_least:
            if not self._thread.is_alive():
                raise RuntimeError("viser closed the viewer's WebSocket")
            if time.monotonic() > deadline:
                raise RuntimeError(f"the viewer was still receiving after {SETTLE_TIMEOUT_S} s")
            seen = len(self.windows)
            time.sleep(QUIET_S)

    def close(self) -> None:
        self._ws.close()
        self._thread.join(timeout=10.0)


def by_span(stamps: Sequence[float], starts: Sequence[float]) -> list[list[int]]:
    """Indices of ``stamps`` per span: span ``i`` runs from ``starts[i]`` (increasing) to
    ``starts[i + 1]``, the last one on; stamps before ``starts[0]`` belong to none.

    >>> by_span([0.5, 1.0, 1.2, 2.5, 9.0], [1.0, 2.0])
    [[1, 2], [3, 4]]
    """
    spans: list[list[int]] = [[] for _ in starts]
    for index, stamp in enumerate(stamps):
        span = bisect.bisect_right(starts, stamp) - 1
        if span >= 0:
            spans[span].append(index)
    return spans


# ---- the scene, in this process ---------------------------------------------------------


@dataclass
class Spans:
    """What was timed: each span's start (``perf_counter``), the wall time of its call and
    whether it re-cut the terrain."""

    start_s: list[float] = field(default_factory=list)
    wall_s: list[float] = field(default_factory=list)
    recut: list[bool] = field(default_factory=list)


def drive_frames(drive_m: float) -> tuple[RoverRuntime, list[dict[str, Any]]]:
    """Spirit's runtime after a ``drive_m`` DRIVE_STRAIGHT, and the drive's frames as the
    runtime plays them out (``as_dict``)."""
    runtime = RoverRuntime(ROVERS[ROVER])
    runtime.session.execute(cmd.DriveStraight(distance_m=drive_m))
    session = runtime.session
    return runtime, [
        merged(d.as_dict(), t.as_dict())
        for d, t in zip(session.downlinks, session.truths, strict=True)
    ]


@contextlib.contextmanager
def started_scene(runtime: RoverRuntime, store: Store) -> Iterator[RoverScene]:
    """A started ``RoverScene`` (stopped on exit). viser prints to stdout whatever its
    ``verbose``; ``roverops bench view3d --json`` must print JSON alone."""
    scene = RoverScene(runtime, store)
    with contextlib.redirect_stdout(io.StringIO()):
        scene.start()
    try:
        yield scene
    finally:
        with contextlib.redirect_stdout(io.StringIO()):
            scene.stop()


def draw_in_order(
    scene: RoverScene, frames: Sequence[dict[str, Any]], viewer: Viewer | None, into: Spans
) -> None:
    """Keep and draw each frame in turn, timing ``_draw``; with a viewer, wait after each
    draw until it holds everything."""
    for frame in frames:
        with scene._lock:  # what publish keeps, without waking the scene thread
            scene._take(frame)
        centre = scene._terrain_centre
        held = len(viewer.windows) if viewer is not None else 0
        start = time.perf_counter()
        scene._draw(frame)
        into.wall_s.append(time.perf_counter() - start)
        into.start_s.append(start)
        into.recut.append(scene._terrain_centre is not centre)
        if viewer is not None:
            viewer.settle(at_least=held + 1)  # every draw sends: it re-adds the arrows


def recut_positions(frames: Sequence[dict[str, Any]], count: int) -> list[FloatArray]:
    """``count`` positions ``TERRAIN_RECUT_M`` apart on the drive's line past its end."""
    first = np.asarray(frames[0]["p_mission_true"], dtype=float)
    last = np.asarray(frames[-1]["p_mission_true"], dtype=float)
    along = np.array([last[0] - first[0], last[1] - first[1], 0.0])
    norm = float(np.linalg.norm(along))
    along = along / norm if norm > 1e-6 else np.array([1.0, 0.0, 0.0])
    return [last + k * TERRAIN_RECUT_M * along for k in range(1, count + 1)]


def recut_terrain_at(
    scene: RoverScene, positions: Sequence[FloatArray], viewer: Viewer, into: Spans
) -> None:
    """Force a terrain re-cut at each position, timing ``_recut_terrain``; wait after each
    until the viewer holds it."""
    for p_w in positions:
        scene._terrain_centre = None  # forces the re-cut
        held = len(viewer.windows)
        start = time.perf_counter()
        scene._recut_terrain(p_w)
        into.wall_s.append(time.perf_counter() - start)
        into.start_s.append(start)
        into.recut.append(True)
        viewer.settle(at_least=held + 1)


def time_patches(scene: RoverScene, positions: Sequence[FloatArray]) -> list[float]:
    """Wall time of ``terrain_patch`` alone at each position (tiles already built)."""
    walls = []
    for p_w in positions:
        centre = np.round(p_w[:2] / TERRAIN_STEP_M) * TERRAIN_STEP_M  # as _recut_terrain
        start = time.perf_counter()
        terrain_patch(scene.terrain, centre, scene.origin_world)
        walls.append(time.perf_counter() - start)
    return walls


def _ms(values_s: Sequence[float], percent: float) -> float:
    return float(np.percentile(np.asarray(values_s, dtype=float) * 1000.0, percent))


def delivered(viewer: Viewer, spans: Spans) -> tuple[list[int], list[float], list[int], int]:
    """Per span, what the viewer received of it: bytes, seconds from the span's start to
    its last byte (NaN if nothing), viser messages; and the bytes before the first span
    (the initial scene)."""
    stamped = [(window, *window_stamp(window.data)) for window in viewer.windows]
    groups = by_span([stamp for _, stamp, _ in stamped], spans.start_s)
    claimed = {i for group in groups for i in group}
    initial = sum(len(w.data) for i, (w, _, _) in enumerate(stamped) if i not in claimed)
    sizes, latency_s, messages = [], [], []
    for start, group in zip(spans.start_s, groups, strict=True):
        sizes.append(sum(len(stamped[i][0].data) for i in group))
        arrived = [stamped[i][0].received_s for i in group]
        latency_s.append(max(arrived) - start if arrived else math.nan)
        messages.append(sum(stamped[i][2] for i in group))
    return sizes, latency_s, messages, initial


def measure_scene(drive_m: float, recuts: int) -> dict[str, Any]:
    """The in-process figures (module docstring): draws without and with one viewer, and
    terrain re-cuts with the viewer."""
    runtime, frames = drive_frames(drive_m)
    if len(frames) < 3:
        raise InputError("drive_m", f"{drive_m:g} m gives {len(frames)} frames: drive further")
    store = Store("sqlite://")  # empty: the scene draws no stored history
    alone, with_viewer = Spans(), Spans()
    try:
        with started_scene(runtime, store) as scene:
            draw_in_order(scene, frames, None, alone)
        with started_scene(runtime, store) as scene:
            draw_in_order(scene, frames[:1], None, Spans())  # the scene a viewer finds
            viewer = Viewer(scene.port)
            try:
                viewer.settle(at_least=1)
                draw_in_order(scene, frames[1:], viewer, with_viewer)
                draws = len(with_viewer.start_s)
                positions = recut_positions(frames, recuts)
                recut_terrain_at(scene, positions, viewer, with_viewer)
            finally:
                viewer.close()
            patch_s = time_patches(scene, positions)
    finally:
        store.close()
    sizes, latency_s, messages, initial = delivered(viewer, with_viewer)
    plain = [i for i in range(draws) if not with_viewer.recut[i]]
    draw_latency = [latency_s[i] for i in range(draws) if math.isfinite(latency_s[i])]
    recut_latency = latency_s[draws:]
    return {
        "view_drive_m": drive_m,
        "view_frames": len(frames),
        "view_draw_ms_median": _ms(alone.wall_s, 50),
        "view_draw_ms_p95": _ms(alone.wall_s, 95),
        "view_draw_ms_max": _ms(alone.wall_s, 100),
        "view_draw_recuts": sum(alone.recut),
        "view_draw_ms_median_1_client": _ms(with_viewer.wall_s[:draws], 50),
        "view_draw_ms_p95_1_client": _ms(with_viewer.wall_s[:draws], 95),
        "view_draw_ms_max_1_client": _ms(with_viewer.wall_s[:draws], 100),
        "view_draw_to_client_ms_median_1_client": _ms(draw_latency, 50),
        "view_draw_to_client_ms_p95_1_client": _ms(draw_latency, 95),
        "view_bytes_per_draw_1_client": int(statistics.median(sizes[i] for i in plain)),
        "view_bytes_last_draw_1_client": sizes[draws - 1],
        "view_messages_per_draw_1_client": int(statistics.median(messages[i] for i in plain)),
        "view_initial_scene_bytes_1_client": initial,
        "view_terrain_recuts": recuts,
        "view_terrain_recut_s_median": statistics.median(recut_latency),
        "view_terrain_cut_s_median": statistics.median(with_viewer.wall_s[draws:]),
        "view_terrain_patch_s_median": statistics.median(patch_s),
        "view_terrain_bytes_1_client": int(statistics.median(sizes[draws:])),
    }


# ---- a sol through the real server, the 3D view on and off ---------------------------------


def _check_view(server: RunningServer, view_on: bool) -> None:
    """RuntimeError unless the server's 3D view is as asked (``/api/rovers/{rover}/scene``
    answers 200 with the view on, 404 with it off)."""
    status, answer = server.request("GET", f"/api/rovers/{ROVER}/scene")
    if status != (200 if view_on else 404):
        state = "on" if view_on else "off"
        raise RuntimeError(f"asked for the 3D view {state}, the server answered {status}: {answer}")


def measure_sol_walls(drive_m: float, hga_min: float, repeats: int) -> dict[str, Any]:
    """``measure_sol`` with the 3D view on and off, interleaved, ``repeats`` times each."""
    walls: dict[bool, list[float]] = {True: [], False: []}
    frames_drawn: list[int] = []
    for _ in range(repeats):
        for view_on in (True, False):
            env = {"ROVEROPS_NO_3D": "0" if view_on else "1"}
            with (
                tempfile.TemporaryDirectory(prefix="roverops-bench-view3d-") as tmp,
                running_server(Path(tmp), env=env) as server,
            ):
                _check_view(server, view_on)
                walls[view_on].append(measure_sol(server, drive_m, hga_min)["sol_sim_wall_s"])
                if view_on:
                    scene = server.ok("GET", f"/api/rovers/{ROVER}/scene")
                    frames_drawn.append(int(scene["frames_drawn"]))
    on, off = statistics.median(walls[True]), statistics.median(walls[False])
    return {
        "sol_sim_wall_s_3d": on,
        "sol_sim_wall_s_no_3d": off,
        "view_sol_wall_ratio": on / off,
        "view_sol_frames_drawn": int(statistics.median(frames_drawn)),
        "view_sol_repeats": repeats,
        "view_sol_drive_m": drive_m,
    }


# ---- the console in a browser with the view shown -------------------------------------------


def measure_console(repeats: int) -> dict[str, Any]:
    """Sign-in and clock round trips in Chromium with software WebGL, the 3D view shown and
    drawing (module docstring). RuntimeError when playwright or Chromium is missing."""
    import shutil

    try:
        from playwright.sync_api import expect, sync_playwright
    except ImportError:
        raise RuntimeError("bench view3d needs playwright: pip install -e '.[dev]'") from None
    chromium = shutil.which("chromium") or "/usr/bin/chromium"
    if not Path(chromium).exists():
        raise RuntimeError("bench view3d needs Chromium (Debian: apt-get install chromium)")
    signin_s: list[float] = []
    round_trip_s: list[float] = []
    with (
        tempfile.TemporaryDirectory(prefix="roverops-bench-console-") as tmp,
        running_server(Path(tmp), env={"ROVEROPS_NO_3D": "0"}) as server,
        sync_playwright() as p,
    ):
        _check_view(server, True)
        browser = p.chromium.launch(executable_path=chromium, args=CHROMIUM_ARGS)
        try:
            for _ in range(repeats):
                page = browser.new_page(viewport={"width": 1280, "height": 800})
                page.set_default_timeout(CONSOLE_TIMEOUT_MS)
                expect.set_options(timeout=CONSOLE_TIMEOUT_MS)
                page.add_init_script("localStorage.setItem('roverops-view3d', 'shown')")
                page.goto(f"{server.base_url}/?rover={ROVER}")
                view = page.get_by_test_id("view3d")
                expect(view).to_have_attribute("src", re.compile(f"/viser/{ROVER}/$"))
                handle = view.element_handle()
                frame = handle.content_frame() if handle else None
                if frame is None:
                    raise RuntimeError("the 3D view's frame did not load")
                frame.wait_for_function(SCENE_LOADED)
                page.fill("[data-testid=token]", server.token)
                start = time.perf_counter()
                page.click("[data-testid=sign-in]")
                expect(page.get_by_test_id("signed-in")).to_have_text("bootstrap · admin")
                signin_s.append(time.perf_counter() - start)
                clock = page.get_by_test_id("clock-speed")
                for button, now in (("#pause", "paused"), ("#resume", "running")) * 2:
                    start = time.perf_counter()
                    page.click(button)
                    expect(clock).to_contain_text(now)
                    round_trip_s.append(time.perf_counter() - start)
                page.close()
        finally:
            browser.close()
    return {
        "signin_with_view_s": statistics.median(signin_s),
        "command_round_trip_with_view_s": statistics.median(round_trip_s),
        "console_repeats": repeats,
    }


# ---- the bench ------------------------------------------------------------------------------


def _check_inputs(
    drive_m: float, recuts: int, sol_drive_m: float, sol_repeats: int, console_repeats: int
) -> None:
    for name, value in (("drive_m", drive_m), ("sol_drive_m", sol_drive_m)):
        if not (math.isfinite(value) and value > 0.0):
            raise InputError(name, f"must be a positive distance in metres, got {value!r}")
    for name, count in (("recuts", recuts), ("sol_repeats", sol_repeats),
                        ("console_repeats", console_repeats)):  # fmt: skip
        if count < 1:
            raise InputError(name, f"must be at least 1, got {count!r}")


def bench_view3d(
    drive_m: float = 20.0,
    recuts: int = 5,
    sol_drive_m: float = 100.0,
    sol_hga_min: float = 15.0,
    sol_repeats: int = 2,
    console_repeats: int = 5,
) -> dict[str, Any]:
    """The 3D view bench (module docstring); smaller arguments make a quick run (the
    target stays the one of the live rate)."""
    _check_inputs(drive_m, recuts, sol_drive_m, sol_repeats, console_repeats)
    metrics = measure_scene(drive_m, recuts)
    metrics.update(measure_sol_walls(sol_drive_m, sol_hga_min, sol_repeats))
    metrics.update(measure_console(console_repeats))
    return bench_result("view3d", metrics, TARGETS)
