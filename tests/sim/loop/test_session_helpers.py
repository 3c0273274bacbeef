"""Shared constants of the session tests."""

from datetime import UTC, datetime

START = datetime(2004, 4, 14, 16, 30, tzinfo=UTC)  # Spirit sol 100, ~10 LMST, sun ~47 deg
