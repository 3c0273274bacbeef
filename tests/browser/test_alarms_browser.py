"""Alarms in two real browsers (Chromium, Playwright) on one server (TESTING.md): a new
rover raises its alarms (attitude Unknown: AQF and both HGA margins, the true one marked as
the truth view), a Fine attitude clears them and browser A acknowledges them while browser
B follows without a reload; then an operator tightens the true HGA margin's limit in A's
limits editor, a drive lets the attitude drift until the margin falls below it (a warning,
truth view), A acknowledges it, B sees who did, the limit put back to its default clears it,
and the sol timeline's Alarms lane shows it. Screenshots in test-artifacts/."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from typing import Any

import httpx
from playwright.sync_api import Browser, Page, expect, sync_playwright

from tests.browser.test_console_browser import (
    ARTIFACTS,
    CHROMIUM,
    LAUNCH_ARGS,
    TOKEN,
    server,  # noqa: F401  (the module's server fixture)
    sign_in,
)
from tests.server.test_server_restart import _wait

AUTH = {"Authorization": f"Bearer {TOKEN}"}


@contextlib.contextmanager
def two_consoles(url: str) -> Iterator[tuple[Page, Page]]:
    """Two consoles in separate browser contexts (each its own session), at 1280x800."""
    ARTIFACTS.mkdir(exist_ok=True)
    with sync_playwright() as p:
        browser: Browser = p.chromium.launch(executable_path=CHROMIUM, args=LAUNCH_ARGS)
        pages = []
        for _ in range(2):
            page = browser.new_context(viewport={"width": 1280, "height": 800}).new_page()
            page.goto(url)
            pages.append(page)
        try:
            yield pages[0], pages[1]
        finally:
            for name, page in zip(("alarms_a.png", "alarms_b.png"), pages, strict=True):
                page.screenshot(path=str(ARTIFACTS / name), full_page=True)
            browser.close()


def _alarms(base: str) -> list[dict[str, Any]]:
    alarms: list[dict[str, Any]] = httpx.get(f"{base}/api/rovers/spirit/alarms").json()
    return alarms


def _run(base: str, command: str, **args: Any) -> None:
    """An immediate command, waited for until the queue is empty and played out."""
    r = httpx.post(f"{base}/api/rovers/spirit/commands", headers=AUTH,
                   json={"command": command, "args": args})  # fmt: skip
    assert r.status_code == 201, r.text

    def done() -> bool:
        state = httpx.get(f"{base}/api/rovers/spirit/state").json()
        return not state["queue"] and not state["executing"]

    _wait(done, 120.0)


def test_alarms_raise_acknowledge_clear_in_two_browsers(server: str) -> None:  # noqa: F811
    # The new rover's attitude is Unknown: AQF and both margins alarm with the first frames
    # (a finite speed: at max an idle rover's clock stands still).
    r = httpx.post(f"{server}/api/rovers/spirit/clock", headers=AUTH, json={"speed": 100})
    assert r.status_code == 200
    startup = _wait(lambda: len(_alarms(server)) >= 3 and _alarms(server))
    httpx.post(f"{server}/api/rovers/spirit/clock", headers=AUTH, json={"speed": "max"})
    assert {(a["channel"], a["level"], a["truth"]) for a in startup} >= {
        ("aqf", "critical", False),
        ("hga_margin_predicted_deg", "critical", False),
        ("hga_margin_deg", "critical", True),
    }
    with two_consoles(f"{server}/?rover=spirit") as (a, b):
        sign_in(a)
        sign_in(b)
        for page in (a, b):
            banner = page.get_by_test_id("alarm-banner")
            expect(banner).to_be_visible()
            expect(banner).to_have_attribute("data-level", "critical")
            expect(banner.get_by_test_id("alarm-count")).to_contain_text("CRITICAL")
            truth_row = page.locator("[data-testid=alarm-row][data-channel=hga_margin_deg]")
            expect(truth_row.get_by_test_id("truth-tag")).to_be_visible()
        a.screenshot(path=str(ARTIFACTS / "alarms_startup.png"))

        # A Fine attitude brings every value back inside: cleared, still listed until
        # acknowledged. A acknowledges them; B follows without a reload.
        _run(server, "GET_FINE_ATTITUDE")
        cleared = b.locator("[data-testid=alarm-row][data-cleared=true]")
        expect(cleared).to_have_count(len(startup))
        for _ in range(len(startup)):
            a.get_by_test_id("alarm-ack").first.click()
        expect(b.locator("[data-testid=alarm-row][data-acknowledged=false]")).to_have_count(0)
        expect(b.get_by_test_id("alarm-banner")).to_be_hidden()

        # An operator tightens the true margin's warning just under its value, in A.
        frame = httpx.get(f"{server}/api/rovers/spirit/state").json()["frame"]
        assert frame["earth_up"] and frame["aqf"] == "Fine"
        margin = frame["hga_margin_deg"]
        a.click("#limits-editor summary")
        row = a.locator("[data-testid=limits-row][data-channel=hga_margin_deg]")
        row.locator("input[name=warning]").fill(f"{margin - 0.03:.3f}")
        row.get_by_test_id("limits-save").click()
        expect(a.get_by_test_id("limits-status")).to_contain_text("saved")
        assert not [x for x in _alarms(server) if x["acknowledged"] is None]

        # A drive: the gyros drift, the true margin falls below the limit.
        _run(server, "DRIVE_STRAIGHT", distance_m=10.0)
        raised = b.locator("[data-testid=alarm-row][data-channel=hga_margin_deg]"
                           "[data-acknowledged=false]")  # fmt: skip
        expect(raised).to_have_count(1)
        expect(raised).to_have_attribute("data-level", "warning")
        for page in (a, b):
            banner = page.get_by_test_id("alarm-banner")
            expect(banner).to_have_attribute("data-level", "warning")
            expect(banner.get_by_test_id("alarm-banner-message")).to_contain_text("hga_margin_deg")
            expect(banner.get_by_test_id("truth-tag")).to_be_visible()
        b.screenshot(path=str(ARTIFACTS / "alarms_raised_b.png"))
        alarm = next(x for x in _alarms(server) if x["acknowledged"] is None)
        assert alarm["truth"] and alarm["value"] < alarm["limit"] == round(margin - 0.03, 3)
        assert alarm["raised"]["utc"] and 0 <= alarm["raised"]["lmst_h"] < 24

        # A acknowledges; B sees who did, without a reload.
        a.locator(f"[data-testid=alarm-row][data-alarm-id='{alarm['id']}']").get_by_test_id(
            "alarm-ack"
        ).click()
        acked = b.locator(f"[data-testid=alarm-row][data-alarm-id='{alarm['id']}']")
        expect(acked.get_by_test_id("alarm-acknowledged")).to_contain_text("bootstrap")
        expect(b.get_by_test_id("alarm-banner")).to_be_hidden()

        # The limit back to its default: the margin is inside again, the alarm clears.
        row.get_by_test_id("limits-reset").click()
        expect(acked).to_have_attribute("data-cleared", "true")
        done = httpx.get(f"{server}/api/rovers/spirit/alarms", params={"active": "false"}).json()
        assert alarm["id"] in {x["id"] for x in done}

        # The sol timeline shows it in its Alarms lane.
        b.click("#timeline-refresh")
        lane = b.locator("[data-testid=timeline-alarm][data-channel=hga_margin_deg]")
        expect(lane.and_(b.locator("[data-level=warning]"))).to_have_count(1)
        b.get_by_test_id("timeline-panel").screenshot(path=str(ARTIFACTS / "alarms_timeline.png"))

        # The panel fits a narrow window (its tables scroll inside it, not the page).
        for width in (760, 1280, 1920):
            b.set_viewport_size({"width": width, "height": 900})
            box = b.get_by_test_id("alarms-panel").bounding_box()
            assert box is not None and box["x"] >= 0 and box["x"] + box["width"] <= width
            b.get_by_test_id("alarms-panel").screenshot(
                path=str(ARTIFACTS / f"alarms-panel-{width}.png")
            )
