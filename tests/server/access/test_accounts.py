"""Users, roles and tokens (server.access.accounts) on SQLite and PostgreSQL: tokens are stored only
as hashes, expired and revoked tokens are refused, roles are ordered, the local admin is
created once, and a database from before accounts is upgraded in place."""

from __future__ import annotations

import hashlib
from datetime import UTC, datetime, timedelta
from pathlib import Path

import pytest
from sqlalchemy import create_engine, inspect, select, text, update

from server.access.accounts import (
    ROLES,
    AccountError,
    Accounts,
    Principal,
    TokenRefusedError,
    UnknownUserError,
    UserExistsError,
)
from server.storage import Store, api_tokens, metadata


@pytest.fixture
def accounts(store_url: str) -> Accounts:
    return Accounts(Store(store_url))


def _every_stored_text(store: Store) -> str:
    """Every value of every table, as one text (to search for a secret)."""
    parts: list[str] = []
    with store.engine.connect() as conn:
        for table in metadata.sorted_tables:
            for row in conn.execute(select(table)):
                parts.extend(repr(v) for v in row)
    return "\n".join(parts)


def test_a_token_is_stored_only_as_its_sha256(accounts: Accounts) -> None:
    issued = accounts.add_user("ada", "operator")
    again = accounts.issue_token("ada")
    stored = _every_stored_text(accounts.store)
    for token in (issued.token, again.token):
        assert token not in stored
        assert hashlib.sha256(token.encode()).hexdigest() in stored
    # 256 random bits: 43 URL-safe base64 characters, and two tokens differ
    assert len(issued.token) >= 43 and issued.token != again.token
    assert accounts.authenticate(issued.token) == Principal("ada", "operator")
    assert accounts.authenticate(again.token) == Principal("ada", "operator")


def test_unknown_expired_and_revoked_tokens_are_refused(accounts: Accounts) -> None:
    first = accounts.add_user("grace", "viewer").token
    second = accounts.issue_token("grace").token
    with pytest.raises(TokenRefusedError, match="unknown token"):
        accounts.authenticate(first + "x")
    with accounts.store.engine.begin() as conn:  # the first token's expiry passes
        conn.execute(
            update(api_tokens)
            .where(api_tokens.c.token_sha256 == hashlib.sha256(first.encode()).hexdigest())
            .values(expires_at=datetime.now(UTC) - timedelta(seconds=1))
        )
    with pytest.raises(TokenRefusedError, match="token expired"):
        accounts.authenticate(first)
    assert accounts.authenticate(second).name == "grace"
    assert accounts.revoke("grace") == 1  # the expired one is not live, the second is
    with pytest.raises(TokenRefusedError, match="token revoked"):
        accounts.authenticate(second)
    assert accounts.list_users() == [
        {"name": "grace", "role": "viewer", "created_at": accounts.list_users()[0]["created_at"],
         "live_tokens": 0}
    ]  # fmt: skip


def test_each_role_may_do_all_that_the_ones_before_it_may() -> None:
    for i, role in enumerate(ROLES):
        principal = Principal("x", role)
        assert [principal.may(r) for r in ROLES] == [j <= i for j in range(len(ROLES))]
    assert not Principal("anonymous", None).may("viewer")


def test_a_new_role_takes_effect_on_the_next_request(accounts: Accounts) -> None:
    token = accounts.add_user("linus", "viewer").token
    accounts.set_role("linus", "conductor")
    assert accounts.authenticate(token).role == "conductor"


def test_bad_names_roles_and_lifetimes_are_refused_and_nothing_is_stored(
    accounts: Accounts,
) -> None:
    for name, role, days in (
        ("", "viewer", 1),
        ("a b", "viewer", 1),
        ("x" * 65, "viewer", 1),
        ("anonymous", "viewer", 1),
        ("bootstrap", "admin", 1),
        ("ok", "root", 1),
        ("ok", "viewer", 0),
        ("ok", "viewer", -5),
        ("ok", "viewer", 1e9),
        ("ok", "viewer", float("nan")),
    ):
        with pytest.raises(AccountError):
            accounts.add_user(name, role, days)
    assert accounts.count_users() == 0
    accounts.add_user("ok", "viewer")
    with pytest.raises(UserExistsError):
        accounts.add_user("ok", "admin")
    with pytest.raises(UnknownUserError):
        accounts.issue_token("nobody")
    with pytest.raises(UnknownUserError):
        accounts.revoke("nobody")
    assert [u["name"] for u in accounts.list_users()] == ["ok"]


