"""The same-origin check of WebSocket routes (``server.api.origin``), alone and on the relayed
viser socket: a browser page of another site is refused before the socket is accepted; a
client without ``Origin`` (a script) is not."""

from __future__ import annotations

from pathlib import Path

import pytest
import viser
from fastapi.testclient import TestClient
from starlette.websockets import WebSocketDisconnect

from server.api.origin import origin_allowed
from server.app import ServerConfig, create_app, data_dir_url

HOST = "rover.example:8000"


@pytest.mark.parametrize(
    "origin,scheme",
    [
        ("http://rover.example:8000", "ws"),
        ("HTTP://Rover.Example:8000", "ws"),  # scheme and host are case-insensitive
        ("https://rover.example:8000", "wss"),
        ("http://rover.example:8000", "http"),
    ],
)
def test_the_page_s_own_origin_is_allowed(origin: str, scheme: str) -> None:
    assert origin_allowed({"host": HOST, "origin": origin}, scheme)


def test_default_ports_count_as_given() -> None:
    assert origin_allowed({"host": "rover.example", "origin": "http://rover.example:80"}, "ws")
    assert origin_allowed({"host": "rover.example:443", "origin": "https://rover.example"}, "wss")
    assert not origin_allowed({"host": "rover.example", "origin": "http://rover.example:443"}, "ws")


def test_ipv6_hosts_compare_as_hosts() -> None:
    assert origin_allowed({"host": "[::1]:8000", "origin": "http://[::1]:8000"}, "ws")
    assert not origin_allowed({"host": "[::1]:8000", "origin": "http://[::2]:8000"}, "ws")


@pytest.mark.parametrize(
    "origin,scheme",
    [
        ("http://evil.example:8000", "ws"),  # another host
        ("http://rover.example.evil.example:8000", "ws"),
        ("http://rover.example:8001", "ws"),  # another port
        ("http://rover.example", "ws"),
        ("https://rover.example:8000", "ws"),  # another scheme
        ("http://rover.example:8000", "wss"),
        ("ws://rover.example:8000", "ws"),  # not a page's scheme
        ("file://rover.example:8000", "ws"),
        ("http://rover.example:8000", "ftp"),  # not a WebSocket's or a page's
    ],
)
def test_another_origin_is_refused(origin: str, scheme: str) -> None:
    assert not origin_allowed({"host": HOST, "origin": origin}, scheme)


@pytest.mark.parametrize(
    "origin",
    [
        "null",  # a sandboxed frame or a file:// page
        "",
        "rover.example:8000",
        "http://",
        "http://rover.example:8000/",
        "http://rover.example:8000/path",
        "http://rover.example:8000?q=1",
        "http://user@rover.example:8000",
        "http://rover.example:port",
        "http://rover.example:99999",
        "http://[::1",
        "http://rover example:8000",
    ],
)
def test_a_malformed_origin_is_refused(origin: str) -> None:
    assert not origin_allowed({"host": HOST, "origin": origin}, "ws")


def test_no_origin_is_a_script_and_is_allowed_but_an_origin_needs_a_host() -> None:
    assert origin_allowed({"host": HOST}, "ws")
    assert origin_allowed({}, "ws")
    assert not origin_allowed({"origin": "http://rover.example:8000"}, "ws")
    assert not origin_allowed({"host": "", "origin": "http://rover.example:8000"}, "ws")
    assert not origin_allowed({"host": "a:b:c", "origin": "http://rover.example:8000"}, "ws")


def test_the_viser_socket_refuses_another_site_s_page(tmp_path: Path) -> None:
    config = ServerConfig(database_url=data_dir_url(tmp_path), viewer_3d=True, start_clocks=False)
    protocol = f"viser-v{viser.__version__}"
    with TestClient(create_app(config)) as client:  # its Host is "testserver"
        for origin in ("http://evil.example", "http://testserver:8080", "https://testserver"):
            with (
                pytest.raises(WebSocketDisconnect) as refused,
                client.websocket_connect(
                    "/viser/spirit", subprotocols=[protocol], headers={"origin": origin}
                ),
            ):
                pass
            assert refused.value.code == 4403, origin
        for headers in ({"origin": "http://testserver"}, {}):
            with client.websocket_connect(
                "/viser/spirit", subprotocols=[protocol], headers=headers
            ) as ws:
                assert ws.accepted_subprotocol == protocol
                assert len(ws.receive_bytes()) > 0  # viser's scene
