"""Alarms in two real browsers (Chromium, Playwright) on one server (TESTING.md): a new
rover raises one alarm (attitude Unknown: the AQF; its predicted HGA margin reads "no
attitude" and alarms nothing, issue 21), a Fine attitude clears it, a second acquisition
raises nothing (shelved while it runs), a NADIR_UPDATE raises it again with its latest value
beside the one that raised it, and the timeline draws its two active spans, no bar where the
AQF was Fine; A shelves it and unshelves it, acknowledges it while browser B follows
without a reload; then an operator sets a limit on the true HGA margin (a truth-view
channel with no default levels) in A's limits editor, a drive lets the attitude drift
until the margin falls below it (a warning, truth view), A acknowledges it, B sees who
did, the limit put back to its default clears it, and the sol timeline's Alarms lane shows
it. Screenshots in test-artifacts/."""

from __future__ import annotations

import contextlib
import re
from collections.abc import Iterator
from typing import Any

import httpx
import pytest
from playwright.sync_api import Browser, Page, expect, sync_playwright

from tests.browser.test_console_browser import ARTIFACTS, CHROMIUM, LAUNCH_ARGS, TOKEN, sign_in
from tests.server.test_server_restart import _wait, serving

AUTH = {"Authorization": f"Bearer {TOKEN}"}


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """The real server without its 3D views: the consoles below never load them (their
    viser frames are aborted), so their scenes would be drawn with nobody watching."""
    with serving(tmp_path_factory.mktemp("alarms"), TOKEN, three_d=False) as base:
        yield base


@contextlib.contextmanager
def two_consoles(url: str) -> Iterator[tuple[Page, Page]]:
    """Two consoles in separate browser contexts (each its own session), at 1280x800."""
    ARTIFACTS.mkdir(exist_ok=True)
    with sync_playwright() as p:
        browser: Browser = p.chromium.launch(executable_path=CHROMIUM, args=LAUNCH_ARGS)
        pages = []
        for _ in range(2):
            page = browser.new_context(viewport={"width": 1280, "height": 800}).new_page()
            # the alarms, not the 3D view: without a GPU its viser iframe can freeze the page
            # (issue 21, another part of it), and two consoles here are two of them
            page.route("**/viser/**", lambda route: route.abort())
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


def test_alarms_raise_acknowledge_clear_in_two_browsers(server: str) -> None:
    # The new rover's attitude is Unknown: the AQF alarms with the first frames, and only it
    # (a finite speed: at max an idle rover's clock stands still).
    r = httpx.post(f"{server}/api/rovers/spirit/clock", headers=AUTH, json={"speed": 100})
    assert r.status_code == 200
    startup = _wait(lambda: _alarms(server))
    httpx.post(f"{server}/api/rovers/spirit/clock", headers=AUTH, json={"speed": "max"})
    assert [(a["channel"], a["level"], a["truth"]) for a in startup] == [("aqf", "critical", False)]
    with two_consoles(f"{server}/?rover=spirit") as (a, b):
        sign_in(a)
        sign_in(b)
        for page in (a, b):
            banner = page.get_by_test_id("alarm-banner")
            expect(banner).to_be_visible()
            expect(banner).to_have_attribute("data-level", "critical")
            expect(banner.get_by_test_id("alarm-count")).to_contain_text("CRITICAL")
            expect(page.get_by_test_id("hga-margin-predicted")).to_have_text("no attitude")
        a.screenshot(path=str(ARTIFACTS / "alarms_startup.png"))

        # A Fine attitude clears it (listed until acknowledged); a second acquisition passes
        # through Unknown again, expected: not raised again.
        _run(server, "GET_FINE_ATTITUDE")
        aqf_row = b.locator("[data-testid=alarm-row][data-channel=aqf]")
        expect(aqf_row).to_have_attribute("data-cleared", "true")
        expect(a.get_by_test_id("hga-margin-predicted")).to_have_text(re.compile(r"^\d\.\d\d°$"))
        _run(server, "GET_FINE_ATTITUDE")
        (aqf,) = _alarms(server)
        assert (aqf["violations"], aqf["cleared"] is not None) == (1, True)

        # A NADIR_UPDATE leaves TiltOnly: raised again, its worst value Unknown (critical)
        # beside its latest, TiltOnly, with that value's time.
        _run(server, "NADIR_UPDATE")
        expect(aqf_row).to_have_attribute("data-cleared", "false")
        expect(aqf_row.get_by_test_id("alarm-latest")).to_contain_text("TiltOnly")
        (aqf,) = _alarms(server)
        assert (aqf["level"], aqf["value"], aqf["latest"]["value"]) == (
            "critical", "Unknown", "TiltOnly",
        )  # fmt: skip

        # The Alarms lane: two spans (Unknown to Coarse, and since the NADIR_UPDATE), none
        # over the AQF's Fine bands.
        b.click("#timeline-refresh")
        bars = b.locator("[data-testid=timeline-alarm][data-channel=aqf]")
        expect(bars).to_have_count(2)
        fine = b.locator("[data-testid=timeline-aqf][data-value=Fine]")
        expect(fine.first).to_be_visible()
        edges = (
            "els => els.map(e => [e.getBoundingClientRect().left, e.getBoundingClientRect().right])"
        )
        fine_x = fine.evaluate_all(edges)
        bars_x = bars.evaluate_all(edges)
        assert all(right > left for left, right in bars_x), bars_x
        for f0, f1 in fine_x:
            for x0, x1 in bars_x:
                assert min(f1, x1) - max(f0, x0) <= 1.5, (fine_x, bars_x)
        b.get_by_test_id("timeline-panel").screenshot(path=str(ARTIFACTS / "alarms_spans.png"))

        # A shelves it for an hour: gone from the banner in both, back once unshelved.
        a.locator("[data-testid=alarm-row][data-channel=aqf]").get_by_test_id(
            "alarm-shelve"
        ).click()
        expect(aqf_row).to_have_attribute("data-shelved", "true")
        expect(aqf_row.get_by_test_id("alarm-shelved")).to_contain_text("shelved by bootstrap")
        expect(b.get_by_test_id("alarm-banner")).to_be_hidden()
        a.locator("[data-testid=alarm-row][data-channel=aqf]").get_by_test_id(
            "alarm-unshelve"
        ).click()
        expect(b.get_by_test_id("alarm-banner")).to_be_visible()

        # A acknowledges it; a Fine attitude clears it; B follows without a reload.
        a.get_by_test_id("alarm-ack").first.click()
        _run(server, "GET_FINE_ATTITUDE")
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
