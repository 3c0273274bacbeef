"""The console in a real browser (Debian's Chromium driven by Playwright, TESTING.md) against
the real server on a temporary database: a sequence with errors shows them at their lines
and queues nothing; with the operator token, the example that runs SUNCHECK_SUNGAZE then a
drive is uploaded as a file and run at full speed, and the readouts show the AQF badge at
Fine, the IMU time reset, the position changed and the HGA margin; the sol timeline shows
the commands and the AQF band; the embedded viser 3D view loads and its rover node moves
(read through ``window.__viserMutable``); nothing overlaps at 1280x800 or 1920x1080.
Screenshots go to test-artifacts/."""

from __future__ import annotations

import contextlib
import os
import re
import shutil
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest

from tests.server.test_server_restart import _wait, serving

CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
ROOT = Path(__file__).resolve().parents[2]
ARTIFACTS = ROOT / "test-artifacts"
TOKEN = "browser-test-token"
LAUNCH_ARGS = [
    "--no-sandbox", "--disable-gpu", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
    "--disable-background-networking", "--disable-component-update", "--disable-sync",
    "--no-first-run",
]  # fmt: skip
BAD = "SEQUENCE broken\nDRIVE_STRAIGHT distance_m=-3\nNADIR_UPDATE\nFLY_AWAY\n"

if not Path(CHROMIUM).exists():
    if os.environ.get("CI"):
        raise RuntimeError("Chromium is missing: `make test` installs Debian's chromium")
    pytest.skip("Chromium not installed (make test installs it)", allow_module_level=True)

from playwright.sync_api import Browser, Frame, Locator, Page, expect, sync_playwright  # noqa: E402


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    with serving(tmp_path_factory.mktemp("console"), TOKEN) as base:
        yield base


@contextlib.contextmanager
def console_page(url: str, screenshot: str) -> Iterator[Page]:
    """Chromium on ``url`` at 1280x800; a full-page screenshot in test-artifacts/ at the end."""
    ARTIFACTS.mkdir(exist_ok=True)
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=LAUNCH_ARGS)
        pg = browser.new_page(viewport={"width": 1280, "height": 800})
        pg.goto(url)
        try:
            yield pg
        finally:
            pg.screenshot(path=str(ARTIFACTS / screenshot), full_page=True)
            browser.close()


@pytest.fixture(scope="module")
def page(server: str) -> Iterator[Page]:
    with console_page(f"{server}/?rover=spirit", "console.png") as pg:
        yield pg


def sign_in(page: Page, token: str = TOKEN, who: str = "bootstrap · admin") -> None:
    """Sign the console in (once: a signed-in page stays signed in)."""
    signed = page.get_by_test_id("signed-in")
    # the console has asked who it is (data-role set): its sign-in handler is attached, and
    # a click before would be lost on a busy machine
    expect(signed).to_have_attribute("data-role", re.compile(".*"))
    if signed.text_content() == who:
        return
    page.fill("[data-testid=token]", token)
    page.click("[data-testid=sign-in]")
    expect(signed).to_have_text(who)


def new_token(server: str, name: str, role: str) -> str:
    """A new user's token, made by the bootstrap admin."""
    r = httpx.post(
        f"{server}/api/users",
        json={"name": name, "role": role},
        headers={"Authorization": f"Bearer {TOKEN}"},
    )
    assert r.status_code == 201, r.text
    token: str = r.json()["token"]
    return token


def open_console(browser: Browser, server: str, token: str, who: str, rover: str) -> Page:
    """A console of ``rover`` in a context of its own, signed in as ``who``."""
    page = browser.new_context(viewport={"width": 1280, "height": 900}).new_page()
    page.goto(f"{server}/?rover={rover}")
    sign_in(page, token, who)
    return page


def test_errors_show_at_their_lines_and_nothing_is_queued(page: Page, server: str) -> None:
    expect(page.get_by_test_id("sol-clock")).to_contain_text("LMST")
    page.fill("#editor", BAD)
    errors = page.get_by_test_id("validation-errors")
    expect(errors).to_contain_text("line 2:")
    expect(errors).to_contain_text("line 4:")
    # not signed in: reading only, the operator's controls greyed out and saying why
    expect(page.get_by_test_id("signed-in")).to_have_text("reading only")
    upload = page.locator("#upload-text")
    expect(upload).to_be_disabled()
    expect(upload).to_have_attribute("title", re.compile("needs the operator role"))
    page.fill("[data-testid=token]", "not-the-token")
    page.click("[data-testid=sign-in]")
    expect(page.get_by_test_id("sequence-status")).to_contain_text("wrong token")
    expect(upload).to_be_disabled()
    sign_in(page)
    page.click("#upload-text")
    expect(page.get_by_test_id("sequence-status")).to_contain_text("Rejected: 2 error(s)")
    assert httpx.get(f"{server}/api/rovers/spirit/state").json()["queue"] == []


