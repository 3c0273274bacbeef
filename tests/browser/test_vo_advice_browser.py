"""The VO pointing advice in the sequence editor, in a real browser (Chromium, Playwright)
against the real server: the caret's drive line gets the server's recommendation, and on
request the pointing goes into that line (web/vo_advice.js). The expected texts are the
server's own answer to the same request. Screenshot in test-artifacts/."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest

from tests.browser.test_console_browser import ARTIFACTS, CHROMIUM, TOKEN, console_page, sign_in
from tests.server.test_server_restart import serving

if not Path(CHROMIUM).exists():
    pytest.skip("Chromium not installed (make test installs it)", allow_module_level=True)

from playwright.sync_api import Page, expect

AUTH = {"Authorization": f"Bearer {TOKEN}"}
TEXT = "SEQUENCE advised\nWAIT duration_s=5\nDRIVE_STRAIGHT distance_m=3 vo=on  # to the rock\n"
LONG_MS = 60_000


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    with serving(tmp_path_factory.mktemp("advice"), TOKEN, three_d=False) as base:
        yield base


@pytest.fixture(scope="module")
def page(server: str) -> Iterator[Page]:
    with console_page(f"{server}/?rover=spirit", "vo_advice.png") as pg:
        yield pg


def _reported(server: str) -> None:
    """The rover runs a wait, so that a downlink with its pose is on the ground."""
    r = httpx.post(f"{server}/api/rovers/spirit/commands", headers=AUTH, timeout=30,
                   json={"command": "WAIT", "args": {"duration_s": 1}})  # fmt: skip
    assert r.status_code == 201, r.text


def test_the_caret_line_gets_the_advice_and_its_pointing(page: Page, server: str) -> None:
    _reported(server)
    sign_in(page)
    expect(page.get_by_test_id("position")).not_to_have_text("—", timeout=LONG_MS)
    page.fill("#editor", TEXT)
    page.evaluate(
        "() => { const e = document.getElementById('editor');"
        " e.focus(); e.setSelectionRange(e.value.indexOf('DRIVE'), e.value.indexOf('DRIVE')); }"
    )
    advice = page.get_by_test_id("vo-advice")
    page.click("[data-testid=vo-advice-ask]")
    expect(advice).to_contain_text("Line 3: point the Navcams at az", timeout=LONG_MS)
    answer = httpx.post(f"{server}/api/rovers/spirit/vo-advice", json={"text": TEXT, "line": 3},
                        headers=AUTH, timeout=LONG_MS / 1000).json()  # fmt: skip
    best = answer["recommended"]
    # the rover stands still: the server's answer now is the one the console showed
    expect(advice).to_contain_text(f"az {best['az_deg']:g}°, el {best['el_deg']:g}°")
    apply = page.get_by_test_id("vo-advice-apply")
    expect(apply).to_have_text(f"Put {answer['arguments']} into line 3")
    apply.click()
    expect(page.locator("#editor")).to_have_value(
        TEXT.replace("vo=on  # to the rock", f"vo=on {answer['arguments']}    # to the rock")
    )
    expect(apply).to_be_hidden()
    page.locator("section.commanding").screenshot(path=str(ARTIFACTS / "vo_advice.png"))
