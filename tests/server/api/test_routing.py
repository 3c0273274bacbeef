"""``server.api.routing.AuthFirstRoute`` on a small app of its own: the auth check runs before
the body is read, once per request (FastAPI's own call reuses its result), and a JSON body
is read through ``server.validation.uploads`` (size, depth)."""

from __future__ import annotations

from typing import Annotated

from fastapi import Depends, FastAPI, HTTPException, Request
from fastapi.testclient import TestClient
from pydantic import BaseModel

from server.api.routing import AuthFirstRoute, auth_check

calls: list[str] = []


@auth_check
def who(request: Request) -> str:
    calls.append(request.url.path)
    if request.headers.get("x-who") != "me":
        raise HTTPException(401, "who are you?")
    return "me"


class Body(BaseModel):
    n: int


def _client() -> TestClient:
    app = FastAPI()
    app.router.route_class = AuthFirstRoute
    app.state.max_body_bytes = 2000

    @app.post("/echo")
    def echo(body: Body, user: Annotated[str, Depends(who)]) -> dict[str, object]:
        return {"n": body.n, "user": user}

    return TestClient(app)


def test_the_check_runs_once_before_the_body() -> None:
    client = _client()
    calls.clear()
    assert client.post("/echo", json={"n": 3}, headers={"x-who": "me"}).json() == {
        "n": 3,
        "user": "me",
    }
    assert calls == ["/echo"]  # run first by the route, then reused by FastAPI
    r = client.post("/echo", content=b"{bad", headers={"content-type": "application/json"})
    assert r.status_code == 401


def test_the_body_is_read_with_the_app_limits() -> None:
    client = _client()
    me = {"x-who": "me", "content-type": "application/json"}
    assert (
        client.post("/echo", content=b'{"n": ' + b" " * 3000 + b"1}", headers=me).status_code == 413
    )
    r = client.post("/echo", content=b"[" * 1000, headers=me)
    assert r.status_code == 422 and "nested" in r.json()["detail"][0]["msg"]
