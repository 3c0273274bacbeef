"""Accounts: users, their roles and their API tokens, in the server's database.

A team shares a rover the way Yamcs and Aerie let it: each person has a user with a role,
and each role may do all that the ones before it may:

- ``viewer``: read everything (telemetry, sequences, timelines, the 3D view);
- ``operator``: also upload and cancel sequences, send immediate commands, run the clock,
  change a rover's comm plan, ask the VO pointing advisor, rehearse sequences (start,
  cancel);
- ``conductor``: also the test conductor's actions (fault injection);
- ``admin``: also manage users and tokens, read the audit log, change a rover's comm mode.

A token is 256 random bits (``secrets.token_urlsafe(32)``), shown once when issued and
stored only as its SHA-256: a hash of a high-entropy token cannot be reversed or guessed,
and, unlike a slow password hash, costs nothing on every request. Each token has an expiry
and can be revoked. The bootstrap token (``roverops serve --operator-token``) is an admin
token kept in memory only, for scripts, tests and benches.

>>> from server.storage import Store
>>> accounts = Accounts(Store("sqlite://"))
>>> token = accounts.add_user("ada", "operator").token
>>> principal = accounts.authenticate(token)
>>> principal.name, principal.role, principal.may("viewer"), principal.may("admin")
('ada', 'operator', True, False)
>>> accounts.revoke("ada")
1
>>> accounts.authenticate(token)
Traceback (most recent call last):
...
server.access.accounts.TokenRefusedError: token revoked
"""

from __future__ import annotations

import hashlib
import hmac
import re
import secrets
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from typing import Any, Literal

from sqlalchemy import func, insert, select, update
from sqlalchemy.exc import IntegrityError

from server.errors import ConflictError, InvalidError, NotFoundError
from server.storage import Store, api_tokens, users

Role = Literal["viewer", "operator", "conductor", "admin"]
ROLES: tuple[Role, ...] = ("viewer", "operator", "conductor", "admin")
RANK: dict[str, int] = {role: i for i, role in enumerate(ROLES)}
NAME_RE = re.compile(r"[A-Za-z0-9_.-]{1,64}")
DEFAULT_EXPIRY_DAYS = 90
MAX_EXPIRY_DAYS = 3650
LOCAL_ADMIN = "admin"  # the user `roverops serve` creates on a new data directory
BOOTSTRAP = "bootstrap"  # the name the --operator-token admin acts under


class AccountError(InvalidError):
    """A request about users that cannot be met (bad name or role, unknown user, ...)."""

    kind = "account"


class UnknownUserError(AccountError, NotFoundError):
    """No user of that name."""


class UserExistsError(AccountError, ConflictError):
    """A user of that name exists already."""


class TokenRefusedError(Exception):
    """A token that is presented but not accepted: unknown, expired or revoked."""


@dataclass(frozen=True)
class Principal:
    """Who a request acts for: ``name`` and ``role`` (``None`` for an anonymous reader
    of a server with public reading)."""

    name: str
    role: Role | None

    def may(self, role: str) -> bool:
        """True when this principal's role is ``role`` or above it."""
        return self.role is not None and RANK[self.role] >= RANK[role]


ANONYMOUS = Principal("anonymous", None)


@dataclass(frozen=True)
class Issued:
    """A token just issued: the only time ``token`` is seen."""

    name: str
    role: Role
    token: str
    expires_at: datetime


def hash_token(token: str) -> str:
    """The SHA-256 (hex) under which a token is stored and looked up."""
    return hashlib.sha256(token.encode("utf-8")).hexdigest()


def check_name(name: str) -> str:
    """A user name: 1-64 letters, digits, ``_``, ``.`` or ``-``."""
    if not isinstance(name, str) or not NAME_RE.fullmatch(name):
        raise AccountError(f"user name {name!r}: 1-64 letters, digits, _, . or -")
    if name in (BOOTSTRAP, ANONYMOUS.name):
        raise AccountError(f"user name {name!r} is reserved")
    return name


def check_role(role: str) -> Role:
    """One of ``ROLES``."""
    for known in ROLES:
        if role == known:
            return known
    raise AccountError(f"role {role!r}: one of {', '.join(ROLES)}")


def check_expiry_days(days: float) -> float:
    """A token lifetime in days, (0, MAX_EXPIRY_DAYS]."""
    if isinstance(days, bool) or not isinstance(days, int | float) or not days > 0:
        raise AccountError(f"expires_days: must be a number > 0, got {days!r}")
    if days > MAX_EXPIRY_DAYS:
        raise AccountError(f"expires_days: at most {MAX_EXPIRY_DAYS}, got {days!r}")
    return float(days)


def _aware(value: datetime) -> datetime:
    """SQLite hands back naive datetimes (stored as UTC), PostgreSQL aware ones."""
    return value if value.tzinfo is not None else value.replace(tzinfo=UTC)


