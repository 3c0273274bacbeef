"""A rehearsal in the 3D view (issue 25): the cloud of predicted traverses and the predicted
end of each step, drawn on the ground's map beside the rover.

What is drawn comes from a campaign's risk table (``server.rehearsal.risk``'s JSON):

- **the cloud**: each run's thinned true traverse (``paths``, mission frame North, East) as
  a thin ribbon ``CLOUD_WIDTH_M`` wide lying on the ground, semi-transparent (viser's line
  segments have no opacity; a mesh has), so that where many runs went the cloud is denser;
- **the ellipses**: at each step's predicted mean end position, the 50 % and 95 % ellipses of
  the Gaussian fit to the runs' true end positions (the table's semi-axes ``a_m``, ``b_m``
  and the major axis' bearing ``angle_deg`` from North towards East: chi-square with 2
  degrees of freedom, k^2 = -2 ln(1 - p), as the table computes them), as line segments on
  the ground, the 95 % one in the colour of the line's verdict, labelled with its line.

A point ``(n, e)`` is drawn at the ground's map's height there (``GroundMap.height_at``,
bilinear, as ``server.scene3d.terrain_mesh`` draws the map's cells), ``ABOVE_GROUND_M`` above
it, in the mission frame (z Down) like the other marks (``server.scene3d.marks``; the
keep-out zones the rover reports are drawn there). The table is what a rehearsal predicts
from the ground's knowledge, never the live rover's truth, so both scenes of a rover (with
the truth or from the downlink alone) draw it.

Each viewer is told in its controls which rehearsal it sees ("rehearsal #N: 200 runs"), as
it is told what its terrain is (``terrain_note``). ``show_latest`` draws a rover's newest
finished campaign (for the rehearsal service to call when one finishes), ``show_stored`` the
one the console picks (``POST /api/rovers/{rover}/scene/rehearsal``); ``clear`` takes it
away.
"""

from __future__ import annotations

import math
import threading
import weakref
from collections.abc import Iterable, Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
import viser
from numpy.typing import NDArray

from server.errors import ConflictError, NotFoundError
from server.storage.rehearsals import get_rehearsal, list_rehearsals
from server.storage.store import Store
from server.terrain.ground_map import GroundMap

if TYPE_CHECKING:
    from server.scene3d.scene import RoverScene

FloatArray = NDArray[np.float64]

NODE = "/rehearsal"
CLOUD_RGB = (120, 200, 255)
CLOUD_OPACITY = 0.35
CLOUD_WIDTH_M = 0.05  # a wheel track is ~0.16 m: thin, yet a few pixels from 10 m
ELLIPSE_50_RGB = (235, 235, 235)
VERDICT_RGB = {"ok": (107, 212, 138), "caution": (240, 180, 41), "risk": (255, 107, 107)}
ELLIPSE_POINTS = 64
ABOVE_GROUND_M = 0.04  # above the ground's map, so its mesh does not hide the marks
MIN_SEGMENT_M = 1e-4  # shorter steps of a path carry no direction


def rehearsal_note(number: int | None, runs: int = 0) -> str:
    """What a viewer is told of the rehearsal it sees."""
    if number is None:
        return "No rehearsal shown"
    return f"rehearsal #{number}: {runs} run{'s' if runs != 1 else ''}"


def ellipse_ne(
    mean_m: Any, a_m: float, b_m: float, angle_deg: float, n: int = ELLIPSE_POINTS
) -> FloatArray:
    """The ellipse's outline, (n + 1, 2) points (North, East; closed): semi-axes ``a_m``
    (major) and ``b_m``, the major axis at ``angle_deg`` from North towards East."""
    if not (a_m >= 0.0 and b_m >= 0.0 and math.isfinite(angle_deg)):
        raise ValueError(
            f"ellipse: semi-axes must be >= 0 and the angle finite, got {a_m}, {b_m}, {angle_deg}"
        )
    theta = math.radians(angle_deg)
    u = np.array([math.cos(theta), math.sin(theta)])  # the major axis, (N, E)
    v = np.array([-math.sin(theta), math.cos(theta)])
    t = np.linspace(0.0, 2.0 * math.pi, n + 1)
    out: FloatArray = (
        np.asarray(mean_m, dtype=float)[None, :]
        + a_m * np.cos(t)[:, None] * u[None, :]
        + b_m * np.sin(t)[:, None] * v[None, :]
    )
    return out


