"""viser's page and WebSocket under ``/viser/{rover}/``, on the console's own origin.

Each rover's 3D view is a ``viser.ViserServer`` on a loopback port (``server.scene3d``).
Its client is one self-contained page that opens a WebSocket back to its own URL (less the
trailing slash), so serving the page at ``/viser/{rover}/`` makes the browser connect to
``/viser/{rover}``, which this module relays to viser byte for byte in both directions.
One origin means one port for operators to open, through any reverse proxy, and the
console can embed the view without cross-origin rules.
"""

from __future__ import annotations

import asyncio
import contextlib
import urllib.error
import urllib.request
from dataclasses import dataclass

from starlette.websockets import WebSocket, WebSocketDisconnect
from websockets.asyncio.client import connect
from websockets.exceptions import ConnectionClosed

FETCH_TIMEOUT_S = 10.0


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

        async def up() -> None:
            while True:
                message = await websocket.receive()
                if message["type"] == "websocket.disconnect":
                    return
                if message.get("bytes") is not None:
                    await upstream.send(message["bytes"])
                elif message.get("text") is not None:
                    await upstream.send(message["text"])

        tasks = [asyncio.create_task(down()), asyncio.create_task(up())]
        try:
            await asyncio.wait(tasks, return_when=asyncio.FIRST_COMPLETED)
        finally:
            for task in tasks:
                task.cancel()
            # Either side going away ends both directions; that is the normal end.
            await asyncio.gather(*tasks, return_exceptions=True)
        # The browser may be gone already: closing then raises, and there is nothing to do.
        with contextlib.suppress(RuntimeError, WebSocketDisconnect):
            await websocket.close()
