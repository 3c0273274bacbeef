"""A viser viewer without a browser, for tests: a WebSocket speaking viser's wire format
(``bench.view3d`` describes it) that keeps the GUI state the server sent it, by
element label, and sends whatever message a test crafts."""

from __future__ import annotations

import contextlib
import threading
import time
from typing import Any

import msgspec
import viser
import zstandard
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import ClientConnection, connect
from websockets.typing import Subprotocol

from bench.view3d import CAMERA_REPORT

PROTOCOL = Subprotocol(f"viser-v{viser.__version__}")
HEADER_BYTES = 16


def decode_window(data: bytes) -> list[dict[str, Any]]:
    """The messages of one window from viser: two little-endian uint64 lengths, the
    zstd-compressed msgpack ``{"messages", ...}``, then binary buffers (not needed here)."""
    inner_len = int.from_bytes(data[:8], "little")
    packed_len = int.from_bytes(data[8:HEADER_BYTES], "little")
    packed = data[HEADER_BYTES : HEADER_BYTES + packed_len]
    inner = zstandard.ZstdDecompressor().decompress(packed, max_output_size=inner_len)
    messages: list[dict[str, Any]] = msgspec.msgpack.decode(inner)["messages"]
    return messages


def wait_for(predicate: Any, timeout_s: float = 30.0) -> Any:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(0.02)
    raise AssertionError("timed out")


class WireViewer:
    """Connects to ``url`` (viser's port or the console's relay), keeps every GUI element
    it is told of (``uuid -> {"label", "value", "markdown", ...}``) up to date."""

    def __init__(self, url: str, headers: dict[str, str] | None = None) -> None:
        self.gui: dict[str, dict[str, Any]] = {}
        self.nodes: dict[tuple[str, str], dict[str, Any]] = {}  # (owner, name): its state
        self.messages: list[dict[str, Any]] = []  # every message received, decoded
        self._lock = threading.Lock()
        self._ws: ClientConnection = connect(
            url,
            subprotocols=[PROTOCOL],
            compression=None,
            max_size=None,
            proxy=None,
            open_timeout=30.0,
            additional_headers=headers,
        )
        self._thread = threading.Thread(target=self._drain, daemon=True)
        self._thread.start()
        # viser counts a client as connected once it has reported its camera, as a
        # browser does at once.
        self.send(CAMERA_REPORT)

    def _drain(self) -> None:
        with contextlib.suppress(ConnectionClosed):
            for data in self._ws:
                assert isinstance(data, bytes)
                for m in decode_window(data):
                    self._keep(m)

    def _keep(self, m: dict[str, Any]) -> None:
        with self._lock:
            self.messages.append(m)
            if m["type"].startswith("Gui") and "props" in m and "uuid" in m:
                state = dict(m["props"])
                if "value" in m:
                    state["value"] = m["value"]
                self.gui[m["uuid"]] = state
            elif m["type"] == "GuiUpdateMessage" and m["uuid"] in self.gui:
                self.gui[m["uuid"]].update(m["updates"])
            elif m["type"] == "GuiRemoveMessage":
                self.gui.pop(m["uuid"], None)
            elif m["type"] == "SetPositionMessage":
                self.nodes.setdefault((m["owner"], m["name"]), {})["position"] = m["position"]
            elif m["type"] == "RemoveSceneNodeMessage":
                name, owner = m["name"], m.get("owner", "")
                for key in [k for k in self.nodes if k[0] == owner]:
                    if key[1] == name or key[1].startswith(name + "/"):
                        del self.nodes[key]
            elif "name" in m and "props" in m:  # a scene node created (or re-created)
                self.nodes[(m.get("owner", ""), m["name"])] = {"position": (0.0, 0.0, 0.0)}

    @property
    def connected(self) -> bool:
        return self._thread.is_alive()

    def uuid(self, label: str) -> str:
        """The uuid of the element labelled ``label`` (waits for it)."""

        def find() -> str | None:
            with self._lock:
                return next((u for u, s in self.gui.items() if s.get("label") == label), None)

        found: str = wait_for(find)
        return found

    def value(self, label: str) -> Any:
        uuid = self.uuid(label)
        with self._lock:
            return self.gui[uuid]["value"]

    def status(self) -> str:
        """The status markdown (the one markdown element of the view)."""
        with self._lock:
            texts = [s["_markdown"] for s in self.gui.values() if "_markdown" in s]
        return texts[0] if texts else ""

    def owners(self, name: str) -> set[str]:
        """The scopes that have a node ``name``: "" is the shared scene, anything else
        one viewer's own."""
        with self._lock:
            return {owner for owner, n in self.nodes if n == name}

    def position(self, name: str) -> tuple[float, float, float] | None:
        """Where the node ``name`` this viewer sees is: its own variant shadows the shared
        one (viser's display rule)."""
        with self._lock:
            variants = {owner: s for (owner, n), s in self.nodes.items() if n == name}
        if not variants:
            return None
        own = [owner for owner in variants if owner != ""]
        return tuple(variants[own[0] if own else ""]["position"])  # type: ignore[return-value]

    def send(self, message: dict[str, Any]) -> None:
        self._ws.send(msgspec.msgpack.encode(message))

    def send_raw(self, data: bytes | str) -> None:
        self._ws.send(data)

    def set_value(self, label: str, value: Any) -> None:
        """What a browser sends when the user changes an input."""
        self.send(
            {"type": "GuiUpdateMessage", "uuid": self.uuid(label), "updates": {"value": value}}
        )

    def close(self) -> None:
        self._ws.close()
        self._thread.join(timeout=10.0)