def on_ground(ground: GroundMap, ne: FloatArray) -> FloatArray:
    """(n, 3) mission-frame points (North, East, Down) on the ground's map at ``ne``."""
    h = ground.height_at(ne[:, 0], ne[:, 1])
    return np.stack([ne[:, 0], ne[:, 1], -h - ABOVE_GROUND_M], axis=1)


def outline_segments(points: FloatArray) -> FloatArray:
    """A polyline's (n - 1, 2, 3) segments for ``add_line_segments``."""
    out: FloatArray = np.stack([points[:-1], points[1:]], axis=1)
    return out


def ribbon(
    ground: GroundMap, paths: Iterable[Any], width_m: float = CLOUD_WIDTH_M
) -> tuple[FloatArray, NDArray[np.int32]]:
    """The paths as one mesh of flat ribbons on the ground: each segment a quad ``width_m``
    wide across its horizontal direction; vertices (4 per segment) and faces (2 per)."""
    quads: list[FloatArray] = []
    for path in paths:
        ne = np.asarray(path, dtype=float).reshape(-1, 2)
        if len(ne) < 2:
            continue
        d = np.diff(ne, axis=0)
        length = np.linalg.norm(d, axis=1)
        keep = length > MIN_SEGMENT_M
        if not np.any(keep):
            continue
        a, b, d, length = ne[:-1][keep], ne[1:][keep], d[keep], length[keep]
        across = np.stack([-d[:, 1], d[:, 0]], axis=1) / length[:, None] * (width_m / 2.0)
        corners = np.stack([a - across, a + across, b + across, b - across], axis=1)  # (m, 4, 2)
        quads.append(on_ground(ground, corners.reshape(-1, 2)))
    if not quads:
        return np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int32)
    vertices = np.concatenate(quads)
    first = np.arange(0, len(vertices), 4, dtype=np.int32)[:, None]
    faces = np.concatenate([first + np.array([0, 1, 2]), first + np.array([0, 2, 3])])
    return vertices, faces.astype(np.int32)


class RehearsalView:
    """The rehearsal one scene shows (module docstring), and each viewer's note of it."""

    def __init__(self, scene: RoverScene) -> None:
        self.scene = scene
        self.number: int | None = None
        self.runs = 0
        self.paths = 0
        self.ellipses = 0
        self._lock = threading.Lock()
        self._notes: dict[int, viser.GuiMarkdownHandle] = {}
        self._listening = False

    def state(self) -> dict[str, Any] | None:
        """What is drawn, for the scene's state (GET .../scene): None before a rehearsal."""
        if self.number is None:
            return None
        return {
            "id": self.number,
            "runs": self.runs,
            "paths": self.paths,
            "ellipses": self.ellipses,
            "note": rehearsal_note(self.number, self.runs),
        }

    def show(self, number: int, risk: Mapping[str, Any]) -> None:
        """Draw campaign ``number``'s risk table in place of any rehearsal drawn before."""
        server = self.scene.server
        if server is None:
            raise RuntimeError("the 3D view is not started")
        ground = self.scene.ground.ground_map()
        vertices, faces = ribbon(ground, risk.get("paths") or [])
        lines = list(risk.get("lines") or [])
        with server.atomic():
            server.scene.remove_by_name(NODE)
            server.scene.add_frame(NODE, show_axes=False)
            if len(faces):
                server.scene.add_mesh_simple(
                    f"{NODE}/cloud",
                    vertices.astype(np.float32),
                    faces,
                    color=CLOUD_RGB,
                    opacity=CLOUD_OPACITY,
                    side="double",
                    cast_shadow=False,
                    receive_shadow=False,
                )
            ellipses = 0
            for line in lines:
                fit = line.get("end_true")
                if not fit or not fit.get("ellipse_95"):
                    continue  # the step never ran in any run
                k = int(line["line"])
                rgb = VERDICT_RGB.get(str(line.get("verdict")), VERDICT_RGB["risk"])
                for which, colour in (("ellipse_50", ELLIPSE_50_RGB), ("ellipse_95", rgb)):
                    e = fit[which]
                    ne = ellipse_ne(fit["mean_m"], e["a_m"], e["b_m"], e["angle_deg"])
                    server.scene.add_line_segments(
                        f"{NODE}/line_{k}/{which}",
                        outline_segments(on_ground(ground, ne)),
                        colour,
                        thickness=0.02 if which == "ellipse_50" else 0.035,
                    )
                top = on_ground(ground, np.asarray([fit["mean_m"]], dtype=float))[0]
                server.scene.add_label(
                    f"{NODE}/line_{k}/label",
                    f"line {k}",
                    position=tuple(top + np.array([0.0, 0.0, -0.25])),
                )
                ellipses += 1
        server.flush()
        with self._lock:
            self.number = int(number)
            self.runs = int(risk.get("runs") or 0)
            self.paths = len(risk.get("paths") or [])
            self.ellipses = ellipses
        self._tell_viewers()

    def clear(self) -> None:
        """No rehearsal shown."""
        server = self.scene.server
        if server is not None:
            server.scene.remove_by_name(NODE)
        with self._lock:
            self.number, self.runs, self.paths, self.ellipses = None, 0, 0, 0
        self._tell_viewers()

    # ---- the viewers' notes -----------------------------------------------------------

    def _tell_viewers(self) -> None:
        server = self.scene.server
        if server is None:
            return
        with self._lock:
            if not self._listening:  # viewers that connect later get their note too
                server.on_client_connect(self._connect)
                server.on_client_disconnect(self._disconnect)
                self._listening = True
        for client in list(server.get_clients().values()):
            self._note(client)

    def _note(self, client: viser.ClientHandle) -> None:
        with self._lock:
            text = rehearsal_note(self.number, self.runs)
            handle = self._notes.get(client.client_id)
        if handle is None:
            handle = client.gui.add_markdown(text)
            with self._lock:
                self._notes[client.client_id] = handle
        else:
            handle.content = text

    def _connect(self, client: viser.ClientHandle) -> None:
        if self.number is not None:
            self._note(client)

    def _disconnect(self, client: viser.ClientHandle) -> None:
        with self._lock:
            self._notes.pop(client.client_id, None)


