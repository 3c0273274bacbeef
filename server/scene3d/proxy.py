"""viser's page and WebSocket under ``/viser/{rover}/``, on the console's own origin.

Each rover's 3D view is a ``viser.ViserServer`` on a loopback port (``server.scene3d``).
Its client is one self-contained page that opens a WebSocket back to its own URL (less the
trailing slash), so serving the page at ``/viser/{rover}/`` makes the browser connect to
``/viser/{rover}``, which this module relays to viser byte for byte in both directions.
One origin means one port for operators to open, through any reverse proxy, and the
console can embed the view without cross-origin rules.

Upstream, only what a viewer of this view sends passes (``refusal``): its camera, and a
new value for one of its inputs. viser applies any property a ``GuiUpdateMessage`` names
to the element, its callbacks and its ``removed`` flag included, so one message could
strip the server's callback for good; other messages would have viser open a public share
tunnel (``ShareUrlRequest``) or broadcast to every viewer. viser's own port is on the
loopback interface: this relay is the one way in from outside.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import urllib.error
import urllib.request
from dataclasses import dataclass
from typing import Any

import msgspec  # viser's own dependency: its client sends msgpack
from starlette.websockets import WebSocket, WebSocketDisconnect
from websockets.asyncio.client import connect
from websockets.exceptions import ConnectionClosed

FETCH_TIMEOUT_S = 10.0
MAX_VIEWER_MESSAGE_BYTES = 64 * 1024  # a camera report is ~200 bytes
CAMERA_FIELDS = frozenset(
    {"type", "wxyz", "position", "fov", "near", "far", "image_height", "image_width",
     "look_at", "up_direction"}
)  # fmt: skip
log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Fetched:
    status: int
    content_type: str
    body: bytes


def fetch(port: int, path: str) -> Fetched:
    """GET ``path`` from the viser server on ``port`` (blocking: run it in a thread)."""
    url = f"http://127.0.0.1:{port}/{path.lstrip('/')}"
    try:
        with urllib.request.urlopen(url, timeout=FETCH_TIMEOUT_S) as response:
            kind = response.headers.get("Content-Type", "application/octet-stream")
            return Fetched(response.status, kind, response.read())
    except urllib.error.HTTPError as error:
        return Fetched(error.code, "text/plain", error.read())


def _plain_value(value: Any) -> bool:
    """A value an input of this view may take: a number or a flag (a checkbox, a slider);
    whether it is a sensible one is for the input's callback to say."""
    return isinstance(value, (bool, int, float))


def refusal(data: bytes | str) -> str | None:
    """Why a message from a viewer must not reach viser, or None if it may: a camera
    report (``ViewerCameraMessage``) or a ``GuiUpdateMessage`` that sets ``value`` alone
    to a plain value (module docstring). The callbacks check the value itself.

    >>> refusal(msgspec.msgpack.encode({"type": "GuiUpdateMessage", "uuid": "u",
    ...                                 "updates": {"value": 1.5}})) is None
    True
    >>> refusal(msgspec.msgpack.encode({"type": "GuiUpdateMessage", "uuid": "u",
    ...                                 "updates": {"update_cb": []}}))
    'a GuiUpdateMessage may set value only, not update_cb'
    """
    if isinstance(data, str):
        return "a text frame (viser speaks binary msgpack)"
    if len(data) > MAX_VIEWER_MESSAGE_BYTES:
        return f"{len(data)} bytes, more than a viewer sends"
    try:
        message = msgspec.msgpack.decode(data)
    except msgspec.DecodeError:
        return "not msgpack"
    if not isinstance(message, dict):
        return "not a message"
    kind = message.get("type")
    if kind == "ViewerCameraMessage":
        extra = set(message) - CAMERA_FIELDS
        return f"a ViewerCameraMessage with {sorted(map(str, extra))}" if extra else None
    if kind != "GuiUpdateMessage":
        return f"{str(kind)[:40]!r} is not a message this view accepts"
    updates = message.get("updates")
    if set(message) != {"type", "uuid", "updates"} or not isinstance(message["uuid"], str):
        return "a GuiUpdateMessage with fields other than uuid and updates"
    if not isinstance(updates, dict) or set(updates) != {"value"}:
        names = (
            ", ".join(sorted(str(k)[:40] for k in updates if k != "value"))
            if isinstance(updates, dict)
            else "nothing"
        )
        return f"a GuiUpdateMessage may set value only, not {names}"
    if not _plain_value(updates["value"]):
        return "a GuiUpdateMessage whose value is not a number or a flag"
    return None


async def relay(websocket: WebSocket, port: int) -> None:
    """Relay ``websocket`` to viser's WebSocket on ``port`` until either side closes.

    The client's subprotocol (viser's version tag) is passed on and the one viser picks is
    the one accepted, so a client of another viser version is refused as viser would.
    """
    protocols = list(websocket.scope.get("subprotocols", []))
    try:
        upstream = await connect(
            f"ws://127.0.0.1:{port}",
            subprotocols=protocols,
            max_size=None,
            compression=None,
        )
    except (OSError, ConnectionClosed) as error:
        await websocket.close(code=1011, reason=f"3D view unavailable: {error}")
        return
    async with upstream:
        await websocket.accept(subprotocol=upstream.subprotocol)

        async def down() -> None:
            async for message in upstream:
                if isinstance(message, bytes):
                    await websocket.send_bytes(message)
                else:
                    await websocket.send_text(message)

        refused = 0

        async def up() -> None:
            nonlocal refused
            while True:
                message = await websocket.receive()
                if message["type"] == "websocket.disconnect":
                    return
                data = message.get("bytes")
                if data is None:
                    data = message.get("text") or ""
                why = refusal(data)
                if why is None:
                    await upstream.send(data)
                    continue
                refused += 1
                if refused == 1:  # one line per viewer: a hostile one must not flood the log
                    log.warning("3D view: a viewer's message dropped: %s", why)

        tasks = [asyncio.create_task(down()), asyncio.create_task(up())]
        try:
            await asyncio.wait(tasks, return_when=asyncio.FIRST_COMPLETED)
        finally:
            for task in tasks:
                task.cancel()
            # Either side going away ends both directions; that is the normal end.
            await asyncio.gather(*tasks, return_exceptions=True)
        if refused > 1:
            log.warning("3D view: %d messages of that viewer dropped in all", refused)
        # The browser may be gone already: closing then raises, and there is nothing to do.
        with contextlib.suppress(RuntimeError, WebSocketDisconnect):
            await websocket.close()
