"""Who is signed in, signing in and out of a browser, and the users, their roles and tokens
(``server.access.accounts``; admin only but ``/api/me`` and the session)."""

from __future__ import annotations

from typing import Any, Literal

from fastapi import HTTPException, Request
from fastapi.responses import JSONResponse
from pydantic import BaseModel, ConfigDict, Field

from server.access.accounts import (
    DEFAULT_EXPIRY_DAYS,
    ROLES,
    Principal,
    TokenRefusedError,
)
from server.access.auth import COOKIE, Admin, Viewer
from server.access.truth_view import may_see_truth
from server.api.answers import Identity, IssuedToken, RoleChanged, SignedOut, TokensRevoked, User
from server.api.deps import (
    BAD_REQUEST,
    NOT_FOUND,
    ServerDep,
    error_doc,
    router,
)


class SessionBody(BaseModel):
    """``POST /api/session``: sign this browser in with a token (kept in a cookie)."""

    model_config = ConfigDict(extra="forbid")
    token: str = Field(min_length=1, max_length=512)


class NewUserBody(BaseModel):
    """``POST /api/users``: a user, its role and the lifetime of its first token."""

    model_config = ConfigDict(extra="forbid", strict=True)
    name: str = Field(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9_.-]+$")
    role: Literal["viewer", "operator", "conductor", "admin"]
    expires_days: float = Field(default=DEFAULT_EXPIRY_DAYS, gt=0, le=3650)


class RoleBody(BaseModel):
    """``PATCH /api/users/{name}``: a new role."""

    model_config = ConfigDict(extra="forbid", strict=True)
    role: Literal["viewer", "operator", "conductor", "admin"]


class TokenBody(BaseModel):
    """``POST /api/users/{name}/tokens``: the lifetime of the new token."""

    model_config = ConfigDict(extra="forbid", strict=True)
    expires_days: float = Field(default=DEFAULT_EXPIRY_DAYS, gt=0, le=3650)


routes = router()


def _principal_json(server: ServerDep, who: Principal) -> dict[str, Any]:
    return {"name": who.name, "role": who.role, "public_read": server.config.public_read,
            "roles": list(ROLES), "truth_view": server.config.truth_view,
            # whether this user's answers carry the simulator's truth (the console's Truth
            # panel shows then): server.access.truth_view
            "sees_truth": may_see_truth(server.config.truth_view, who)}  # fmt: skip


@routes.get("/api/me", response_model=Identity)
def me(server: ServerDep, who: Viewer) -> dict[str, Any]:
    """Who this request acts as (``anonymous`` with no role when reading without a
    token), whether reading needs a token on this server, its truth view and whether
    this caller sees the truth."""
    return _principal_json(server, who)


@routes.post("/api/session", response_model=Identity, responses=BAD_REQUEST)
def sign_in(server: ServerDep, body: SessionBody, request: Request) -> JSONResponse:
    """Sign this browser in: the token is checked and kept in an HttpOnly cookie that
    the 3D view and the telemetry WebSocket send (it counts for reading only)."""
    request.state.audit_action = "sign in"
    try:
        who = server.accounts.authenticate(body.token)
    except TokenRefusedError as refused:
        raise HTTPException(403, f"wrong token: {refused}") from None
    request.state.principal = who
    response = JSONResponse(_principal_json(server, who))
    secure = request.url.scheme == "https"
    response.set_cookie(COOKIE, body.token, httponly=True, samesite="strict", secure=secure)
    return response


@routes.delete("/api/session", response_model=SignedOut)
def sign_out(request: Request) -> JSONResponse:
    """Sign this browser out (forget the cookie)."""
    request.state.audit_action = "sign out"
    response = JSONResponse({"signed_out": True})
    response.delete_cookie(COOKIE, httponly=True, samesite="strict")
    return response


@routes.get("/api/users", response_model=list[User])
def list_users(server: ServerDep, _: Admin) -> list[dict[str, Any]]:
    """Every user: name, role, creation time and how many live tokens it holds."""
    return server.accounts.list_users()


@routes.post(
    "/api/users",
    response_model=IssuedToken,
    status_code=201,
    responses={409: error_doc("the user exists")},
)
def add_user(server: ServerDep, body: NewUserBody, request: Request, _: Admin) -> dict[str, Any]:
    """A new user and its first token (shown in this answer only; stored hashed)."""
    request.state.audit_action = f"add user {body.name} as {body.role}"
    issued = server.accounts.add_user(body.name, body.role, body.expires_days)
    return {"name": issued.name, "role": issued.role, "token": issued.token,
            "expires_at": issued.expires_at.isoformat()}  # fmt: skip


@routes.patch("/api/users/{name}", response_model=RoleChanged, responses=NOT_FOUND)
def change_role(
    server: ServerDep, name: str, body: RoleBody, request: Request, _: Admin
) -> dict[str, Any]:
    """Give a user another role."""
    request.state.audit_action = f"set the role of {name} to {body.role}"
    server.accounts.set_role(name, body.role)
    return {"name": name, "role": body.role}


@routes.post(
    "/api/users/{name}/tokens", response_model=IssuedToken, status_code=201, responses=NOT_FOUND
)
def new_token(
    server: ServerDep, name: str, body: TokenBody, request: Request, _: Admin
) -> dict[str, Any]:
    """Another token for a user (shown in this answer only)."""
    request.state.audit_action = f"issue a token to {name}"
    issued = server.accounts.issue_token(name, body.expires_days)
    return {"name": issued.name, "role": issued.role, "token": issued.token,
            "expires_at": issued.expires_at.isoformat()}  # fmt: skip


@routes.delete("/api/users/{name}/tokens", response_model=TokensRevoked, responses=NOT_FOUND)
def revoke_tokens(server: ServerDep, name: str, request: Request, _: Admin) -> dict[str, Any]:
    """Revoke every live token of a user."""
    request.state.audit_action = f"revoke the tokens of {name}"
    revoked = server.accounts.revoke(name)
    return {"name": name, "revoked": revoked}
