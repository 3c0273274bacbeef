"""Who may do what over HTTP and WebSocket: tokens in, a ``Principal`` with a role out.

A request presents its token as ``Authorization: Bearer <token>`` (or the older
``X-Operator-Token`` header). Browsers cannot put a header on a WebSocket or on the 3D
view's iframe, so the console also keeps the token in an HttpOnly, SameSite=Strict cookie
(``POST /api/session``); the cookie counts for reading only (GET, HEAD and WebSocket
handshakes, the latter Origin-checked), never for a request that changes anything, so a
page on another site cannot act with it.

``require(role)`` makes the dependency a route declares. It is marked ``__auth_check__``
so that ``server.api.routing`` runs it before the request body is read: a client without the
right token is refused (401 missing, 403 wrong or too low a role) before any of its input
is parsed, and nothing changes. With ``public_read`` on (the default) the viewer role needs
no token; a token that is presented must still be valid.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Annotated, Any

from fastapi import Depends, HTTPException, Request
from fastapi.security import APIKeyHeader, HTTPAuthorizationCredentials, HTTPBearer
from starlette.datastructures import Headers

from server.access.accounts import ANONYMOUS, RANK, Accounts, Principal, TokenRefusedError

COOKIE = "roverops_token"
SAFE_METHODS = ("GET", "HEAD")

# Declares the bearer scheme in OpenAPI (so /docs has an Authorize button); the check
# itself reads the headers, so it runs the same whether FastAPI or server.api.routing calls it.
bearer_scheme = HTTPBearer(auto_error=False, description="an API token (roverops users token)")
legacy_scheme = APIKeyHeader(
    name="X-Operator-Token", auto_error=False, description="the same token, the older header"
)


def presented_token(
    headers: Headers | Mapping[str, str], cookies: Mapping[str, str], cookie_ok: bool
) -> tuple[str | None, bool]:
    """The token a request presents and whether it came from the cookie."""
    authorization = headers.get("authorization")
    if authorization is not None:
        if authorization[:7].lower() != "bearer " or not authorization[7:].strip():
            # a credential we cannot read is refused, never taken for no credential
            raise HTTPException(
                401, "malformed Authorization header: use Bearer <token>",
                {"WWW-Authenticate": "Bearer"},
            )  # fmt: skip
        return authorization[7:].strip(), False
    legacy = (headers.get("x-operator-token") or "").strip()
    if legacy:
        return legacy, False
    if cookie_ok and cookies.get(COOKIE):
        return cookies[COOKIE], True
    return None, False


def identify(
    accounts: Accounts,
    public_read: bool,
    role: str,
    token: str | None,
    from_cookie: bool,
) -> Principal:
    """Who presents ``token`` (anonymous when none is needed for ``role``); ``HTTPException``
    401 when a token is needed and missing, 403 when it is not valid."""
    if token is None:
        if role == "viewer" and public_read:
            return ANONYMOUS
        raise HTTPException(
            401,
            f"token required: this needs the {role} role (Authorization: Bearer <token>)",
            {"WWW-Authenticate": "Bearer"},
        )
    try:
        principal = accounts.authenticate(token)
    except TokenRefusedError as refused:
        if from_cookie and role == "viewer" and public_read:
            return ANONYMOUS  # a stale sign-in must not stop public reading
        raise HTTPException(403, f"wrong token: {refused}") from None
    return principal


def authorize(principal: Principal, role: str) -> Principal:
    """``principal`` if its role is ``role`` or above (anonymous passes for reading only
    when ``identify`` let it through); ``HTTPException`` 403 if not."""
    if principal.role is not None and not principal.may(role):
        raise HTTPException(
            403, f"{principal.name} is {principal.role}: this needs the {role} role"
        )
    return principal


def require(role: str) -> Callable[..., Principal]:
    """The dependency of a route that needs ``role`` (``viewer`` ... ``admin``)."""
    if role not in RANK:
        raise ValueError(f"unknown role {role!r}")

    def check(
        request: Request,
        _scheme: Annotated[HTTPAuthorizationCredentials | None, Depends(bearer_scheme)] = None,
        _legacy: Annotated[str | None, Depends(legacy_scheme)] = None,
    ) -> Principal:
        cached: Principal | None = getattr(request.state, "principal", None)
        if cached is not None and getattr(request.state, "checked_role", None) == role:
            return cached
        server = request.app.state.server
        token, from_cookie = presented_token(
            request.headers, request.cookies, request.method in SAFE_METHODS
        )
        principal = identify(server.accounts, server.config.public_read, role, token, from_cookie)
        request.state.principal = principal  # known before the role check: the audit names it
        authorize(principal, role)
        request.state.checked_role = role
        return principal

    check.__auth_check__ = True  # type: ignore[attr-defined]  # server.api.routing runs it first
    check.__required_role__ = role  # type: ignore[attr-defined]  # server.api.routing reads it
    check.__name__ = f"require_{role}"
    return check


def websocket_principal(server: Any, headers: Headers, cookies: Mapping[str, str]) -> Principal:
    """The principal of a WebSocket handshake (viewer role); ``HTTPException`` if refused."""
    token, from_cookie = presented_token(headers, cookies, True)
    principal = identify(server.accounts, server.config.public_read, "viewer", token, from_cookie)
    return authorize(principal, "viewer")


Viewer = Annotated[Principal, Depends(require("viewer"))]
Operator = Annotated[Principal, Depends(require("operator"))]
Conductor = Annotated[Principal, Depends(require("conductor"))]
Admin = Annotated[Principal, Depends(require("admin"))]
