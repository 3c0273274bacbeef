"""A route class that checks who is asking before it reads what they sent (issue 13, defect 10).

FastAPI reads and parses a route's body before it solves the route's dependencies, so a
request without a token but with bad JSON got a 422 (the body's fault) instead of a 401,
and a stranger could make the server parse whatever they sent. ``AuthFirstRoute`` runs the
route's auth checks (dependencies marked with ``auth_check``) first, then reads a JSON body
itself through ``server.validation.uploads`` (size limit while streaming, nesting and number limits,
parsed in the threadpool), and only then hands the request to FastAPI's own handler, which
reuses both: the check's result is cached on ``request.state`` and the body on the request.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Coroutine, Iterator
from typing import Any, TypeVar

from fastapi import FastAPI, Request, params
from fastapi.dependencies.models import Dependant
from fastapi.exception_handlers import http_exception_handler
from fastapi.responses import JSONResponse
from fastapi.routing import APIRoute, iter_route_contexts
from starlette.concurrency import run_in_threadpool
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.responses import Response

from server.validation.uploads import parse_json, read_body

DEFAULT_MAX_BODY_BYTES = 1_000_000  # when the app sets no ``state.max_body_bytes``

F = TypeVar("F", bound=Callable[..., Any])


def auth_check(fn: F) -> F:
    """Mark ``fn(request, ...)`` (every other parameter with a default) as an auth check:
    ``AuthFirstRoute`` calls it with the request alone before the body is read, and
    FastAPI's own call of it (as a dependency) returns the cached result."""

    @functools.wraps(fn)
    def check(request: Request, *args: Any, **kwargs: Any) -> Any:
        done: dict[Any, Any] | None = getattr(request.state, "auth_checks", None)
        if done is None:
            done = request.state.auth_checks = {}
        if fn not in done:
            done[fn] = fn(request, *args, **kwargs)
        return done[fn]

    check.__auth_check__ = True  # type: ignore[attr-defined]
    return check  # type: ignore[return-value]


def _auth_checks(dependant: Dependant) -> list[Callable[[Request], Any]]:
    """The auth checks among a route's dependencies (depth first, each once)."""
    found: list[Callable[[Request], Any]] = []
    stack = list(dependant.dependencies)
    while stack:
        dep = stack.pop(0)
        if getattr(dep.call, "__auth_check__", False) and dep.call not in found:
            found.append(dep.call)  # type: ignore[arg-type]
        stack[:0] = dep.dependencies
    return found


def _is_json(content_type: str) -> bool:
    media = content_type.split(";")[0].strip().lower()
    return media.startswith("application/") and (media.endswith("/json") or media.endswith("+json"))


class AuthFirstRoute(APIRoute):
    """An ``APIRoute`` whose handler runs the auth checks, then reads and parses a JSON
    body safely, then FastAPI's normal handler (module docstring). Its answer is dumped
    without the fields the route's dict did not set (``server.api.answers``: a frame outside
    the truth view has no truth key, not a null one)."""

    def __init__(self, path: str, endpoint: Callable[..., Any], **kwargs: Any) -> None:
        kwargs["response_model_exclude_unset"] = True
        super().__init__(path, endpoint, **kwargs)

    def get_route_handler(self) -> Callable[[Request], Coroutine[Any, Any, Response]]:
        handler = super().get_route_handler()
        checks = _auth_checks(self.dependant)
        reads_json = self.body_field is not None and not isinstance(
            self.body_field.field_info, params.Form
        )

        async def auth_first(request: Request) -> Response:
            for check in checks:
                await run_in_threadpool(check, request)
            if reads_json:
                limit = getattr(request.app.state, "max_body_bytes", DEFAULT_MAX_BODY_BYTES)
                body = await read_body(request, limit)
                request._body = body  # FastAPI's handler reads the body from here
                if body and _is_json(request.headers.get("content-type", "")):
                    parsed = await run_in_threadpool(parse_json, body)
                    request._json = parsed
            return await handler(request)

        return auth_first


def api_routes(app: FastAPI) -> Iterator[APIRoute]:
    """Every ``APIRoute`` of ``app``, those of its included routers too (FastAPI keeps an
    included router whole, one entry of ``app.routes``; ``iter_route_contexts`` opens it)."""
    for context in iter_route_contexts(app.routes):
        if isinstance(context.original_route, APIRoute):
            yield context.original_route


def allow_every_method(app: FastAPI) -> None:
    """A 405's ``Allow`` lists every method of every route at that path. Starlette answers
    with the methods of the first route whose path matched, and this API puts GET and POST
    (or GET and DELETE) of one path in two routes, so it named only one of them."""

    async def method_not_allowed(request: Request, exc: Exception) -> Response:
        assert isinstance(exc, StarletteHTTPException)
        if exc.status_code != 405:
            return await http_exception_handler(request, exc)
        methods = {
            method
            for route in api_routes(app)
            if route.path_regex.match(request.url.path)
            for method in route.methods or ()
        }
        headers = {**(exc.headers or {}), "Allow": ", ".join(sorted(methods))}
        return JSONResponse({"detail": exc.detail}, 405, headers)

    app.add_exception_handler(StarletteHTTPException, method_not_allowed)


def document_public_reads(app: FastAPI) -> None:
    """With public reading on, the OpenAPI of each viewer route says its token is optional
    (``security: [{}, ...]``): the schema describes what the server does."""
    original = app.openapi

    def openapi() -> dict[str, Any]:
        schema = original()
        if schema.get("x-public-reads-documented"):
            return schema
        for route in api_routes(app):
            if not route.include_in_schema:
                continue
            roles = {
                getattr(d.call, "__required_role__", None) for d in route.dependant.dependencies
            }
            if "viewer" not in roles:
                continue
            for method in route.methods or ():
                operation = schema["paths"].get(route.path_format, {}).get(method.lower())
                if operation is not None and operation.get("security"):
                    operation["security"] = [{}, *operation["security"]]
        schema["x-public-reads-documented"] = True
        return schema

    app.openapi = openapi  # type: ignore[method-assign]
