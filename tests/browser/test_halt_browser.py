"""A drive halted by mobility fault protection, as an operator sees it in a real browser:
a sequence adds a keep-out zone and drives at it; the rover halts before it; the Rover panel
shows mobility HALTED with the reason and the position's 2σ, the event list the halt, the
queue the step `halted` and the sequence stopped; CLEAR_MOBILITY_FAULT enables mobility
again. Screenshots in test-artifacts/."""

from __future__ import annotations

import re
from collections.abc import Iterator

import httpx
import pytest
from playwright.sync_api import expect

from tests.browser.test_console_browser import ARTIFACTS, TOKEN, console_page, sign_in
from tests.server.test_server_restart import serving

AUTH = {"Authorization": f"Bearer {TOKEN}"}
SEQ = (
    "SEQUENCE keepout_drive\n"
    "KEEPOUT_ADD zone=wopmay x_m=2.5 y_m=0 radius_m=0.3\n"
    "DRIVE_STRAIGHT distance_m=4\n"
    "DRIVE_STRAIGHT distance_m=1\n"
)


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    with serving(tmp_path_factory.mktemp("halt"), TOKEN, three_d=False) as base:
        yield base


def test_an_operator_sees_the_halt_its_reason_and_clears_it(server: str) -> None:
    httpx.post(
        f"{server}/api/rovers/spirit/clock", json={"speed": "max"}, headers=AUTH
    ).raise_for_status()
    with console_page(f"{server}/?rover=spirit", "halt.png") as page:
        # the console's modules have run (a click before they listen would be lost)
        expect(page.get_by_test_id("signed-in")).to_have_text("reading only")
        sign_in(page)
        expect(page.get_by_test_id("mobility")).to_have_text("enabled")
        r = httpx.post(f"{server}/api/rovers/spirit/sequences", content=SEQ, headers=AUTH)
        assert r.status_code == 201, r.text
        mobility = page.get_by_test_id("mobility")
        expect(mobility).to_contain_text("HALTED: keep-out zone wopmay", timeout=60_000)
        expect(page.get_by_test_id("position")).to_contain_text(re.compile(r"± \d+\.\d\d m \(2σ\)"))
        expect(page.get_by_test_id("events")).to_contain_text("drive halted by fault protection")
        page.get_by_test_id("readouts").screenshot(path=str(ARTIFACTS / "halt-readouts.png"))
        body = httpx.get(f"{server}/api/rovers/spirit/queue", headers=AUTH).json()
        done = body["recent"][0]
        assert [s["status"] for s in done["steps"]][:3] == ["completed", "halted", "skipped"]
        r = httpx.post(
            f"{server}/api/rovers/spirit/sequences",
            content="SEQUENCE clear\nCLEAR_MOBILITY_FAULT\n",
            headers=AUTH,
        )
        assert r.status_code == 201, r.text
        expect(mobility).to_have_text("enabled", timeout=60_000)
