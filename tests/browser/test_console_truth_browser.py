"""What the console says is what the server says (issue 14, items 1-4 and 6), in a real
browser (Chromium, Playwright) against the real server: the speed selector shows the
server's speed after a load and after a refused change; a refused token is reported with
the API's words (403 "wrong token: ...", 401 "token required"), also in a tab that reads
with another tab's sign-in; after PLANT_SITE the Site estimate and the mission-frame error
(the truth view) are two readouts; at max speed with nothing queued the header says the
clock runs in real time; a failed upload clears the old diagnostics, and a rejected
sequence is listed with its name and errors. Screenshots go to test-artifacts/."""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest

from tests.browser.test_console_browser import (
    ARTIFACTS,
    CHROMIUM,
    LAUNCH_ARGS,
    TOKEN,
    server,  # noqa: F401  (the fixture: a real server on a temporary database)
    sign_in,
)
from tests.server.test_server_restart import _wait

if not Path(CHROMIUM).exists():
    pytest.skip("Chromium not installed (make test installs it)", allow_module_level=True)

from playwright.sync_api import BrowserContext, Page, Route, expect, sync_playwright

ADMIN = {"Authorization": f"Bearer {TOKEN}"}
BAD = "SEQUENCE broken\nDRIVE_STRAIGHT distance_m=-3\nNADIR_UPDATE\nFLY_AWAY\n"


@pytest.fixture(scope="module")
def context(server: str) -> Iterator[BrowserContext]:  # noqa: F811
    """One browser profile (its tabs share the sign-in cookie, not sessionStorage)."""
    ARTIFACTS.mkdir(exist_ok=True)
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=LAUNCH_ARGS)
        yield browser.new_context(viewport={"width": 1280, "height": 800})
        browser.close()


def _open(context: BrowserContext, server: str) -> Page:  # noqa: F811
    page = context.new_page()
    page.goto(f"{server}/?rover=spirit")
    expect(page.get_by_test_id("sol-clock")).to_contain_text("LMST")
    return page


def _operator_token(server: str, name: str) -> str:  # noqa: F811
    r = httpx.post(f"{server}/api/users", json={"name": name, "role": "operator"}, headers=ADMIN)
    assert r.status_code == 201, r.text
    token: str = r.json()["token"]
    return token


def _revoke(server: str, name: str) -> None:  # noqa: F811
    r = httpx.delete(f"{server}/api/users/{name}/tokens", headers=ADMIN)
    assert r.status_code == 200, r.text


def _header_rows(page: Page) -> int:
    """How many lines the header's items take (items whose vertical middles differ)."""
    middles: list[float] = page.evaluate(
        """() => [...document.querySelectorAll('header > *')]
              .map(e => e.getBoundingClientRect()).filter(r => r.width > 0)
              .map(r => (r.top + r.bottom) / 2)"""
    )
    rows: list[float] = []
    for m in sorted(middles):
        if not rows or m - rows[-1] > 8.0:
            rows.append(m)
    return len(rows)


def test_a_refused_token_is_reported_as_the_api_words_it(
    context: BrowserContext,
    server: str,  # noqa: F811
) -> None:
    page = _open(context, server)
    assert _header_rows(page) == 1  # not signed in (the widest header) at 1280 px
    # a token a header cannot carry (not Latin-1) is still checked, and refused in words
    expect(page.get_by_test_id("signed-in")).to_have_attribute("data-role", re.compile(".*"))
    page.fill("[data-testid=token]", "токен-оператора")
    page.click("[data-testid=sign-in]")
    expect(page.get_by_test_id("sequence-status")).to_have_text(
        "Not signed in: wrong token: unknown token"
    )
    # a tab that signed in, and its token revoked since: the reload says so
    sign_in(page, _operator_token(server, "revoked1"), "revoked1 · operator")
    _revoke(server, "revoked1")
    page.reload()
    expect(page.get_by_test_id("sequence-status")).to_have_text(
        "Signed out: wrong token: token revoked"
    )
    expect(page.get_by_test_id("signed-in")).to_have_text("reading only")
    # the once-a-second poll finds the revocation first: a reload after it still says why
    sign_in(page, _operator_token(server, "revoked2"), "revoked2 · operator")
    _revoke(server, "revoked2")
    expect(page.get_by_test_id("sequence-status")).to_have_text(
        "Signed out: wrong token: token revoked"
    )
    page.reload()
    expect(page.get_by_test_id("sequence-status")).to_have_text(
        "Signed out: wrong token: token revoked"
    )
    # ... once: the next reload is a plain page that reads
    page.reload()
    expect(page.get_by_test_id("signed-in")).to_have_text("reading only")
    expect(page.get_by_test_id("sequence-status")).to_have_text("")
    page.close()


def test_a_tab_reading_with_another_tabs_sign_in_may_not_act(
    context: BrowserContext,
    server: str,  # noqa: F811
) -> None:
    """The cookie is for reading; the token is kept per tab. A second tab would be
    answered 401 "token required" if it acted, so it says it must sign in first."""
    first = _open(context, server)
    sign_in(first)
    second = _open(context, server)
    expect(second.get_by_test_id("signed-in")).to_have_text("bootstrap · reading (sign in to act)")
    expect(second.locator("#pause")).to_be_disabled()
    expect(second.locator("#pause")).to_have_attribute("title", re.compile("sign in in this tab"))
    sign_in(second)  # the second tab signed in acts
    expect(second.locator("#pause")).to_be_enabled()
    second.close()
    first.close()


