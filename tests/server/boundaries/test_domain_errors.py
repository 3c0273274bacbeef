"""Domain errors are mapped to HTTP in one place (issue 21, "Typed boundaries"):
``server.state.Server.rover`` and the other domain code raise ``server.errors``' exceptions,
never ``HTTPException``, and ``server.api.deps`` answers each with its status."""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

import pytest
from fastapi import HTTPException
from fastapi.testclient import TestClient

from server.api.deps import domain_error_answer
from server.app import ServerConfig, create_app, data_dir_url
from server.errors import (
    ConflictError,
    DomainError,
    InvalidError,
    NotFoundError,
    UnknownRoverError,
)
from server.eventlog import FilterError
from server.state import Server

SERVER = Path(__file__).resolve().parents[3] / "server"
# the HTTP edge: the routes, the token checks, reading a request's body
HTTP_EDGE = ("api/", "access/auth.py", "access/truth_view.py", "validation/uploads.py",
             "validation/pool.py")  # fmt: skip
TOKEN = "domain-errors-token"


@pytest.fixture(scope="module")
def client(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    url = data_dir_url(tmp_path_factory.mktemp("errors"))
    config = ServerConfig(database_url=url, operator_token=TOKEN, start_clocks=False,
                          validation_processes=0)  # fmt: skip
    with TestClient(create_app(config)) as c:
        yield c


def test_an_unknown_rover_is_a_domain_error_not_http(client: TestClient) -> None:
    server: Server = client.app.state.server  # type: ignore[attr-defined]
    with pytest.raises(UnknownRoverError) as unknown:
        server.rover("curiosity")
    assert not isinstance(unknown.value, HTTPException)
    assert "spirit" in str(unknown.value)
    answer = client.get("/api/rovers/curiosity/state")
    assert answer.status_code == 404
    assert answer.json() == {"detail": str(unknown.value)}


def test_each_kind_of_domain_error_has_its_status() -> None:
    assert domain_error_answer(NotFoundError("no alarm 7")) == (404, "no alarm 7")
    assert domain_error_answer(ConflictError("acknowledged")) == (409, "acknowledged")
    status, detail = domain_error_answer(FilterError("sol_to", "before sol_from"))
    assert status == 422
    assert detail == [{"loc": ["query", "sol_to"], "msg": "sol_to: before sol_from",
                       "type": "value_error"}]  # fmt: skip
    assert domain_error_answer(InvalidError("bad"))[0] == 422


def test_conflicts_and_bad_values_reach_the_client(client: TestClient) -> None:
    auth = {"Authorization": f"Bearer {TOKEN}"}
    moved = client.post("/api/rovers/spirit/queue/999/move", json={"to": 0}, headers=auth)
    assert moved.status_code == 404 and "999" in moved.json()["detail"]
    limits = {"warning": 5.0, "critical": 1.0}  # a critical inside the warning: refused
    bad = client.put("/api/rovers/spirit/limits/tilt_accel_deg", json=limits, headers=auth)
    assert bad.status_code == 422 and bad.json()["detail"][0]["loc"] == ["body"]
    twice = client.post("/api/users", json={"name": "ada", "role": "viewer"}, headers=auth)
    again = client.post("/api/users", json={"name": "ada", "role": "viewer"}, headers=auth)
    assert (twice.status_code, again.status_code) == (201, 409)


def test_domain_code_never_speaks_http() -> None:
    """No module of ``server/`` below the HTTP edge names ``HTTPException``."""
    speaking = []
    for path in sorted(SERVER.rglob("*.py")):
        relative = path.relative_to(SERVER).as_posix()
        if relative.startswith(HTTP_EDGE):
            continue
        names = {n.id for n in ast.walk(ast.parse(path.read_text())) if isinstance(n, ast.Name)}
        names |= {a.name for n in ast.walk(ast.parse(path.read_text()))
                  if isinstance(n, ast.ImportFrom) for a in n.names}  # fmt: skip
        if "HTTPException" in names:
            speaking.append(relative)
    assert not speaking
    assert issubclass(UnknownRoverError, NotFoundError) and issubclass(NotFoundError, DomainError)
