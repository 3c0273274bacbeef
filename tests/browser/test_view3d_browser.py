"""Two viewers of one rover's 3D view in a real browser (issue 13, defect 9): while the
rover drives, viewer A drags its "Sol time" slider back to the start of the sol and sees
the rover where it was then, and viewer B, untouched, keeps following live: B's "Follow
live" stays ticked and B's rover and status keep moving on while A's stay in the past.
Then A follows again and sees the live rover. viser's client state is read through
``window.__viserMutable`` and the page's own controls. Screenshots go to test-artifacts/."""

from __future__ import annotations

import math
import re
from collections.abc import Iterator

import httpx
import pytest

from tests.browser.test_console_browser import ARTIFACTS, CHROMIUM, LAUNCH_ARGS
from tests.server.test_server_restart import serving

from playwright.sync_api import Frame, Locator, Page, expect, sync_playwright  # isort: skip

TOKEN = "view3d-browser-token"
DRIVE = "SEQUENCE two_viewers\nDRIVE_STRAIGHT distance_m=100\n"  # 2,667 s at 3.75 cm/s
SPEED = 10  # simulated s per wall s: 0.375 m a second; the drive outlasts the test
TIMEOUT_MS = 90_000  # generous: the test must pass with both cores busy
# The two viewers' pages: both draw their scene in software (SwiftShader) all along, at a
# cost that grows with their pixels; what they show is read from viser's state, not pixels.
VIEWER = {"width": 1280, "height": 480}
LIVE = re.compile(r"LMST \(live\)")
REPLAY = re.compile(r"LMST \(replay\)")
STATUS = re.compile(r"Sol \d+ \d\d:\d\d LMST \((?:live|replay)\)")

ROVER_AT = "() => { const n = window.__viserMutable?.nodeRefFromName?.['/rover'];"
ROVER_AT += " return n ? n.position.toArray() : null; }"
MOVED_FROM = (
    "([p, d]) => { const n = window.__viserMutable?.nodeRefFromName?.['/rover'];"
    " return !!n && Math.hypot(n.position.x - p[0], n.position.y - p[1]) > d; }"
)


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    with serving(
        tmp_path_factory.mktemp("view3d"), TOKEN, ready="/api/rovers/spirit/scene"
    ) as base:
        yield base


def _position(page: Page) -> list[float]:
    position: list[float] | None = page.evaluate(ROVER_AT)
    assert position is not None
    return position


def _status(page: Page) -> str:
    return page.get_by_text(STATUS).inner_text()


def _follow(page: Page) -> Locator:
    return page.get_by_label("Follow live")


def test_one_viewer_scrubs_while_the_other_keeps_following(server: str) -> None:
    ARTIFACTS.mkdir(exist_ok=True)
    expect.set_options(timeout=TIMEOUT_MS)
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=LAUNCH_ARGS)
        a = browser.new_page(viewport=VIEWER)
        b = browser.new_page(viewport=VIEWER)
        try:
            for page in (a, b):
                page.set_default_timeout(TIMEOUT_MS)
                page.goto(f"{server}/viser/spirit/")
                page.wait_for_function(ROVER_AT)
                expect(page.get_by_text(LIVE)).to_be_visible()
                expect(_follow(page)).to_be_checked()
            start = _position(b)

            auth = {"Authorization": f"Bearer {TOKEN}"}
            answer = httpx.post(
                f"{server}/api/rovers/spirit/clock", json={"speed": SPEED}, headers=auth
            )
            assert answer.status_code == 200, answer.text
            answer = httpx.post(
                f"{server}/api/rovers/spirit/sequences", json={"text": DRIVE}, headers=auth
            )
            assert answer.status_code == 201, answer.text
            b.wait_for_function(MOVED_FROM, arg=[start, 1.0])  # the rover is under way

            # A scrubs back to the start of the sol.
            thumb = a.get_by_role("slider")
            thumb.focus()
            thumb.press("Home")
            expect(a.get_by_text(REPLAY)).to_be_visible()
            expect(_follow(a)).not_to_be_checked()
            a.wait_for_function(
                "p => { const n = window.__viserMutable.nodeRefFromName['/rover'];"
                " return Math.hypot(n.position.x - p[0], n.position.y - p[1]) < 0.2; }",
                arg=start,
            )
            a_status = _status(a)

            # B follows on: its rover and its status move while A's stay.
            expect(_follow(b)).to_be_checked()
            expect(b.get_by_text(LIVE)).to_be_visible()
            b_at, b_status = _position(b), _status(b)
            b.wait_for_function(MOVED_FROM, arg=[b_at, 1.0])
            expect(b.get_by_text(STATUS)).not_to_have_text(b_status)
            expect(b.get_by_text(LIVE)).to_be_visible()
            expect(_follow(b)).to_be_checked()
            a_at = _position(a)
            assert math.hypot(a_at[0] - start[0], a_at[1] - start[1]) < 0.2
            assert _status(a) == a_status
            expect(_follow(a)).not_to_be_checked()
            a.screenshot(path=str(ARTIFACTS / "view3d_viewer_a_replay.png"))
            b.screenshot(path=str(ARTIFACTS / "view3d_viewer_b_live.png"))

            # A follows again: the live rover, where B sees it.
            _follow(a).check()
            expect(a.get_by_text(LIVE)).to_be_visible()
            b_at = _position(b)
            a.wait_for_function(
                MOVED_FROM, arg=[start, math.hypot(b_at[0] - start[0], b_at[1] - start[1]) - 0.5]
            )
        except Exception:
            a.screenshot(path=str(ARTIFACTS / "view3d_viewer_a_failed.png"))
            b.screenshot(path=str(ARTIFACTS / "view3d_viewer_b_failed.png"))
            raise
        finally:
            browser.close()