def test_the_speed_selector_shows_the_servers_speed(
    context: BrowserContext,
    server: str,  # noqa: F811
) -> None:
    r = httpx.post(f"{server}/api/rovers/spirit/clock", json={"speed": 10}, headers=ADMIN)
    assert r.status_code == 200, r.text
    page = _open(context, server)
    expect(page.get_by_test_id("clock-speed")).to_have_text("running at 10×")
    expect(page.locator("#speed")).to_have_value("10")
    # a change the server refuses: the selector goes back, the status says the API's words
    # (the refusal is played by the test: the console lets no one make a refused change)
    sign_in(page)
    refusal = {"detail": "bootstrap is admin: this needs the flight director role"}
    page.route("**/api/rovers/spirit/clock", lambda route: route.fulfill(status=403, json=refusal))
    page.select_option("#speed", "1000")
    expect(page.get_by_test_id("sequence-status")).to_have_text(
        f"Clock not changed: {refusal['detail']}"
    )
    expect(page.locator("#speed")).to_have_value("10")
    page.unroute("**/api/rovers/spirit/clock")
    # a speed set over the API that the selector does not list is shown as it is
    httpx.post(f"{server}/api/rovers/spirit/clock", json={"speed": 20}, headers=ADMIN)
    expect(page.locator("#speed")).to_have_value("20")
    expect(page.get_by_test_id("clock-speed")).to_have_text("running at 20×")
    page.close()


def test_after_plant_site_the_site_estimate_and_the_mission_error_are_apart(
    context: BrowserContext,
    server: str,  # noqa: F811
) -> None:
    page = _open(context, server)
    sign_in(page)
    page.select_option("#speed", "max")
    page.fill("#editor", "SEQUENCE drive_then_plant\nDRIVE_STRAIGHT distance_m=6\nPLANT_SITE\n")
    page.click("#upload-text")
    expect(page.get_by_test_id("sequence-status")).to_contain_text("queued")
    position = page.get_by_test_id("position")
    # the estimate at the new Site's origin, with the rover's own 2σ beside it (its position
    # uncertainty carries over: the drive's, grown with the heading unknown)
    expect(position).to_have_text(
        re.compile(r"^Site [1-9]\d*: est \(0\.00, 0\.00\) m ± \d+\.\d\d m \(2σ\)$")
    )
    frame = _wait(
        lambda: (
            (s := httpx.get(f"{server}/api/rovers/spirit/state").json())["queue"] == []
            and not s["executing"]
            and s["frame"]
        )
    )
    assert frame["position_error_m"] >= 0.005, frame  # a drive leaves an error to show
    error = page.get_by_test_id("position-error")
    expect(error).to_have_text(re.compile(rf"^{frame['position_error_m']:.2f} m \(mission frame"))
    expect(page.locator("dt.truth-view", has_text="Position error")).to_contain_text("truth")
    # at max with nothing queued the clock runs in real time, and the header says so
    expect(page.get_by_test_id("clock-speed")).to_have_text("running at 1× (max, idle)")
    expect(page.locator("#speed")).to_have_value("max")
    page.locator("section.readouts").screenshot(path=str(ARTIFACTS / "readouts_after_plant.png"))
    page.close()


def test_a_failed_upload_clears_the_old_diagnostics(
    context: BrowserContext,
    server: str,  # noqa: F811
    tmp_path: Path,
) -> None:
    page = _open(context, server)
    sign_in(page)
    held: list[Route] = []  # the editor's own check, answered only after both uploads
    page.route("**/api/sequences/validate*", lambda route: held.append(route))
    with page.expect_request("**/api/sequences/validate*"):  # 300 ms after the last key
        page.fill("#editor", BAD)
    page.click("#upload-text")
    status = page.get_by_test_id("sequence-status")
    expect(status).to_contain_text("Rejected: 2 error(s)")
    diagnostics = page.get_by_test_id("validation-errors").locator("li")
    expect(diagnostics).to_have_count(2)
    row = page.locator("#sequences tbody tr").first
    expect(row).to_contain_text("broken")
    expect(row).to_contain_text(re.compile(r"rejected: 2 errors: line 2: .*; line 4: "))
    # A file's diagnostics go under the file's name; the editor's list keeps describing the
    # editor's text. A failed upload of another file clears the first file's diagnostics.
    file_head = page.get_by_test_id("file-result-head")
    file_diagnostics = page.get_by_test_id("file-diagnostics").locator("li")
    bad = tmp_path / "bad.seq"
    bad.write_text(BAD)
    page.set_input_files("[data-testid=file-input]", str(bad))
    page.click("#upload-file")
    expect(file_head).to_have_text("bad.seq: Rejected: 2 error(s), nothing queued")
    expect(file_diagnostics).to_have_count(2)
    big = tmp_path / "big.seq"
    big.write_text("SEQUENCE big\n" + "# padding\n" * 120_000)  # over the 1 MB limit
    page.set_input_files("[data-testid=file-input]", str(big))
    page.click("#upload-file")
    refused = r"Upload failed \(413\): body over the upload limit of 1 MB \(1000000 bytes\)$"
    expect(status).to_have_text(re.compile("^" + refused))
    expect(file_head).to_have_text(re.compile(r"^big\.seq: " + refused))
    expect(file_diagnostics).to_have_count(0)
    expect(diagnostics).to_have_count(2)  # the editor's text, unchanged
    # the editor's check comes back late (a busy server): it is not shown over the upload's
    assert len(held) == 1
    with page.expect_response("**/api/sequences/validate*") as late:
        held[0].continue_()
    late.value.finished()  # its body read; then the page's tasks queued behind it have run
    page.evaluate("() => new Promise(r => setTimeout(() => setTimeout(r)))")
    expect(diagnostics).to_have_count(2)
    expect(file_diagnostics).to_have_count(0)
    page.close()