class Accounts:
    """Users and tokens over a ``Store``'s engine; every method is one transaction."""

    def __init__(self, store: Store, bootstrap_token: str | None = None) -> None:
        self.store = store
        self._bootstrap = bootstrap_token.encode() if bootstrap_token else None

    # ---- who is asking ----------------------------------------------------------------

    def authenticate(self, token: str) -> Principal:
        """The principal a presented token stands for; ``TokenRefusedError`` saying why not."""
        if self._bootstrap is not None and hmac.compare_digest(token.encode(), self._bootstrap):
            return Principal(BOOTSTRAP, "admin")
        t, u = api_tokens.c, users.c
        query = (
            select(u.name, u.role, t.expires_at, t.revoked_at)
            .select_from(api_tokens.join(users, t.user_id == u.id))
            .where(t.token_sha256 == hash_token(token))
        )
        with self.store.engine.connect() as conn:
            row = conn.execute(query).first()
        if row is None:
            raise TokenRefusedError("unknown token")
        if row.revoked_at is not None:
            raise TokenRefusedError("token revoked")
        if _aware(row.expires_at) <= datetime.now(UTC):
            raise TokenRefusedError("token expired")
        return Principal(row.name, check_role(row.role))

    # ---- managing users ---------------------------------------------------------------

    def add_user(self, name: str, role: str, expires_days: float = DEFAULT_EXPIRY_DAYS) -> Issued:
        """A new user with its first token."""
        name, checked_role = check_name(name), check_role(role)
        days = check_expiry_days(expires_days)
        try:
            with self.store.engine.begin() as conn:
                conn.execute(insert(users).values(name=name, role=checked_role))
                return self._issue(conn, name, days)
        except IntegrityError:
            raise UserExistsError(f"user {name!r} exists already") from None

    def issue_token(self, name: str, expires_days: float = DEFAULT_EXPIRY_DAYS) -> Issued:
        """Another token for an existing user (its other tokens stay valid)."""
        days = check_expiry_days(expires_days)
        with self.store.engine.begin() as conn:
            return self._issue(conn, check_name(name), days)

    def _issue(self, conn: Any, name: str, days: float) -> Issued:
        user = conn.execute(select(users.c.id, users.c.role).where(users.c.name == name)).first()
        if user is None:
            raise UnknownUserError(f"no user {name!r}")
        token = secrets.token_urlsafe(32)  # 256 bits
        expires = datetime.now(UTC) + timedelta(days=days)
        conn.execute(
            insert(api_tokens).values(
                user_id=user.id, token_sha256=hash_token(token), expires_at=expires
            )
        )
        return Issued(name, check_role(user.role), token, expires)

    def revoke(self, name: str) -> int:
        """Revoke every live token of ``name``; how many were revoked."""
        now = datetime.now(UTC)
        with self.store.engine.begin() as conn:
            user = conn.execute(select(users.c.id).where(users.c.name == check_name(name))).first()
            if user is None:
                raise UnknownUserError(f"no user {name!r}")
            result = conn.execute(
                update(api_tokens)
                .where(
                    api_tokens.c.user_id == user.id,
                    api_tokens.c.revoked_at.is_(None),
                    api_tokens.c.expires_at > now,
                )
                .values(revoked_at=now)
            )
            return int(result.rowcount)

    def set_role(self, name: str, role: str) -> None:
        """Change a user's role (its tokens carry the new role from the next request)."""
        checked = check_role(role)
        with self.store.engine.begin() as conn:
            result = conn.execute(
                update(users).where(users.c.name == check_name(name)).values(role=checked)
            )
            if result.rowcount == 0:
                raise UnknownUserError(f"no user {name!r}")

    def list_users(self) -> list[dict[str, Any]]:
        """Every user with its role, creation time and how many live tokens it holds."""
        t, u = api_tokens.c, users.c
        now = datetime.now(UTC)
        live = (
            select(t.user_id, func.count().label("n"))
            .where(t.revoked_at.is_(None), t.expires_at > now)
            .group_by(t.user_id)
            .subquery()
        )
        query = (
            select(u.name, u.role, u.created_at, func.coalesce(live.c.n, 0).label("live_tokens"))
            .select_from(users.outerjoin(live, live.c.user_id == u.id))
            .order_by(u.name)
        )
        with self.store.engine.connect() as conn:
            return [
                {
                    "name": r.name,
                    "role": r.role,
                    "created_at": _aware(r.created_at).isoformat(),
                    "live_tokens": int(r.live_tokens),
                }
                for r in conn.execute(query)
            ]

    def count_users(self) -> int:
        """How many users exist."""
        with self.store.engine.connect() as conn:
            return int(conn.execute(select(func.count()).select_from(users)).scalar_one())

    def ensure_local_admin(self) -> Issued | None:
        """On a database with no users: the local admin and its token (to print once);
        ``None`` when users exist (a restart keeps them and their tokens)."""
        if self.count_users() > 0:
            return None
        try:
            return self.add_user(LOCAL_ADMIN, "admin", expires_days=365)
        except UserExistsError:  # another process created it first
            return None