def test_the_local_admin_is_created_once(accounts: Accounts) -> None:
    issued = accounts.ensure_local_admin()
    assert issued is not None and issued.role == "admin"
    assert accounts.ensure_local_admin() is None  # a restart keeps it and prints nothing
    assert accounts.authenticate(issued.token) == Principal("admin", "admin")


def test_the_bootstrap_token_is_an_admin_kept_in_memory(tmp_path: Path) -> None:
    store = Store(f"sqlite:///{tmp_path / 'a.db'}")
    accounts = Accounts(store, bootstrap_token="a-bootstrap-token")
    assert accounts.authenticate("a-bootstrap-token") == Principal("bootstrap", "admin")
    assert "a-bootstrap-token" not in _every_stored_text(store)
    with pytest.raises(TokenRefusedError):
        Accounts(store).authenticate("a-bootstrap-token")


def test_a_database_from_before_accounts_is_upgraded_in_place(tmp_path: Path) -> None:
    """The previous version's sequences table had no submitted_by column: a new server
    adds it (and the new tables) and reads the old rows."""
    url = f"sqlite:///{tmp_path / 'old.db'}"
    engine = create_engine(url)
    with engine.begin() as conn:
        conn.execute(
            text(
                "CREATE TABLE sequences (id INTEGER PRIMARY KEY, rover VARCHAR(64) NOT NULL, "
                "name VARCHAR(256) NOT NULL, source TEXT NOT NULL, format VARCHAR(16) NOT NULL, "
                "status VARCHAR(32) NOT NULL, detail TEXT, errors JSON NOT NULL, "
                "warnings JSON NOT NULL, steps JSON NOT NULL, created_at DATETIME NOT NULL, "
                "updated_at DATETIME NOT NULL)"
            )
        )
        conn.execute(
            text(
                "INSERT INTO sequences VALUES (1, 'spirit', 'old', 'NADIR_UPDATE', 'text', "
                "'completed', NULL, '[]', '[]', '[]', '2024-01-01 00:00:00', "
                "'2024-01-01 00:00:00')"
            )
        )
    engine.dispose()
    store = Store(url)
    assert "submitted_by" in {c["name"] for c in inspect(store.engine).get_columns("sequences")}
    old = store.get_sequence(1)
    assert old is not None and old["name"] == "old" and old["submitted_by"] is None
    new_id = store.add_sequence("spirit", "new", "X", "text", "queued", [], [], [], "ada")
    assert store.submitters([1, new_id]) == {1: None, new_id: "ada"}
    assert Accounts(store).count_users() == 0  # the new tables exist


def test_the_api_refuses_an_expired_or_revoked_token_with_its_reason(tmp_path: Path) -> None:
    from fastapi.testclient import TestClient

    from server.app import ServerConfig, create_app

    config = ServerConfig(database_url=f"sqlite:///{tmp_path / 'api.db'}", start_clocks=False)
    app = create_app(config)
    accounts: Accounts = app.state.server.accounts
    expiring = accounts.add_user("old", "operator").token
    revoked = accounts.add_user("gone", "operator").token
    accounts.revoke("gone")
    with accounts.store.engine.begin() as conn:
        conn.execute(
            update(api_tokens)
            .where(api_tokens.c.token_sha256 == hashlib.sha256(expiring.encode()).hexdigest())
            .values(expires_at=datetime.now(UTC) - timedelta(seconds=1))
        )
    with TestClient(app) as client:
        for token, reason in ((expiring, "token expired"), (revoked, "token revoked")):
            auth = {"Authorization": f"Bearer {token}"}
            answer = client.post("/api/rovers/spirit/clock", json={"action": "pause"}, headers=auth)
            assert (answer.status_code, answer.json()["detail"]) == (403, f"wrong token: {reason}")
        assert client.get("/api/rovers/spirit/state").json()["clock"]["running"] is True
