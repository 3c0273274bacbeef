"""Shared fixtures: a throwaway PostgreSQL server, and database URLs for SQLite and it.

Issue 4 asks that the same storage tests pass on SQLite and on a real PostgreSQL server
that ``make test`` starts (``make pg`` installs Debian's ``postgresql`` when missing).
``pg_url`` is, in order of preference: ``ROVEROPS_TEST_PG_URL`` (a server you run; the
tests create and drop their own schemas in it), or a cluster ``initdb``-ed into a temporary
directory and started on a Unix socket there, or nothing: then the PostgreSQL tests fail
in CI (``CI`` set: the issue requires them to run) and are skipped on a developer machine.
"""

from __future__ import annotations

import contextlib
import glob
import os
import pwd
import shutil
import socket
import subprocess
import tempfile
import uuid
from collections.abc import Iterator
from pathlib import Path
from urllib.parse import quote

import pytest

PG_ENV = "ROVEROPS_TEST_PG_URL"
PG_OS_USER = "roverops_pg"  # created when running as root without a postgres user
PG_DB_USER = "roverops"
PG_DB = "roverops_test"


def _initdb() -> Path | None:
    """The newest PostgreSQL's initdb (Debian: /usr/lib/postgresql/<major>/bin)."""
    found = glob.glob("/usr/lib/postgresql/*/bin/initdb")
    found.sort(key=lambda p: int(Path(p).parts[-3]) if Path(p).parts[-3].isdigit() else 0)
    return Path(found[-1]) if found else None


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _as_user() -> list[str]:
    """The command prefix that runs PostgreSQL as a non-root user (it refuses root)."""
    if os.geteuid() != 0:
        return []
    try:
        pwd.getpwnam("postgres")
        user = "postgres"
    except KeyError:
        user = PG_OS_USER
        with contextlib.suppress(KeyError):
            pwd.getpwnam(user)
            return ["runuser", "-u", user, "--"]
        subprocess.run(["useradd", "--system", "--no-create-home", user], check=True)
    return ["runuser", "-u", user, "--"]


def _unavailable(reason: str) -> None:
    if os.environ.get("CI"):
        pytest.fail(f"PostgreSQL tests must run in CI: {reason} (run `make pg`)", pytrace=False)
    pytest.skip(f"PostgreSQL not available: {reason}")


@pytest.fixture(scope="session")
def pg_url() -> Iterator[str]:
    """A SQLAlchemy URL of an empty PostgreSQL database, for the whole test session."""
    if os.environ.get(PG_ENV):
        yield os.environ[PG_ENV]
        return
    initdb = _initdb()
    if initdb is None:
        _unavailable("no /usr/lib/postgresql/*/bin/initdb and no " + PG_ENV)
    assert initdb is not None
    bindir = initdb.parent
    prefix = _as_user()
    # In /tmp, not pytest's tmp_path: the server's user must reach the directory.
    root = Path(tempfile.mkdtemp(prefix="roverops-pg-"))
    data, log = root / "data", root / "server.log"
    if prefix:
        shutil.chown(root, user=prefix[2])
    port = _free_port()

    def run(*args: str) -> None:
        done = subprocess.run([*prefix, *args], capture_output=True, text=True)
        if done.returncode != 0:
            tail = log.read_text()[-2000:] if log.exists() else ""
            pytest.fail(
                f"PostgreSQL: {' '.join(args[:2])} failed:\n{done.stdout}{done.stderr}{tail}",
                pytrace=False,
            )

    try:
        # fsync off: a test cluster, nothing to keep after a machine crash.
        run(str(initdb), "-D", str(data), "-U", PG_DB_USER, "-A", "trust", "-E", "UTF8",
            "--no-sync", "--no-instructions")  # fmt: skip
        options = f"-k {root} -p {port} -c listen_addresses='' -c fsync=off"
        run(str(bindir / "pg_ctl"), "-D", str(data), "-l", str(log), "-w", "-s",
            "-o", options, "start")  # fmt: skip
        try:
            import psycopg

            with psycopg.connect(
                host=str(root), port=port, user=PG_DB_USER, dbname="postgres", autocommit=True
            ) as conn:
                conn.execute(f"CREATE DATABASE {PG_DB}")
            yield f"postgresql+psycopg://{PG_DB_USER}@/{PG_DB}?host={quote(str(root))}&port={port}"
        finally:
            subprocess.run(
                [*prefix, str(bindir / "pg_ctl"), "-D", str(data), "-m", "immediate", "-s",
                 "stop"],
                capture_output=True,
            )  # fmt: skip
    finally:
        shutil.rmtree(root, ignore_errors=True)


@pytest.fixture
def pg_schema_url(pg_url: str) -> Iterator[str]:
    """``pg_url`` with a fresh schema of its own first on the search path, dropped after
    the test: every test starts from empty tables, also on a server you provide."""
    import psycopg
    from sqlalchemy.engine import make_url

    schema = f"t_{uuid.uuid4().hex[:12]}"
    url = make_url(pg_url)
    conninfo = url.set(drivername="postgresql").render_as_string(hide_password=False)
    with psycopg.connect(conninfo, autocommit=True) as conn:
        conn.execute(f"CREATE SCHEMA {schema}")
    yield url.update_query_dict({"options": f"-csearch_path={schema}"}).render_as_string(
        hide_password=False
    )
    with psycopg.connect(conninfo, autocommit=True) as conn:
        conn.execute(f"DROP SCHEMA {schema} CASCADE")


@pytest.fixture(params=["sqlite", "postgresql"])
def store_url(request: pytest.FixtureRequest, tmp_path: Path) -> str:
    """The same test on both databases: a new SQLite file, or a new PostgreSQL schema."""
    if request.param == "sqlite":
        return f"sqlite:///{tmp_path / 'roverops.db'}"
    url: str = request.getfixturevalue("pg_schema_url")
    return url


def _browser_waits() -> None:
    """Every Playwright ``expect`` waits for its condition up to 30 s instead of 5 s: with
    both cores busy the console's first render (its sign-in check, then the rovers, then the
    timeline) takes longer than 5 s. A passing condition returns as soon as it holds."""
    try:
        from playwright.sync_api import expect
    except ImportError:  # the browser tests skip themselves without Playwright
        return
    expect.set_options(timeout=30_000)


_browser_waits()