IMU_WATCH = """() => {
  const imu = document.querySelector('[data-testid=imu-time]');
  window.__imuSeen = [];
  new MutationObserver(() => window.__imuSeen.push(parseFloat(imu.textContent)))
    .observe(imu, { childList: true, characterData: true, subtree: true });
}"""


def test_fine_attitude_then_drive_runs_and_the_readouts_follow(page: Page, server: str) -> None:
    sign_in(page)
    page.select_option("#speed", "100")
    expect(page.get_by_test_id("clock-speed")).to_contain_text("100", timeout=10_000)
    # A short drive first: IMU time accrues while the gyros are integrated in motion.
    page.select_option("[data-testid=command-picker]", "DRIVE_STRAIGHT")
    page.fill("#args input[name=distance_m]", "2")
    page.click("#send")
    imu = page.get_by_test_id("imu-time")
    expect(imu).to_have_text(re.compile(r"^[3-9]\d s$"), timeout=30_000)
    page.evaluate(IMU_WATCH)
    page.set_input_files(
        "[data-testid=file-input]", str(ROOT / "sequences/examples/fine_attitude_then_drive.seq")
    )
    page.click("#upload-file")
    expect(page.get_by_test_id("sequence-status")).to_contain_text("queued")
    expect(page.get_by_test_id("aqf")).to_have_text("Fine", timeout=60_000)
    expect(page.get_by_test_id("position")).to_contain_text(
        re.compile(r"est \((?:[1-9]|-?\d\.\d*[1-9])"), timeout=60_000
    )
    expect(page.get_by_test_id("hga-margin")).to_contain_text(re.compile(r"°|horizon"))
    # the rover's own prediction beside the truth: at Fine it is a margin, not the -178°
    # of a rover that knows nothing of its heading
    expect(page.get_by_test_id("hga-margin-predicted")).to_have_text(re.compile(r"^\d+\.\d\d°$"))
    _wait(lambda: httpx.get(f"{server}/api/rovers/spirit/state").json()["queue"] == [])
    seen: list[float] = page.evaluate("window.__imuSeen")
    peak = seen.index(max(seen[: len(seen) // 2 + 1]))
    assert min(seen[peak:]) < 10.0 < seen[peak], seen  # the Sungaze reset it to zero
    page.screenshot(path=str(ARTIFACTS / "console_after_drive.png"), full_page=True)


def test_the_sol_timeline_shows_the_commands_and_the_aqf_band(page: Page, server: str) -> None:
    page.click("#timeline-refresh")
    commands = page.get_by_test_id("timeline-command")
    expect(commands.filter(has_text="SUNCHECK_SUNGAZE")).to_have_count(1)
    expect(commands.filter(has_text="DRIVE_STRAIGHT distance_m=10")).to_have_count(1)
    aqf = page.get_by_test_id("timeline-aqf")
    expect(aqf.and_(page.locator("[data-value=Fine]"))).to_have_count(1)
    page.get_by_test_id("timeline-panel").screenshot(path=str(ARTIFACTS / "console_timeline.png"))


def _rover_position(frame: Frame) -> list[float] | None:
    position: list[float] | None = frame.evaluate(
        "() => { const n = window.__viserMutable?.nodeRefFromName?.['/rover'];"
        " return n ? n.position.toArray() : null; }"
    )
    return position


def _view_in_sight(page: Page) -> Locator:
    """The 3D view scrolled into sight, where a shown view must load and draw (out of sight
    it is paused: view3d.js); the earlier steps may have scrolled the page past it."""
    view = page.get_by_test_id("view3d")
    page.locator("#view3d-box").scroll_into_view_if_needed()
    expect(view).not_to_have_class("paused")
    return view


def test_the_3d_view_loads_and_its_rover_node_moves(page: Page, server: str) -> None:
    view = _view_in_sight(page)
    # from the loopback twin of the page's host: its own process (view3d.js)
    expect(view).to_have_attribute("src", re.compile(r"^http://localhost:\d+/viser/spirit/$"))
    handle = view.element_handle()
    frame = handle.content_frame() if handle else None
    assert frame is not None
    frame.wait_for_function("() => window.__viserMutable?.nodeRefFromName?.['/rover']")
    frame.wait_for_function("() => window.__viserMutable.nodeRefFromName['/terrain/ground']")
    before = _rover_position(frame)
    assert before is not None
    answer = httpx.post(
        f"{server}/api/rovers/spirit/commands",
        json={"command": "DRIVE_STRAIGHT", "args": {"distance_m": 2.0}},
        headers={"Authorization": f"Bearer {TOKEN}"},
    )
    assert answer.status_code == 201, answer.text
    frame.wait_for_function(
        "b => { const p = window.__viserMutable.nodeRefFromName['/rover'].position;"
        " return Math.hypot(p.x - b[0], p.y - b[1]) > 1.5; }",
        arg=before,
        timeout=60_000,
    )
    _view_in_sight(page)
    # two animation frames of the view's own: SwiftShader has painted the last pose
    frame.evaluate("new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)))")
    page.locator("#view3d-box").screenshot(path=str(ARTIFACTS / "view3d.png"))


def _sol_of(server: str, command: str) -> int:
    """The sol whose timeline lists ``command`` (the clock runs on meanwhile: the timeline
    opens on the newest sol, which on a slow machine may be a later one)."""
    for sol in httpx.get(f"{server}/api/rovers/spirit/sols").json():
        timeline = httpx.get(f"{server}/api/rovers/spirit/sols/{sol}/timeline").json()
        if any(c["command"] == command for c in timeline["commands"]):
            return int(sol)
    raise AssertionError(f"no sol lists {command}")


def test_a_reload_loses_nothing_and_every_view_follows_the_rover(page: Page, server: str) -> None:
    """Every read waits for its condition (a busy machine slows the page), and the sol is
    picked, not assumed to be the newest. The reload keeps the page's scroll, so the 3D view
    is brought into sight before it is expected to load."""
    page.reload()
    expect(page.get_by_test_id("aqf")).to_have_text("Fine")
    expect(page.locator("#sequences")).to_contain_text("fine_attitude_then_drive")
    sol = str(_sol_of(server, "SUNCHECK_SUNGAZE"))
    expect(page.locator(f"#timeline-sol option[value='{sol}']")).to_have_count(1)
    page.select_option("#timeline-sol", sol)
    timeline = page.get_by_test_id("timeline-command")
    expect(timeline.filter(has_text="SUNCHECK_SUNGAZE")).to_have_count(1)
    view = _view_in_sight(page)
    # from the loopback twin of the page's host: its own process (view3d.js)
    expect(view).to_have_attribute("src", re.compile(r"^http://localhost:\d+/viser/spirit/$"))

    page.select_option("#rover", "opportunity")
    expect(view).to_have_attribute("src", re.compile(r"^http://localhost:\d+/viser/opportunity/$"))
    expect(page.get_by_test_id("aqf")).to_have_text("Unknown")  # never commanded
    expect(timeline.filter(has_text="SUNCHECK_SUNGAZE")).to_have_count(0)
    page.select_option("#rover", "spirit")
    # from the loopback twin of the page's host: its own process (view3d.js)
    expect(view).to_have_attribute("src", re.compile(r"^http://localhost:\d+/viser/spirit/$"))
    expect(page.get_by_test_id("aqf")).to_have_text("Fine")


def _overlaps(page: Page) -> list[str]:
    """Pairs of the page's panels whose boxes intersect, a sideways scroll, a header on more
    than one line from 1280 px up, and anything over the 3D view's frame."""
    boxes = page.evaluate(
        """() => [...document.querySelectorAll(
                    '#alarm-banner, header, main > section, body > section')]
              .map(e => { const r = e.getBoundingClientRect();
                          return [e.className || e.tagName, r.left, r.top, r.right, r.bottom]; })"""
    )
    found = []
    for i, (a, al, at, ar, ab) in enumerate(boxes):
        for b, bl, bt, br, bb in boxes[i + 1 :]:
            if al < br - 0.5 and bl < ar - 0.5 and at < bb - 0.5 and bt < ab - 0.5:
                found.append(f"{a} overlaps {b}")
    if page.evaluate("document.scrollingElement.scrollWidth > window.innerWidth"):
        found.append("the page scrolls sideways")
    header = page.evaluate(
        """() => [...document.querySelectorAll('header > *')].map(e => e.getBoundingClientRect())
              .filter(r => r.width > 0).map(r => [r.top, r.bottom])"""
    )
    lines = max(b for _, b in header) - min(t for t, _ in header)
    if page.viewport_size and page.viewport_size["width"] >= 1280 and lines > 40:
        found.append(f"the header takes {lines:.0f} px: more than one line")
    covered = page.evaluate(
        """() => { const f = document.getElementById('view3d'); f.scrollIntoView();
                   const r = f.getBoundingClientRect();
                   // the part of the frame on screen: the frame may be taller than the
                   // window when the readouts beside it grow, and a point below the
                   // window's edge hits nothing at all
                   const top = Math.max(r.top, 0), bottom = Math.min(r.bottom, innerHeight);
                   return [[.5, .5], [.05, .95], [.95, .95], [.95, .05], [.05, .05]]
                     .map(([x, y]) => document.elementFromPoint(r.left + x * r.width,
                                                               top + y * (bottom - top)))
                     .filter(e => e !== f).map(e => e ? e.tagName : 'nothing'); }"""
    )
    found += [f"{tag} covers the 3D view" for tag in covered]
    page.evaluate("window.scrollTo(0, 0)")
    return found


CANVAS_AT = """([x, y]) => { const e = document.elementFromPoint(innerWidth * x, innerHeight * y);
                             return e !== null && e.tagName === 'CANVAS'; }"""


@pytest.mark.parametrize("width,height", [(760, 900), (1280, 800), (1920, 1080)])
def test_nothing_overlaps(page: Page, width: int, height: int) -> None:
    """Nothing overlaps, nothing scrolls sideways, the header is one line from 1280 px up;
    in the embedded 3D view viser's controls (minimized in a narrow view) leave the scene
    free where they would open (top right) and in the middle."""
    page.set_viewport_size({"width": width, "height": height})
    expect(page.locator("header")).to_have_js_property("offsetWidth", width)
    _view_in_sight(page)  # a paused view has no box to cover
    assert _overlaps(page) == []
    handle = page.get_by_test_id("view3d").element_handle()
    frame = handle.content_frame() if handle else None
    assert frame is not None
    for point in ([0.5, 0.5], [0.75, 0.3]):
        frame.wait_for_function(CANVAS_AT, arg=point)
    page.screenshot(path=str(ARTIFACTS / f"console-{width}x{height}.png"))
    page.set_viewport_size({"width": 1280, "height": 800})


def test_an_immediate_command_from_the_dictionary_form(page: Page, server: str) -> None:
    sign_in(page)
    # a rule across arguments the form leaves to the server: its 422 message is shown
    page.select_option("[data-testid=command-picker]", "DRIVE_ARC")
    page.fill("#args input[name=radius_m]", "0.3")
    page.fill("#args input[name=angle_deg]", "20")
    page.click("#send")
    expect(page.get_by_test_id("sequence-status")).to_contain_text(
        re.compile(r"Command refused: .*radius_m: must be at least 0\.6 m")
    )
    expect(page.locator("#args input[name=radius_m]")).to_have_class(re.compile("invalid"))
    page.select_option("[data-testid=command-picker]", "DRIVE_STRAIGHT")
    page.fill("#args input[name=distance_m]", "1.5")
    page.click("#send")
    expect(page.get_by_test_id("sequence-status")).to_contain_text("Command DRIVE_STRAIGHT queued")
    names = [s["name"] for s in httpx.get(f"{server}/api/rovers/spirit/sequences").json()]
    assert "immediate_DRIVE_STRAIGHT" in names


def test_an_out_of_range_argument_is_named_with_its_range_and_nothing_is_sent(
    page: Page, server: str
) -> None:
    def sequence_ids() -> list[int]:  # the earlier commands may still be running
        return [s["id"] for s in httpx.get(f"{server}/api/rovers/spirit/sequences").json()]

    before = sequence_ids()
    sign_in(page)
    page.select_option("[data-testid=command-picker]", "DRIVE_STRAIGHT")
    distance = page.locator("#args input[name=distance_m]")
    expect(distance).to_have_attribute("max", "100")
    expect(distance).to_have_attribute("title", re.compile(r"^distance_m: \(0, 100\] m"))
    distance.fill("150")
    page.click("#send")
    expect(page.get_by_test_id("sequence-status")).to_have_text(
        "Not sent: distance_m: must be in (0, 100] m, got 150"
    )
    expect(distance).to_have_class(re.compile("invalid"))
    page.screenshot(path=str(ARTIFACTS / "console_command_out_of_range.png"), full_page=True)
    assert sequence_ids() == before
