"""Every route's role: the lowest role that may call it gets through, the role below it is
refused (401 without a token, 403 with too low a role or a bad token) and nothing changes.
A new route fails ``test_every_route_has_a_role_here`` until it is given its row."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.routing import APIRoute, iter_route_contexts
from fastapi.testclient import TestClient
from starlette.routing import WebSocketRoute
from starlette.websockets import WebSocketDisconnect

from server.access.accounts import ROLES
from server.app import ServerConfig, create_app, data_dir_url

BOOTSTRAP = "roles-bootstrap-token"
SEQ = "SEQUENCE roles\nNADIR_UPDATE\n"
TILT_LIMITS = {"warning": 20, "critical": 30}
ADVISED_DRIVE = "DRIVE_STRAIGHT distance_m=1 vo=on"

# (method, path, lowest role, request keyword arguments). Paths name real things so the
# allowed call does its work: sequence 1 exists (made by the fixture), user "victim" too.
ROUTES: list[tuple[str, str, str, dict[str, Any]]] = [
    ("GET", "/api/rovers", "viewer", {}),
    ("GET", "/api/rovers/spirit/state", "viewer", {}),
    ("GET", "/api/schema/downlink", "viewer", {}),
    ("GET", "/api/schema/truth", "viewer", {}),
    ("GET", "/api/schema/ws", "viewer", {}),
    ("GET", "/api/rovers/spirit/queue", "viewer", {}),
    ("GET", "/api/commands", "viewer", {}),
    ("GET", "/api/me", "viewer", {}),
    ("POST", "/api/sequences/validate", "viewer", {"content": SEQ}),
    ("GET", "/api/rovers/spirit/sequences", "viewer", {}),
    ("GET", "/api/sequences/1", "viewer", {}),
    ("GET", "/api/rovers/spirit/sols", "viewer", {}),
    ("GET", "/api/rovers/spirit/sols/0/timeline", "viewer", {}),
    ("GET", "/api/rovers/spirit/sols/0/telemetry.csv", "viewer", {}),
    ("GET", "/api/rovers/spirit/telemetry", "viewer", {}),
    ("GET", "/api/rovers/spirit/events", "viewer", {}),
    ("GET", "/api/rovers/spirit/channels", "viewer", {}),
    ("GET", "/api/rovers/spirit/channels/tilt_accel_deg", "viewer", {}),
    ("GET", "/api/rovers/spirit/scene", "viewer", {}),
    # which rehearsal the shared 3D view draws (none here, or the view is off: 404 once allowed)
    ("POST", "/api/rovers/spirit/scene/rehearsal", "operator", {"json": {"id": 1}}),
    # a rehearsal refused for its runs once allowed (no campaign, no cluster started here)
    ("POST", "/api/rovers/spirit/rehearsals", "operator", {"json": {"runs": 0}}),
    ("GET", "/api/rovers/spirit/rehearsals", "viewer", {}),
    ("GET", "/api/rovers/spirit/rehearsals/1", "viewer", {}),  # none: 404 once allowed
    ("POST", "/api/rovers/spirit/rehearsals/1/cancel", "operator", {}),
    ("GET", "/api/rovers/spirit/rehearsals/1/report", "viewer", {}),
    ("GET", "/api/rovers/spirit/images", "viewer", {}),
    ("GET", "/api/rovers/spirit/images/1", "viewer", {}),  # none taken: 404 once allowed
    ("GET", "/api/rovers/spirit/images/1/left.png", "viewer", {}),
    ("GET", "/api/rovers/spirit/images/1/right.png", "viewer", {}),
    ("GET", "/viser/spirit", "viewer", {}),
    ("GET", "/viser/spirit/index.html", "viewer", {}),
    ("POST", "/api/rovers/spirit/sequences", "operator", {"content": SEQ}),
    ("POST", "/api/rovers/spirit/commands", "operator", {"json": {"command": "NADIR_UPDATE"}}),
    ("POST", "/api/rovers/spirit/vo-advice", "operator", {"json": {"command": ADVISED_DRIVE}}),
    ("POST", "/api/rovers/spirit/clock", "operator", {"json": {"action": "pause"}}),
    ("POST", "/api/rovers/spirit/queue/1/move", "operator", {"json": {"to": 0}}),
    ("DELETE", "/api/sequences/1", "operator", {}),
    ("GET", "/api/rovers/spirit/limits", "viewer", {}),
    ("GET", "/api/rovers/spirit/alarms", "viewer", {}),
    ("PUT", "/api/rovers/spirit/limits/tilt_accel_deg", "operator", {"json": TILT_LIMITS}),
    ("DELETE", "/api/rovers/spirit/limits/tilt_accel_deg", "operator", {}),
    ("POST", "/api/alarms/1/acknowledge", "operator", {}),  # none raised: 404 once allowed
    ("POST", "/api/alarms/1/shelve", "operator", {"json": {"duration_s": 60}}),  # 404 once allowed
    ("POST", "/api/alarms/1/unshelve", "operator", {}),
    ("GET", "/api/rovers/spirit/faults", "conductor", {}),
    ("POST", "/api/rovers/spirit/faults", "conductor", {"json": {"kind": "navcam"}}),
    ("POST", "/api/rovers/spirit/faults/reveal", "conductor", {}),
    ("GET", "/api/rovers/spirit/comm", "viewer", {}),
    ("PUT", "/api/rovers/spirit/comm/plan", "operator", {"json": {"relay_rate_bps": 256000}}),
    ("PUT", "/api/rovers/spirit/comm/mode", "admin", {"json": {"mode": "instant"}}),
    ("GET", "/api/users", "admin", {}),
    ("POST", "/api/users", "admin", {"json": {"name": "newcomer", "role": "viewer"}}),
    ("PATCH", "/api/users/victim", "admin", {"json": {"role": "operator"}}),
    ("POST", "/api/users/victim/tokens", "admin", {"json": {}}),
    ("DELETE", "/api/users/victim/tokens", "admin", {}),
    ("GET", "/api/audit", "admin", {}),
]
WEBSOCKETS = ["/ws/rovers/spirit/telemetry", "/viser/spirit"]
# Open to everyone by design: the page and its files hold no data, and signing in or out
# is how a token is presented (POST /api/session checks it).
OPEN = {("GET", "/"), ("POST", "/api/session"), ("DELETE", "/api/session")}


def _app(tmp: Path, public_read: bool) -> tuple[TestClient, dict[str, str]]:
    config = ServerConfig(
        database_url=data_dir_url(tmp),
        operator_token=BOOTSTRAP,
        public_read=public_read,
        start_clocks=False,  # nothing moves on its own: the state before and after compares
    )
    app = create_app(config)
    accounts = app.state.server.accounts
    tokens = {role: accounts.add_user(f"{role}_user", role).token for role in ROLES}
    accounts.add_user("victim", "viewer")
    return TestClient(app), tokens


def _snapshot(client: TestClient) -> dict[str, Any]:
    """What a refused request must not change (read with the bootstrap admin token)."""
    admin = {"Authorization": f"Bearer {BOOTSTRAP}"}
    server = client.app.state.server  # type: ignore[attr-defined]
    return {
        rover: {
            "sequences": client.get(f"/api/rovers/{rover}/sequences", headers=admin).json(),
            "state": {k: v for k, v in runtime.state().items() if k != "frame"},
            "limits": client.get(f"/api/rovers/{rover}/limits", headers=admin).json(),
        }
        for rover, runtime in server.rovers.items()
    } | {"users": client.get("/api/users", headers=admin).json()}


@pytest.fixture(scope="module", params=[True, False], ids=["public-read", "private"])
def setup(
    request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory
) -> Iterator[tuple[TestClient, dict[str, str], bool]]:
    public_read: bool = request.param
    client, tokens = _app(tmp_path_factory.mktemp("roles"), public_read)
    with client:
        admin = {"Authorization": f"Bearer {BOOTSTRAP}"}
        first = client.post("/api/rovers/spirit/sequences", content=SEQ, headers=admin)
        assert first.status_code == 201 and first.json()["id"] == 1, first.text
        yield client, tokens, public_read


def _below(role: str) -> str | None:
    i = ROLES.index(role)
    return ROLES[i - 1] if i > 0 else None


def test_every_route_has_a_role_here(setup: tuple[TestClient, dict[str, str], bool]) -> None:
    client = setup[0]
    listed = {(m, p) for m, p, _, _ in ROUTES} | OPEN
    templates = {"{rover}": "spirit", "{sequence_id:int}": "1", "{sol}": "0", "{name}": "victim",
                 "{path:path}": "index.html", "{channel}": "tilt_accel_deg",
                 "{alarm_id}": "1", "{image_id}": "1", "{rehearsal_id}": "1"}  # fmt: skip
    missing = []
    # iter_route_contexts opens the included routers (server.api: one per resource)
    for context in iter_route_contexts(client.app.routes):  # type: ignore[attr-defined]
        route = context.original_route
        if isinstance(route, APIRoute) and (
            route.include_in_schema or route.path.startswith("/viser")
        ):
            path = route.path
            for k, v in templates.items():
                path = path.replace(k, v)
            for method in route.methods - {"HEAD"}:
                if (method, path) not in listed and not path.startswith("/docs"):
                    missing.append((method, path))
        elif isinstance(route, WebSocketRoute):
            path = route.path.replace("{rover}", "spirit")
            if path not in WEBSOCKETS:
                missing.append(("WS", path))
    assert not missing, f"routes without a row in ROUTES: {missing}"


@pytest.mark.parametrize(("method", "path", "role", "kwargs"), ROUTES, ids=[
    f"{m} {p}" for m, p, _, _ in ROUTES
])  # fmt: skip
def test_the_lowest_role_may_and_the_one_below_is_refused(
    setup: tuple[TestClient, dict[str, str], bool],
    method: str,
    path: str,
    role: str,
    kwargs: dict[str, Any],
) -> None:
    client, tokens, public_read = setup
    before = _snapshot(client)
    below = _below(role)
    refusals: list[tuple[dict[str, str], int]] = [
        ({"Authorization": "Bearer not-a-real-token"}, 403),
    ]
    if below is not None:
        refusals.append(({"Authorization": f"Bearer {tokens[below]}"}, 403))
    if role != "viewer" or not public_read:
        refusals.append(({}, 401))
    for headers, status in refusals:
        answer = client.request(method, path, headers=headers, **kwargs)
        assert answer.status_code == status, (headers, answer.text)
        assert _snapshot(client) == before, f"a refused {method} {path} changed the state"
    allowed = client.request(
        method, path, headers={"Authorization": f"Bearer {tokens[role]}"}, **kwargs
    )
    assert allowed.status_code not in (401, 403), allowed.text
    if role == "viewer" and public_read:
        assert client.request(method, path, **kwargs).status_code not in (401, 403)


@pytest.mark.parametrize("path", WEBSOCKETS)
def test_websockets_need_a_viewer_token_when_reading_is_private(
    setup: tuple[TestClient, dict[str, str], bool], path: str
) -> None:
    client, tokens, public_read = setup
    bad = {"Authorization": "Bearer not-a-real-token"}
    with pytest.raises(WebSocketDisconnect) as refused, client.websocket_connect(path, headers=bad):
        pass
    assert refused.value.code == 4403
    if not public_read:
        with pytest.raises(WebSocketDisconnect) as refused, client.websocket_connect(path):
            pass
        assert refused.value.code == 4401
    if path.startswith("/ws/"):  # the 3D view is off in this app: only telemetry connects
        viewer = {"Authorization": f"Bearer {tokens['viewer']}"}
        with client.websocket_connect(path, headers=viewer):
            pass


def test_a_browser_signs_in_with_a_cookie_that_counts_for_reading_only(
    setup: tuple[TestClient, dict[str, str], bool],
) -> None:
    client, tokens, public_read = setup
    assert client.post("/api/session", json={"token": "wrong"}).status_code == 403
    signed = client.post("/api/session", json={"token": tokens["operator"]})
    assert signed.status_code == 200 and signed.json()["role"] == "operator"
    assert "httponly" in signed.headers["set-cookie"].lower()
    try:
        assert client.get("/api/me").json()["name"] == "operator_user"
        with client.websocket_connect("/ws/rovers/spirit/telemetry"):
            pass
        # the cookie alone never changes anything: a page on another site cannot act with it
        assert client.post("/api/rovers/spirit/clock", json={"action": "pause"}).status_code == 401
    finally:
        client.delete("/api/session")
    me = client.get("/api/me")
    assert (me.status_code, me.json().get("name")) == (
        (200, "anonymous") if public_read else (401, None)
    )


@pytest.mark.parametrize("path", WEBSOCKETS)
def test_a_page_of_another_origin_cannot_open_a_websocket(
    setup: tuple[TestClient, dict[str, str], bool], path: str
) -> None:
    """With the sign-in cookie, a page of another site could read in the user's name:
    its Origin is refused before the token is even looked at."""
    client, tokens, _ = setup
    viewer = {"Authorization": f"Bearer {tokens['viewer']}", "Origin": "http://evil.example"}
    with (
        pytest.raises(WebSocketDisconnect) as refused,
        client.websocket_connect(path, headers=viewer),
    ):
        pass
    assert refused.value.code == 4403