_views: weakref.WeakKeyDictionary[RoverScene, RehearsalView] = weakref.WeakKeyDictionary()
_views_lock = threading.Lock()


def view_of(scene: RoverScene) -> RehearsalView:
    """The rehearsal drawn in ``scene`` (made on first use)."""
    with _views_lock:
        view = _views.get(scene)
        if view is None:
            view = _views[scene] = RehearsalView(scene)
        return view


def show(scenes: Iterable[RoverScene | None], number: int, risk: Mapping[str, Any]) -> None:
    """Draw campaign ``number``'s risk table in each of a rover's scenes (with the truth and
    without: ``Server.scenes`` and ``Server.truth_scenes``); a scene that is off (None, or
    not started) is skipped."""
    for scene in scenes:
        if scene is not None and scene.server is not None:
            view_of(scene).show(number, risk)


def show_stored(
    scenes: Iterable[RoverScene | None], store: Store, rover: str, rehearsal_id: int
) -> int:
    """Draw stored campaign ``rehearsal_id`` of ``rover`` in ``scenes``; the runs drawn.
    ``NotFoundError`` for no such campaign of the rover, ``ConflictError`` for one with no
    risk table yet (queued, running, or stopped before any run finished)."""
    found = get_rehearsal(store, rehearsal_id)
    if found is None or found["rover"] != rover:
        raise NotFoundError(f"no rehearsal {rehearsal_id} of {rover}")
    risk = found["risk"]
    if risk is None:
        raise ConflictError(
            f"rehearsal {rehearsal_id} is {found['state']}: no risk table to draw yet"
        )
    show(scenes, rehearsal_id, risk)
    return int(risk.get("runs") or 0)


def show_latest(scenes: Iterable[RoverScene | None], store: Store, rover: str) -> int | None:
    """Draw ``rover``'s newest finished campaign (``done``) in ``scenes``; its id, or None
    when it has none. What the rehearsal service calls when a campaign finishes, and a
    server's start to draw what was drawn before."""
    done = [s for s in list_rehearsals(store, rover) if s["state"] == "done"]
    if not done:
        return None
    show_stored(scenes, store, rover, int(done[0]["id"]))
    return int(done[0]["id"])