SCENE_LOADED = "() => !!window.__viserMutable?.nodeRefFromName?.['/terrain/ground']"


def _view_frame(page: Page) -> Frame:
    handle = page.get_by_test_id("view3d").element_handle()
    frame = handle.content_frame() if handle else None
    assert frame is not None
    return frame


def _viser_targets(page: Page) -> list[str]:
    """The URLs of the browser's out-of-process frames showing a 3D view (Chromium's CDP
    lists a frame that renders in a process of its own as a target of type iframe)."""
    cdp = page.context.browser.new_browser_cdp_session()  # type: ignore[union-attr]
    targets = cdp.send("Target.getTargets")["targetInfos"]
    return [t["url"] for t in targets if t["type"] == "iframe" and "/viser/" in t["url"]]


def test_the_console_answers_with_the_view_running_and_collapsing_unloads_it(server: str) -> None:
    """Issue 21, the 3D view freezes the console without a GPU: in this browser WebGL is
    software (SwiftShader). With the view shown and drawing, sign-in and a clock command
    complete; the view renders in a process of its own, not on the console's thread; its
    toggle collapses it, which unloads the frame, and this browser remembers that over a
    reload; shown again, the view loads again."""
    ARTIFACTS.mkdir(exist_ok=True)
    expect.set_options(timeout=TIMEOUT_MS)
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=LAUNCH_ARGS)
        page = browser.new_page(viewport={"width": 1280, "height": 800})
        page.set_default_timeout(TIMEOUT_MS)
        try:
            page.goto(f"{server}/?rover=spirit")
            toggle = page.get_by_test_id("view3d-toggle")
            expect(toggle).to_have_attribute("aria-expanded", "true")  # shown: a fresh browser
            frame = _view_frame(page)
            frame.wait_for_function(SCENE_LOADED)  # the view is loaded and drawing
            assert any(u.startswith(frame.url) for u in _viser_targets(page)), frame.url

            expect(page.get_by_test_id("signed-in")).to_have_attribute(
                "data-role", re.compile(".*")
            )
            page.fill("[data-testid=token]", TOKEN)
            page.click("[data-testid=sign-in]")
            expect(page.get_by_test_id("signed-in")).to_have_text("bootstrap · admin")
            speed = page.get_by_test_id("clock-speed")
            expect(speed).to_contain_text("running")
            page.click("#pause")
            expect(speed).to_contain_text("paused")
            page.click("#resume")
            expect(speed).to_contain_text("running")
            page.screenshot(path=str(ARTIFACTS / "view3d_shown.png"))

            toggle.click()  # collapse
            expect(toggle).to_have_attribute("aria-expanded", "false")
            view = page.get_by_test_id("view3d")
            expect(view).to_be_hidden()
            expect(view).to_have_attribute("src", "about:blank")
            page.wait_for_function(
                "() => document.getElementById('view3d').contentWindow.location.href"
                " === 'about:blank'"
            )
            assert _view_frame(page).evaluate("() => window.__viserMutable") is None
            assert _viser_targets(page) == []  # no process draws it any more
            page.screenshot(path=str(ARTIFACTS / "view3d_collapsed.png"))

            page.reload()  # remembered by this browser
            expect(toggle).to_have_attribute("aria-expanded", "false")
            expect(page.get_by_test_id("sol-clock")).to_contain_text("LMST")
            expect(view).to_have_attribute("src", "about:blank")

            toggle.click()  # shown again: loaded again
            expect(toggle).to_have_attribute("aria-expanded", "true")
            expect(view).to_be_visible()
            _view_frame(page).wait_for_function(SCENE_LOADED)
        except Exception:
            page.screenshot(path=str(ARTIFACTS / "view3d_toggle_failed.png"))
            raise
        finally:
            browser.close()
