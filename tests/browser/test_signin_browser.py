"""Signing the console in, in a real browser (Chromium, Playwright) against a real server
that keeps reading private (``--public-read off``): before sign-in the console says so and
shows nothing; a viewer's token shows the rover live (the telemetry WebSocket and the 3D
view read with the sign-in cookie) with the operator's controls greyed out; an operator's
token enables them; signing out forgets the token. Screenshots go to test-artifacts/."""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest

from tests.browser.test_console_browser import ARTIFACTS, CHROMIUM, console_page
from tests.server.test_server_restart import _wait, serving

if not Path(CHROMIUM).exists():
    pytest.skip("Chromium not installed (make test installs it)", allow_module_level=True)

from playwright.sync_api import Page, expect

BOOTSTRAP = "signin-bootstrap-token"


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[str, dict[str, str]]]:
    data = tmp_path_factory.mktemp("signin")
    admin = {"Authorization": f"Bearer {BOOTSTRAP}"}
    with serving(data, BOOTSTRAP, env_extra={"ROVEROPS_PUBLIC_READ": "off"}) as base:
        tokens = {
            role: httpx.post(f"{base}/api/users", json={"name": f"{role}1", "role": role},
                             headers=admin).json()["token"]
            for role in ("viewer", "operator")
        }  # fmt: skip
        yield base, tokens


@pytest.fixture(scope="module")
def page(server: tuple[str, dict[str, str]]) -> Iterator[Page]:
    with console_page(f"{server[0]}/?rover=spirit", "signin.png") as pg:
        yield pg


def test_a_private_server_shows_nothing_before_sign_in(page: Page) -> None:
    expect(page.get_by_test_id("signed-in")).to_have_text("sign in to view")
    expect(page.get_by_test_id("sol-clock")).to_have_text("—")
    expect(page.locator("#upload-text")).to_be_disabled()


def test_a_viewer_reads_live_and_may_not_command(
    page: Page, server: tuple[str, dict[str, str]]
) -> None:
    expect(page.get_by_test_id("signed-in")).to_have_attribute("data-role", re.compile(".*"))
    page.fill("[data-testid=token]", server[1]["viewer"])
    page.click("[data-testid=sign-in]")
    expect(page.get_by_test_id("signed-in")).to_have_text("viewer1 · viewer")
    expect(page.get_by_test_id("sol-clock")).to_contain_text("LMST", timeout=20_000)
    # the telemetry WebSocket reads with the cookie: readouts arrive without a reload
    expect(page.get_by_test_id("nate-mode")).not_to_have_text("—", timeout=20_000)
    # Reading needs the cookie here, so the view cannot come from the loopback twin (a
    # process of its own): it would share the console's thread, and with software WebGL
    # (SwiftShader) it starts hidden, saying why, so that the console stays responsive.
    toggle = page.get_by_test_id("view3d-toggle")
    expect(toggle).to_have_attribute("aria-expanded", "false")
    expect(page.locator("#view3d-status")).to_contain_text("draws WebGL in software")
    toggle.click()  # this browser's choice: shown, it loads
    expect(toggle).to_have_attribute("aria-expanded", "true")
    page.locator("#view3d-box").scroll_into_view_if_needed()
    # the 3D view (its own page and WebSocket in the iframe) reads with the cookie too
    frame = page.frame_locator("[data-testid=view3d]")
    expect(frame.locator("canvas").first).to_be_visible(timeout=60_000)
    for control in ("#upload-text", "#send", "#pause", "#speed"):
        expect(page.locator(control)).to_be_disabled()
        expect(page.locator(control)).to_have_attribute("title", re.compile("operator role"))
    page.screenshot(path=str(ARTIFACTS / "signin_viewer.png"))
    toggle.click()  # hidden again: the next steps time the console, not SwiftShader
    expect(page.get_by_test_id("view3d")).to_have_attribute("src", "about:blank")


def test_an_operator_may_command_and_signing_out_forgets_the_token(
    page: Page, server: tuple[str, dict[str, str]]
) -> None:
    page.click("[data-testid=sign-out]")
    expect(page.get_by_test_id("signed-in")).to_have_text("sign in to view")
    page.fill("[data-testid=token]", server[1]["operator"])
    page.keyboard.press("Enter")
    expect(page.get_by_test_id("signed-in")).to_have_text("operator1 · operator")
    expect(page.locator("#upload-text")).to_be_enabled()
    page.click("#pause")
    expect(page.get_by_test_id("clock-speed")).to_contain_text("paused")
    page.reload()  # the sign-in survives a reload of the page
    expect(page.get_by_test_id("signed-in")).to_have_text("operator1 · operator")
    audit = httpx.get(
        f"{server[0]}/api/audit",
        params={"user": "operator1"},
        headers={"Authorization": f"Bearer {BOOTSTRAP}"},
    ).json()
    assert [r["action"] for r in audit][:2] == ["clock action=pause", "sign in"]
    page.screenshot(path=str(ARTIFACTS / "signin_operator.png"))


def test_a_tab_reads_the_timeline_with_its_token_when_another_tab_signed_out(
    page: Page, server: tuple[str, dict[str, str]]
) -> None:
    """The console's reads all carry the tab's token: another tab of the browser signing out
    (which forgets the shared cookie) leaves this tab reading, its sol timeline too (issue
    21: the timeline's own fetch sent no token and was refused 401 without the cookie)."""
    if page.get_by_test_id("sign-out").is_visible():
        page.click("[data-testid=sign-out]")
    expect(page.get_by_test_id("signed-in")).to_have_attribute("data-role", re.compile(".*"))
    page.fill("[data-testid=token]", server[1]["operator"])
    page.click("[data-testid=sign-in]")
    expect(page.get_by_test_id("signed-in")).to_have_text("operator1 · operator")
    # what another tab's Sign out sends: the browser forgets the (HttpOnly) sign-in cookie
    page.evaluate("fetch('/api/session', { method: 'DELETE' })")
    _wait(lambda: page.context.cookies() == [])
    page.reload()
    expect(page.get_by_test_id("signed-in")).to_have_text("operator1 · operator")
    status = page.get_by_test_id("timeline-status")
    expect(status).to_contain_text(re.compile(r"frames plotted|live:"), timeout=30_000)
    expect(page.get_by_test_id("timeline-summary")).to_contain_text("Sol ")
