"""The API against hostile and careless clients (issue 13, defects 1, 2, 4, 5, 6 and 10): out
of range path integers, JSON too deep or with huge numbers, bodies that never end, uploads
that take long to validate, many validations at once, and the OpenAPI contract (the token
before the body, one 422 shape, strict types, declared bodies and errors).

No wall-clock asserts: "the event loop stays free" is proven by another request answered
while a validation is held on a ``threading.Event`` (in the threadpool path,
``validation_processes=0``: an event does not cross processes;
tests/server/validation/test_validation_pool.py covers the process path), and "the limit is
enforced while streaming" by counting the bytes the server pulled."""

from __future__ import annotations

import asyncio
import json
import threading
from collections.abc import AsyncIterator, Callable, Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest
from fastapi.testclient import TestClient

import server.validation.pool as pool_module
from bench.fuzz import live_server
from server.api.deps import MAX_ID, MAX_SOL
from server.app import ServerConfig, create_app, data_dir_url
from server.validation.uploads import MAX_JSON_DEPTH

TOKEN = "hardening-token"
AUTH = {"Authorization": f"Bearer {TOKEN}"}
JSON = {"Content-Type": "application/json"}
LIMIT = 100_000
GOOD = "SEQUENCE hardening\nNADIR_UPDATE\n"
WAIT_S = 30.0  # how long a helper thread may take before the test calls it stuck
IN_THREADS = {"validation_processes": 0}  # a validation held on an Event: in this process


def _app(data_dir: Path, **overrides: Any) -> Any:
    url = data_dir_url(data_dir)
    config = ServerConfig(
        database_url=url, operator_token=TOKEN, max_upload_bytes=LIMIT, start_clocks=False
    )
    for key, value in overrides.items():
        setattr(config, key, value)
    return create_app(config)


