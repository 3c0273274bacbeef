"""The images the rover sends, in a real browser (Debian's Chromium driven by Playwright,
TESTING.md) against the real server on a temporary database: an operator uploads a short
``vo=on vo_keep_images=on`` drive in the console and runs it at full speed; the drive's VO
pairs appear as marks on the sol timeline's Images lane, and a click on a converged step's
mark opens the pair: both images load (decoded: ``naturalWidth`` > 0), and the features,
tracked features and inliers drawn over the left image are as many as the API says, inliers
and outliers apart. The 3D view beside it then shows the ground's map refined by those three
pairs (its terrain note counts them). Screenshots go to test-artifacts/."""

from __future__ import annotations

import re
from collections.abc import Iterator

import httpx
import pytest
from playwright.sync_api import Browser, Page, expect, sync_playwright

from tests.browser.test_console_browser import ARTIFACTS, CHROMIUM, LAUNCH_ARGS, sign_in
from tests.browser.test_view3d_browser import SCENE_LOADED, TIMEOUT_MS, VIEWER, _view_frame
from tests.server.test_server_restart import _wait, serving

TOKEN = "images-browser-token"
AUTH = {"Authorization": f"Bearer {TOKEN}"}
DRIVE = "SEQUENCE vo_images\nDRIVE_STRAIGHT distance_m=1.2 vo=on vo_keep_images=on\n"


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    with serving(
        tmp_path_factory.mktemp("images_browser"),
        TOKEN,
        ready="/api/rovers/spirit/scene",
        three_d=True,
    ) as base:
        yield base


@pytest.fixture(scope="module")
def browser() -> Iterator[Browser]:
    ARTIFACTS.mkdir(exist_ok=True)
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=LAUNCH_ARGS)
        try:
            yield b
        finally:
            b.close()


@pytest.fixture
def page(browser: Browser, server: str) -> Iterator[Page]:
    context = browser.new_context(viewport={"width": 1280, "height": 900})
    pg = context.new_page()
    pg.goto(f"{server}/?rover=spirit")
    try:
        yield pg
    finally:
        context.close()


def test_a_vo_pair_opens_from_its_mark_with_its_features_drawn(page: Page, server: str) -> None:
    sign_in(page, TOKEN, "bootstrap · admin")
    page.fill("#editor", DRIVE)
    page.click("#upload-text")
    expect(page.get_by_test_id("sequence-status")).to_contain_text("queued")
    page.select_option("#speed", "max")
    with httpx.Client(base_url=server, timeout=10.0, headers=AUTH) as c:
        _wait(lambda: c.get("/api/rovers/spirit/sequences").json()[0]["status"] == "completed")
        _wait(lambda: not c.get("/api/rovers/spirit/state").json()["executing"])
        listed = c.get("/api/rovers/spirit/images").json()
    assert listed["total"] == 3  # the first pair and one after each of the two steps
    converged = [
        i for i in listed["images"] if i["vo"]["status"] == "converged" and i["vo"]["step"]
    ]
    assert converged, [i["vo"] for i in listed["images"]]
    chosen = converged[-1]
    marks = page.get_by_test_id("timeline-image")
    expect(marks).to_have_count(3, timeout=30_000)  # read with the sol, or after the command
    mark = page.locator(f"[data-testid=timeline-image][data-image-id='{chosen['id']}']")
    expect(mark).to_have_attribute("data-status", "converged")
    mark.click()
    dialog = page.get_by_test_id("image-dialog")
    expect(dialog).to_be_visible()
    expect(dialog).to_have_attribute("data-loaded", "1", timeout=30_000)
    for side in ("image-left", "image-right"):
        width = page.get_by_test_id(side).evaluate("img => img.complete ? img.naturalWidth : 0")
        assert width == chosen["width_px"] == 256
    with httpx.Client(base_url=server, timeout=10.0, headers=AUTH) as c:
        detail = c.get(f"/api/rovers/spirit/images/{chosen['id']}").json()
    features = detail["features"]
    assert len(features["features_uv_px"]) == detail["vo"]["n_features"] > 0
    overlay = page.get_by_test_id("image-overlay")
    expect(overlay.get_by_test_id("feature-marker")).to_have_count(detail["vo"]["n_features"])
    tracked = overlay.get_by_test_id("track-marker")
    expect(tracked).to_have_count(detail["vo"]["n_tracked"])
    expect(overlay.locator("[data-testid=track-marker][data-inlier='1']")).to_have_count(
        detail["vo"]["n_inliers"]
    )
    expect(page.get_by_test_id("image-status")).to_have_text("converged")
    expect(page.get_by_test_id("image-summary")).to_contain_text(
        f"{detail['vo']['n_inliers']} inliers"
    )
    # the marks sit on the image: every drawn pixel inside the rig's frame
    box = overlay.bounding_box()
    img = page.get_by_test_id("image-left").bounding_box()
    assert box is not None and img is not None
    assert abs(box["width"] - img["width"]) <= 1.0 and abs(box["height"] - img["height"]) <= 1.0
    dialog.screenshot(path=str(ARTIFACTS / "vo_pair.png"))
    page.get_by_test_id("image-close").click()
    expect(dialog).to_be_hidden()
    # the ground's map in the 3D view has taken the three pairs (the view draws it again)
    # out of sight the view is paused (display: none): bring its panel into sight
    page.locator("section.view3d").scroll_into_view_if_needed()
    frame = _view_frame(page)
    frame.wait_for_function(SCENE_LOADED, timeout=TIMEOUT_MS)
    page.get_by_test_id("view3d").screenshot(path=str(ARTIFACTS / "ground_map_view3d.png"))
    # the view in a tab of its own ("open in a tab"), its panel open: the terrain's note
    tab = page.context.new_page()
    tab.set_viewport_size({"width": VIEWER["width"], "height": VIEWER["height"]})
    tab.goto(f"{server}/viser/spirit/")
    tab.wait_for_function(SCENE_LOADED, timeout=TIMEOUT_MS)
    note = tab.get_by_text(re.compile("Terrain: the ground.s map"))
    expect(note).to_contain_text("3 stereo pairs", timeout=TIMEOUT_MS)
    tab.screenshot(path=str(ARTIFACTS / "ground_map_tab.png"))