@pytest.fixture(scope="module")
def client(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    app = _app(tmp_path_factory.mktemp("hardening"))
    with TestClient(app, raise_server_exceptions=False) as c:
        yield c


# ---- defect 1: integers in paths --------------------------------------------------------

HUGE = "9223372036854775808"  # 2^63: SQLite's and PostgreSQL's integers end before it


@pytest.mark.parametrize(
    ("method", "path"),
    [
        ("GET", f"/api/sequences/{HUGE}"),
        ("GET", f"/api/sequences/{MAX_ID + 1}"),
        ("GET", "/api/sequences/-1"),
        ("GET", "/api/sequences/0"),
        ("DELETE", f"/api/sequences/{HUGE}"),
        ("DELETE", "/api/sequences/-1"),
        ("GET", f"/api/rovers/spirit/sols/{HUGE}/timeline"),
        ("GET", f"/api/rovers/spirit/sols/{MAX_SOL + 1}/timeline"),
        ("GET", "/api/rovers/spirit/sols/-1/timeline"),
        ("GET", f"/api/rovers/spirit/sols/{HUGE}/telemetry.csv"),
        ("GET", "/api/rovers/spirit/sols/-3/telemetry.csv"),
    ],
)
def test_out_of_range_integers_in_paths_are_a_4xx(
    client: TestClient, method: str, path: str
) -> None:
    r = client.request(method, path, headers=AUTH)
    assert r.status_code in (404, 422), r.text
    if r.status_code == 422:
        assert isinstance(r.json()["detail"], list) and "than or equal" in r.text


# ---- defect 2: JSON the parser cannot or must not take ---------------------------------

DEEP = b"[" * 100_000
BIG_INT = b'{"steps": [], "name": ' + b"1" * 5000 + b"}"
NAN = b'{"command": "WAIT", "args": {"duration_s": NaN}}'
OVERFLOW = b'{"command": "WAIT", "args": {"duration_s": 1e999}}'
JSON_ROUTES = [
    "/api/sequences/validate",
    "/api/rovers/spirit/sequences",
    "/api/rovers/spirit/commands",
    "/api/rovers/spirit/clock",
]


@pytest.mark.parametrize("path", JSON_ROUTES)
@pytest.mark.parametrize(
    ("body", "named"),
    [(DEEP, "nested"), (BIG_INT, "4300 digits"), (NAN, "NaN"), (OVERFLOW, "1e999")],
)
def test_hostile_json_is_a_422_naming_the_problem(
    client: TestClient, path: str, body: bytes, named: str
) -> None:
    r = client.post(path, content=body, headers={**JSON, **AUTH})
    assert r.status_code == 422, r.text
    detail = r.json()["detail"]
    assert isinstance(detail, list) and named in detail[0]["msg"]


def test_json_as_deep_as_allowed_is_read(client: TestClient) -> None:
    nested = b"[" * (MAX_JSON_DEPTH - 1) + b"]" * (MAX_JSON_DEPTH - 1)
    r = client.post("/api/sequences/validate", content=b'{"steps": %s}' % nested, headers=JSON)
    assert r.status_code == 200 and r.json()["valid"] is False  # read, then refused as a sequence


# ---- defect 10: the contract ------------------------------------------------------------


@pytest.mark.parametrize(
    "path",
    ["/api/rovers/spirit/sequences", "/api/rovers/spirit/commands", "/api/rovers/spirit/clock"],
)
def test_the_token_is_checked_before_the_body_is_read(client: TestClient, path: str) -> None:
    assert client.post(path, content=b"{not json", headers=JSON).status_code == 401
    assert (
        client.post(path, content=DEEP, headers={**JSON, "X-Operator-Token": "x"}).status_code
        == 403
    )


def test_a_boolean_is_not_a_speed(client: TestClient) -> None:
    before = client.get("/api/rovers/spirit/state").json()["clock"]
    r = client.post("/api/rovers/spirit/clock", json={"speed": True}, headers=AUTH)
    assert r.status_code == 422 and "speed" in r.text
    assert client.get("/api/rovers/spirit/state").json()["clock"] == before
    r = client.post("/api/rovers/spirit/commands", json={"command": 1, "args": {}}, headers=AUTH)
    assert r.status_code == 422


def test_get_on_validate_is_405(client: TestClient) -> None:
    assert client.get("/api/sequences/validate").status_code == 405


@pytest.mark.parametrize(
    ("method", "path", "kwargs"),
    [
        ("POST", "/api/rovers/spirit/clock", {"json": {"speed": 0.5}}),
        ("POST", "/api/rovers/spirit/commands", {"json": {"command": "FLY_AWAY"}}),
        (
            "POST",
            "/api/rovers/spirit/commands",
            {"json": {"command": "DRIVE_STRAIGHT", "args": {"distance_m": 1e6}}},
        ),
        ("GET", "/api/rovers/spirit/telemetry?from=10&to=5", {}),
        ("POST", "/api/sequences/validate", {"content": b"\xff\xfe", "headers": {}}),
        ("POST", "/api/sequences/validate", {"content": b"{bad", "headers": JSON}),
        ("POST", "/api/sequences/validate", {"content": b"17", "headers": JSON}),
        ("POST", "/api/sequences/validate", {"files": {"not_file": ("a.seq", GOOD.encode())}}),
    ],
)
def test_every_422_detail_is_a_list_of_problems(
    client: TestClient, method: str, path: str, kwargs: dict[str, Any]
) -> None:
    r = client.request(method, path, **{"headers": AUTH, **kwargs})
    assert r.status_code == 422, r.text
    detail = r.json()["detail"]
    assert isinstance(detail, list) and detail
    assert all({"loc", "msg", "type"} <= set(d) for d in detail)


def test_the_console_reads_a_refused_command_from_the_list(client: TestClient) -> None:
    body = {"command": "DRIVE_ARC", "args": {"radius_m": 0.1, "angle_deg": 10}}
    detail = client.post("/api/rovers/spirit/commands", json=body, headers=AUTH).json()["detail"]
    assert any("args.radius_m:" in d["msg"] for d in detail)


def test_the_openapi_declares_bodies_security_and_errors(client: TestClient) -> None:
    spec = client.get("/openapi.json").json()
    paths = spec["paths"]
    for path in ("/api/rovers/{rover}/sequences", "/api/sequences/validate"):
        content = paths[path]["post"]["requestBody"]["content"]
        assert set(content) == {"text/plain", "application/json", "multipart/form-data"}
        file = content["multipart/form-data"]["schema"]["properties"]["file"]
        assert file == {"type": "string", "format": "binary"}
    codes = {
        ("post", "/api/rovers/{rover}/sequences"): {
            "201",
            "401",
            "403",
            "404",
            "413",
            "422",
            "429",
        },
        # a wrong token is refused anywhere, and reading may need one (--public-read off)
        ("post", "/api/sequences/validate"): {"200", "401", "403", "404", "413", "422", "429"},
        ("delete", "/api/sequences/{sequence_id}"): {"200", "401", "403", "404", "409", "422"},
        ("post", "/api/rovers/{rover}/commands"): {"201", "401", "403", "404", "413", "422"},
        ("post", "/api/rovers/{rover}/clock"): {"200", "401", "403", "404", "413", "422"},
        ("get", "/api/rovers/{rover}/sols/{sol}/timeline"): {"200", "401", "403", "404", "422"},
    }
    for (method, path), expected in codes.items():
        assert set(paths[path][method]["responses"]) == expected, path
    assert (
        paths["/api/sequences/{sequence_id}"]["get"]["parameters"][0]["schema"]["maximum"] == MAX_ID
    )
    schemes = spec["components"]["securitySchemes"]
    assert {s["type"] for s in schemes.values()} == {"http", "apiKey"}
    assert paths["/api/rovers/{rover}/clock"]["post"]["security"]
    # reading is public on this server: a viewer route's token is optional ({} first)
    assert paths["/api/sequences/validate"]["post"]["security"][0] == {}
    assert {} not in paths["/api/rovers/{rover}/clock"]["post"]["security"]


# ---- defects 4 and 5: validation off the event loop, and bounded per client ----------------


class Held:
    """Makes a function block (on a ``threading.Event``) when its input holds a marker."""

    def __init__(self, real: Callable[..., Any], marker: str) -> None:
        self.real, self.marker = real, marker
        self.entered = threading.Semaphore(0)
        self.release = threading.Event()

    def __call__(self, source: Any, *args: Any, **kwargs: Any) -> Any:
        seen = source if isinstance(source, (str, bytes, bytearray)) else json.dumps(source)
        if self.marker.encode() in (seen.encode() if isinstance(seen, str) else seen):
            self.entered.release()
            self.release.wait(WAIT_S)
        return self.real(source, *args, **kwargs)

    def wait_entered(self, n: int = 1) -> None:
        for _ in range(n):
            assert self.entered.acquire(timeout=WAIT_S), "the upload never reached the hold"


def _in_thread(call: Callable[[], Any]) -> tuple[threading.Thread, list[Any]]:
    out: list[Any] = []
    thread = threading.Thread(target=lambda: out.append(call()), daemon=True)
    thread.start()
    return thread, out


def _http(base_url: str, source: str = "127.0.0.1") -> httpx.Client:
    """A client of the live server from ``source`` (any 127.x.y.z is this machine), that
    gives up after ``WAIT_S``: a request the server does not answer fails the test."""
    transport = httpx.HTTPTransport(local_address=source)
    return httpx.Client(base_url=base_url, transport=transport, timeout=WAIT_S)


@pytest.mark.parametrize("held", ["validate", "json"])
def test_other_requests_are_answered_while_an_upload_is_checked(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path, held: str
) -> None:
    """Held in validation, or in the JSON parsing of the upload (which ran on the event
    loop before: every other request waited)."""
    marker = "held_upload"
    if held == "validate":
        hold = Held(pool_module.validate, marker)
        monkeypatch.setattr(pool_module, "validate", hold)
    else:
        hold = Held(json.loads, marker)
        monkeypatch.setattr(json, "loads", hold)
    with live_server(tmp_path, TOKEN, **IN_THREADS) as (base_url, _), _http(base_url) as c:
        body = {"text": f"SEQUENCE {marker}\nNADIR_UPDATE\n"}
        upload, result = _in_thread(
            lambda: c.post("/api/rovers/spirit/sequences", json=body, headers=AUTH)
        )
        try:
            hold.wait_entered()
            assert c.get("/api/rovers").status_code == 200  # a timeout if the loop is held
            assert upload.is_alive()  # still held
        finally:
            hold.release.set()
        upload.join(WAIT_S)
        assert result[0].status_code == 201, result[0].text


def test_a_client_gets_429_past_its_concurrent_validations(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    marker = "held_validation"
    hold = Held(pool_module.validate, marker)
    monkeypatch.setattr(pool_module, "validate", hold)
    text = f"SEQUENCE {marker}\nNADIR_UPDATE\n"
    with (
        live_server(tmp_path, TOKEN, max_concurrent_validations=2, **IN_THREADS) as (base_url, _),
        _http(base_url) as c,
        _http(base_url, "127.0.0.2") as other,
    ):
        first = [
            _in_thread(lambda: c.post("/api/sequences/validate", content=text)),
            _in_thread(lambda: c.post("/api/rovers/spirit/sequences", content=text, headers=AUTH)),
        ]
        try:
            hold.wait_entered(2)
            refused = c.post("/api/sequences/validate", content=GOOD)
            assert refused.status_code == 429
            assert refused.headers["Retry-After"] == "1"
            assert "client address" in refused.json()["detail"] and "at most 2" in refused.text
            assert other.post("/api/sequences/validate", content=GOOD).json()["valid"]
        finally:
            hold.release.set()
        for thread, out in first:
            thread.join(WAIT_S)
            assert out[0].status_code in (200, 201)
        assert c.post("/api/sequences/validate", content=GOOD).status_code == 200  # slots freed


def test_one_token_from_many_addresses_gets_429(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    marker = "held_token"
    hold = Held(pool_module.validate, marker)
    monkeypatch.setattr(pool_module, "validate", hold)
    with (
        live_server(tmp_path, TOKEN, max_concurrent_validations=1, **IN_THREADS) as (base_url, _),
        _http(base_url) as c,
        _http(base_url, "127.0.0.3") as other,
    ):
        text = f"SEQUENCE {marker}\n"
        thread, out = _in_thread(
            lambda: c.post("/api/rovers/spirit/sequences", content=text, headers=AUTH)
        )
        try:
            hold.wait_entered()
            r = other.post("/api/rovers/spirit/sequences", content=GOOD, headers=AUTH)
            assert r.status_code == 429 and "token" in r.json()["detail"]
            assert other.post("/api/sequences/validate", content=GOOD).status_code == 200
        finally:
            hold.release.set()
        thread.join(WAIT_S)
        assert out[0].status_code == 422  # no steps: rejected, and stored as such


# ---- defect 6: the size limit while streaming ------------------------------------------

CHUNK = 10_000


async def _chunked_post(
    app: Any, path: str, headers: dict[str, str], first: bytes
) -> tuple[int, int]:
    """POST a chunked body (no Content-Length) of ``first`` then up to 3 MB of filler;
    the status and how many bytes the server pulled."""
    pulled = 0

    async def body() -> AsyncIterator[bytes]:
        nonlocal pulled
        for chunk in [first] + [b"# filler " * (CHUNK // 9)] * (3_000_000 // CHUNK):
            pulled += len(chunk)
            yield chunk

    transport = httpx.ASGITransport(app=app)
    async with httpx.AsyncClient(transport=transport, base_url="http://test") as client:
        r = await client.post(path, content=body(), headers=headers)
    return r.status_code, pulled


@pytest.mark.parametrize(
    ("path", "content_type", "first"),
    [
        ("/api/sequences/validate", "text/plain", b"SEQUENCE s\n"),
        ("/api/rovers/spirit/sequences", "application/json", b'{"text": "'),
        ("/api/rovers/spirit/commands", "application/json", b'{"command": "'),
        (
            "/api/sequences/validate",
            "multipart/form-data; boundary=xyz",
            b'--xyz\r\nContent-Disposition: form-data; name="file"; filename="a.seq"\r\n\r\n',
        ),
    ],
)
def test_a_chunked_body_is_refused_after_the_limit(
    tmp_path: Path, path: str, content_type: str, first: bytes
) -> None:
    headers = {"Content-Type": content_type, **AUTH}
    status, pulled = asyncio.run(_chunked_post(_app(tmp_path), path, headers, first))
    assert status == 413
    assert pulled <= LIMIT + CHUNK


def test_a_405_allows_every_method_of_the_path(client: TestClient) -> None:
    r = client.request("OPTIONS", "/api/rovers/spirit/sequences")
    assert r.status_code == 405 and set(r.headers["Allow"].split(", ")) >= {"GET", "POST"}
    r = client.put("/api/sequences/1")
    assert r.status_code == 405 and set(r.headers["Allow"].split(", ")) >= {"GET", "DELETE"}


@pytest.mark.parametrize("body", [{"text": 5}, {"text": None}, {"sequence": "NADIR_UPDATE"}])
def test_a_json_wrapper_of_the_wrong_type_is_a_422(client: TestClient, body: Any) -> None:
    """What the declared schema refuses, the server refuses (found by schemathesis)."""
    r = client.post("/api/sequences/validate", json=body)
    assert r.status_code == 422 and r.json()["detail"][0]["loc"][0] == "body"
