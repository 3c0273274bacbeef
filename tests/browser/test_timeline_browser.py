"""The sol timeline review in a real browser (Debian's Chromium driven by Playwright,
TESTING.md) against the real server on a temporary database. The example that runs
SUNCHECK_SUNGAZE then a drive is run on spirit at full speed; the page then shows the sol
with both command bars, an AQF band with a Fine segment, the events, three drawn plots on
the lanes' LMST axis, and a CSV link that downloads the sol's frames. The sol picker
follows the rover picker. Screenshots at 1280x800 and 1920x1080 go to test-artifacts/."""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest
from playwright.sync_api import Browser, Page, expect, sync_playwright

from tests.browser.test_console_browser import ARTIFACTS, CHROMIUM, LAUNCH_ARGS, ROOT
from tests.server.test_server_restart import _wait, serving

TOKEN = "timeline-test-token"
AUTH = {"Authorization": f"Bearer {TOKEN}"}
EXAMPLE = ROOT / "sequences/examples/fine_attitude_then_drive.seq"
PLOTS = {  # container test id -> its series' stroke colour (timeline.js)
    "plot-position-error": (0x3D, 0x8B, 0xFD),
    "plot-attitude-error": (0x6B, 0xD4, 0x8A),
    "plot-hga-margin": (0xF0, 0xB4, 0x29),
}
SIDE_ESTIMATORS = "sapp,kinematic_ekf,radio_ekf"
SIDE_RGB = {"kinematic_ekf": (0xFF, 0x8C, 0x42), "radio_ekf": (0xE6, 0x5A, 0xC8)}
# Pixels of a canvas within 40 of a colour on every channel: the plotted line's own.
COUNT_COLOUR = """(canvas, rgb) => {
  const data = canvas.getContext("2d").getImageData(0, 0, canvas.width, canvas.height).data;
  let n = 0;
  for (let i = 0; i < data.length; i += 4) {
    if (data[i + 3] > 200 && Math.abs(data[i] - rgb[0]) < 40 && Math.abs(data[i + 1] - rgb[1]) < 40
        && Math.abs(data[i + 2] - rgb[2]) < 40) n++;
  }
  return n;
}"""


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """The real server, both fusion filters beside SAPP, with the example sequence run to
    completion on spirit."""
    with (
        serving(tmp_path_factory.mktemp("timeline"), TOKEN, estimators=SIDE_ESTIMATORS) as base,
        httpx.Client(base_url=base, timeout=10.0) as c,
    ):
        r = c.post("/api/rovers/spirit/sequences", content=EXAMPLE.read_text(), headers=AUTH)
        assert r.status_code == 201, r.text
        seq_id = r.json()["id"]
        c.post("/api/rovers/spirit/clock", json={"speed": "max"}, headers=AUTH)
        _wait(lambda: c.get(f"/api/sequences/{seq_id}").json()["status"] == "completed")
        _wait(lambda: not c.get("/api/rovers/spirit/state").json()["executing"])
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
    context = browser.new_context(viewport={"width": 1280, "height": 800}, accept_downloads=True)
    pg = context.new_page()
    pg.goto(f"{server}/?rover=spirit")
    try:
        yield pg
    finally:
        context.close()


def _box(page: Page, selector: str) -> dict[str, float]:
    box = page.locator(selector).first.bounding_box()
    assert box is not None, f"{selector} is not on screen"
    return box


def _check_layout(page: Page) -> None:
    """The panel sits under the console; the lanes' tracks start and end where the plots'
    plotting areas do (one LMST axis); the plots fit in the panel."""
    main, panel = _box(page, "main"), _box(page, "#timeline-panel")
    assert panel["y"] >= main["y"] + main["height"]
    track = _box(page, "#lane-commands")
    for test_id in PLOTS:
        area = _box(page, f"[data-testid={test_id}] .u-over")
        assert abs(area["x"] - track["x"]) <= 1.5
        assert abs(area["width"] - track["width"]) <= 1.5
        assert area["x"] + area["width"] <= panel["x"] + panel["width"]


def _check_plots_drawn(page: Page) -> None:
    for test_id, rgb in PLOTS.items():
        canvas = page.locator(f"[data-testid={test_id}] canvas")
        expect(canvas).to_have_count(1)
        assert canvas.evaluate(COUNT_COLOUR, rgb) > 40, f"{test_id}: no line drawn"


def test_the_sol_shows_commands_bands_events_plots_and_a_csv(page: Page, server: str) -> None:
    sol = httpx.get(f"{server}/api/rovers/spirit/sols").json()[-1]
    picker = page.get_by_test_id("timeline-sol")
    expect(picker).to_have_value(str(sol))  # the latest sol by default
    picker.select_option(str(sol))

    commands = page.get_by_test_id("timeline-command")
    expect(commands).to_have_count(2)
    titles = [t or "" for t in commands.evaluate_all("els => els.map(e => e.title)")]
    assert titles[0].startswith("SUNCHECK_SUNGAZE\ncompleted")
    assert titles[1].startswith("DRIVE_STRAIGHT distance_m=10\ncompleted")
    expect(commands.nth(1).locator(".tl-label")).to_be_visible()  # the drive's label fits

    aqf = page.get_by_test_id("timeline-aqf")
    expect(aqf.and_(page.locator("[data-value=Fine]"))).to_have_count(1)
    # the badge's .aqf-Fine; retried: the sol's first render may still be replacing the
    # bands it drew when the picker's choice arrives (a computed style read from a band
    # just taken out of the page is empty)
    expect(aqf.and_(page.locator("[data-value=Fine]"))).to_have_css(
        "background-color", "rgb(31, 107, 53)"
    )
    nate = [v for v in page.get_by_test_id("timeline-nate").evaluate_all(
        "els => els.map(e => e.dataset.value)"
    )]  # fmt: skip
    assert "Sungaze" in nate and "Mobility" in nate

    events = page.get_by_test_id("timeline-event").evaluate_all("els => els.map(e => e.title)")
    assert any("Sungaze: converged" in t for t in events)
    assert any("SuncheckSungaze done: AQF Fine" in t for t in events)

    expect(page.get_by_test_id("timeline-summary")).to_contain_text(
        re.compile(r"2 commands \(0 not completed\).*9\.\d\d m driven")
    )
    expect(page.locator("#lane-axis .tl-tick").first).to_have_text(re.compile(r"^\d\d:\d\d$"))
    _check_plots_drawn(page)
    _check_layout(page)
    page.screenshot(path=str(ARTIFACTS / "timeline-1280x800.png"), full_page=True)

    with page.expect_download() as info:
        page.get_by_test_id("timeline-csv").click()
    download = info.value
    assert download.suggested_filename == f"spirit_sol{sol}.csv"
    lines = Path(download.path()).read_text().splitlines()
    assert lines[0].startswith("t_s,sol,lmst_h,nate_mode,aqf") and len(lines) > 100

    narrow = page.locator("[data-testid=plot-hga-margin] canvas").bounding_box()
    page.set_viewport_size({"width": 1920, "height": 1080})
    page.wait_for_function(
        "w => document.querySelector('[data-testid=plot-hga-margin] canvas')"
        ".getBoundingClientRect().width > w + 500",
        arg=narrow["width"] if narrow else 0,
    )
    _check_plots_drawn(page)
    _check_layout(page)
    page.screenshot(path=str(ARTIFACTS / "timeline-1920x1080.png"), full_page=True)


def test_the_sol_picker_follows_the_rover(page: Page, server: str) -> None:
    picker = page.get_by_test_id("timeline-sol")
    spirit: list[Any] = httpx.get(f"{server}/api/rovers/spirit/sols").json()
    expect(picker).to_have_value(str(spirit[-1]))
    # opportunity idles at 1x from the start: wait for its first stored frames
    opportunity = _wait(lambda: httpx.get(f"{server}/api/rovers/opportunity/sols").json())
    page.select_option("#rover", "opportunity")
    expect(picker).to_have_value(str(opportunity[-1]))
    assert opportunity[-1] != spirit[-1]  # the two rovers' sols differ: a real switch
    expect(page.get_by_test_id("timeline-csv")).to_have_attribute(
        "href", f"/api/rovers/opportunity/sols/{opportunity[-1]}/telemetry.csv"
    )
    expect(page.get_by_test_id("timeline-command")).to_have_count(0)  # opportunity idled
    page.select_option("#rover", "spirit")
    expect(picker).to_have_value(str(spirit[-1]))
    expect(page.get_by_test_id("timeline-command")).to_have_count(2)


def test_each_vo_step_is_a_mark_on_the_vo_lane(page: Page, server: str) -> None:
    """A vo=on drive (two steps): each step's update or failure on the VO lane, its text
    as the tooltip, and not among the other events."""
    with httpx.Client(base_url=server, timeout=10.0) as c:
        body = {"command": "DRIVE_STRAIGHT", "args": {"distance_m": 1.0, "vo": True}}
        r = c.post("/api/rovers/spirit/commands", json=body, headers=AUTH)
        assert r.status_code == 201, r.text
        seq_id = r.json()["id"]
        _wait(lambda: c.get(f"/api/sequences/{seq_id}").json()["status"] == "completed")
        _wait(lambda: not c.get("/api/rovers/spirit/state").json()["executing"])
    page.click("#timeline-refresh")
    marks = page.get_by_test_id("timeline-vo")
    expect(marks).to_have_count(2)
    titles = marks.evaluate_all("els => els.map(e => e.title)")
    values = marks.evaluate_all("els => els.map(e => e.dataset.value)")
    for title, value in zip(titles, values, strict=True):
        assert re.search(r"VO step [12]/2", title)
        assert value == ("failure" if "failed" in title else "update")
    others = page.get_by_test_id("timeline-event").evaluate_all("els => els.map(e => e.title)")
    assert not any("VO step" in t for t in others)
    page.get_by_test_id("timeline-panel").screenshot(path=str(ARTIFACTS / "timeline-vo.png"))


def test_the_estimators_beside_sapp_are_lines_on_the_error_plots(page: Page) -> None:
    """roverops serve --estimators sapp,kinematic_ekf,radio_ekf: each filter's position
    error is a line of its own colour, named in the legend; the radio EKF estimates
    position only, so the attitude plot has the kinematic EKF's line and not its."""
    position = page.get_by_test_id("plot-position-error")
    attitude = page.get_by_test_id("plot-attitude-error")
    expect(position.locator(".u-legend")).to_contain_text("kinematic_ekf")
    expect(position.locator(".u-legend")).to_contain_text("radio_ekf")
    expect(attitude.locator(".u-legend")).to_contain_text("kinematic_ekf")
    expect(attitude.locator(".u-legend")).not_to_contain_text("radio_ekf")
    pos_canvas, att_canvas = position.locator("canvas"), attitude.locator("canvas")
    for name, rgb in SIDE_RGB.items():
        assert pos_canvas.evaluate(COUNT_COLOUR, rgb) > 40, f"{name}: no position line"
    assert att_canvas.evaluate(COUNT_COLOUR, SIDE_RGB["kinematic_ekf"]) > 40
    assert att_canvas.evaluate(COUNT_COLOUR, SIDE_RGB["radio_ekf"]) == 0
    page.get_by_test_id("timeline-panel").screenshot(
        path=str(ARTIFACTS / "timeline-estimators.png")
    )


# ---- telemetry at a glance (web/plot.js) ------------------------------------------------

TRUTH_RGB = (0xE6, 0x5A, 0xC8)  # plot.js COLOURS.truth
ROVER_RGB = (0x3D, 0x8B, 0xFD)  # plot.js COLOURS.rover


def _channel(server: str, name: str, sol: int) -> dict[str, Any]:
    params: dict[str, Any] = {"sol_from": sol, "sol_to": sol, "max_points": 2000}
    got: dict[str, Any] = httpx.get(
        f"{server}/api/rovers/spirit/channels/{name}", params=params
    ).json()
    return got


def test_a_channel_is_plotted_over_the_chosen_sols(page: Page, server: str) -> None:
    """Pick a channel and a sol range: the plot has the API's points, LMST labels with the
    sol, and the truth-view marker exactly when the channel is scored against truth."""
    sol = httpx.get(f"{server}/api/rovers/spirit/sols").json()[-1]
    httpx.post(f"{server}/api/rovers/spirit/clock", json={"action": "pause"}, headers=AUTH)
    try:
        plot = page.get_by_test_id("channel-plot")
        expect(plot).to_have_attribute("data-channel", "hga_margin_deg")  # the first draw
        page.select_option("[data-testid=plot-channel]", "position_error_m")
        page.fill("[data-testid=plot-sol-from]", str(sol))
        page.fill("[data-testid=plot-sol-to]", str(sol))
        page.click("[data-testid=plot-draw]")
        api = _channel(server, "position_error_m", sol)
        assert len(api["t_s"]) > 20
        expect(plot).to_have_attribute("data-channel", "position_error_m")
        expect(plot).to_have_attribute("data-points", str(len(api["t_s"])))
        expect(page.get_by_test_id("plot-truth")).to_be_visible()
        assert plot.locator("canvas").evaluate(COUNT_COLOUR, TRUTH_RGB) > 40
        plot.locator(".u-over").hover()  # the legend reads the x under the pointer
        expect(plot.locator(".u-legend")).to_contain_text(re.compile(rf"Sol {sol} \d\d:\d\d"))
        page.get_by_test_id("telemetry-panel").screenshot(
            path=str(ARTIFACTS / "telemetry-plot-truth.png")
        )

        page.select_option("[data-testid=plot-channel]", "imu_integration_s")
        api = _channel(server, "imu_integration_s", sol)
        expect(plot).to_have_attribute("data-channel", "imu_integration_s")
        expect(plot).to_have_attribute("data-points", str(len(api["t_s"])))
        expect(page.get_by_test_id("plot-truth")).to_be_hidden()
        assert plot.locator("canvas").evaluate(COUNT_COLOUR, ROVER_RGB) > 40
        page.get_by_test_id("telemetry-panel").screenshot(
            path=str(ARTIFACTS / "telemetry-plot.png")
        )
        # narrow: the panel and its plot shrink to the window
        page.set_viewport_size({"width": 760, "height": 900})
        page.wait_for_function(
            "() => document.querySelector('[data-testid=channel-plot] canvas')"
            ".getBoundingClientRect().right <= 760"
        )
        assert _box(page, "#telemetry-panel")["x"] + _box(page, "#telemetry-panel")["width"] <= 760
        page.get_by_test_id("telemetry-panel").screenshot(
            path=str(ARTIFACTS / "telemetry-plot-760.png")
        )
        page.fill("[data-testid=plot-sol-to]", str(sol - 1))
        page.click("[data-testid=plot-draw]")
        expect(page.get_by_test_id("plot-status")).to_contain_text("no smaller")
    finally:
        httpx.post(f"{server}/api/rovers/spirit/clock", json={"action": "resume"}, headers=AUTH)


# ---- the live timeline ------------------------------------------------------------------

SOL_S = 88775.244
MARK_NODES = """() => {
  for (const selector of ['[data-testid=timeline-command]', '[data-testid=timeline-aqf]',
      '[data-testid=timeline-event]', '[data-testid=plot-position-error] canvas']) {
    document.querySelector(selector).dataset.marker = 'kept';
  }
}"""


# A frame 5 s after the rover's latest, carrying two events of frames it skipped (1 s and 2 s
# after the latest), as the hub sends them; returns the latest frame's t_s.
LIVE_EVENT_FRAME = """async () => {
  const f = (await (await fetch('/api/rovers/spirit/state')).json()).frame;
  const at = (dt) => ({ t_s: f.t_s + dt, sol: f.sol, lmst_h: f.lmst_h + dt * 24 / 88775.244 });
  const event = (dt, text) => ({ text, kind: "server", severity: "info", ...at(dt) });
  const events = [event(1, "test event A"), event(2, "test event B")];
  window.roverops.emit("frame", { ...f, ...at(5), events });
  return f.t_s;
}"""


def _loaded(page: Page) -> None:
    """The sol is drawn: its frames plotted, and maybe live frames added since (at max
    speed with nothing queued the clock runs on in real time: server.runtime)."""
    expect(page.get_by_test_id("timeline-status")).to_contain_text(
        re.compile(r"frames plotted|live: \d+ frames? added")
    )


def _command(server: str, command: str, args: dict[str, Any] | None = None) -> int:
    body = {"command": command, "args": args or {}}
    r = httpx.post(f"{server}/api/rovers/spirit/commands", json=body, headers=AUTH)
    assert r.status_code == 201, r.text
    seq_id: int = r.json()["id"]
    return seq_id


def test_a_command_appears_live_without_a_reload_or_a_redraw(page: Page, server: str) -> None:
    """With the current sol on screen, an immediate command's box appears in the commands
    lane, its mode in the NATE lane and its points on the plots, with no Refresh; the nodes
    drawn before (marked) are still the page's."""
    sol = httpx.get(f"{server}/api/rovers/spirit/sols").json()[-1]
    listed = httpx.get(f"{server}/api/rovers/spirit/sols/{sol}/timeline").json()["commands"]
    _loaded(page)
    commands = page.get_by_test_id("timeline-command")
    expect(commands).to_have_count(len(listed))
    plot = page.get_by_test_id("channel-plot")
    expect(plot).to_have_attribute("data-channel", "hga_margin_deg")
    points = int(plot.get_attribute("data-points") or 0)
    page.evaluate(MARK_NODES)

    seq_id = _command(server, "NADIR_UPDATE")
    expect(commands).to_have_count(len(listed) + 1)
    expect(commands.last).to_have_attribute("title", re.compile(r"^NADIR_UPDATE\ncompleted"))
    expect(
        page.locator("[data-testid=timeline-nate][data-value=NadirUpdate]").first
    ).to_be_attached()
    expect(page.get_by_test_id("timeline-summary")).to_contain_text(f"{len(listed) + 1} commands")
    expect(page.get_by_test_id("timeline-status")).to_contain_text("live:")
    page.wait_for_function(
        "n => Number(document.querySelector('[data-testid=channel-plot]').dataset.points) > n",
        arg=points,
    )
    _wait(lambda: httpx.get(f"{server}/api/sequences/{seq_id}").json()["status"] == "completed")
    # the rover fell idle: the lanes were checked against storage, in place
    expect(page.get_by_test_id("timeline-panel")).to_have_attribute(
        "data-reconciled", re.compile(r"^[1-9]\d*$")
    )
    assert page.locator("[data-marker=kept]").count() == 4, "a node drawn before was replaced"
    stored = httpx.get(f"{server}/api/rovers/spirit/sols/{sol}/timeline").json()["commands"]
    ids = commands.evaluate_all("els => els.map(e => Number(e.dataset.id))")
    assert ids == [c["id"] for c in stored]  # the boxes are storage's commands, in order
    page.get_by_test_id("timeline-panel").screenshot(path=str(ARTIFACTS / "timeline-live.png"))

    # events as the event contract carries them on the WebSocket: objects with their own
    # time (a frame of a batch carries the events of the frames it skipped)
    base = page.evaluate(LIVE_EVENT_FRAME)
    for text, dt in (("test event A", 1.0), ("test event B", 2.0)):
        mark = page.locator(f"[data-testid=timeline-event][title*='{text}']")
        expect(mark).to_have_count(1)
        expect(mark).to_have_attribute("data-t", f"{base + dt:.3f}")  # its own time


def test_following_live_moves_to_the_next_sol(page: Page, server: str) -> None:
    """The rover waits past midnight: with Follow live on, the timeline shows the new sol
    without a reload."""
    state = httpx.get(f"{server}/api/rovers/spirit/state").json()
    sol = state["sol"]
    _loaded(page)
    picker = page.get_by_test_id("timeline-sol")
    expect(picker).to_have_value(str(sol))
    expect(page.get_by_test_id("timeline-follow")).to_be_checked()
    _command(server, "WAIT", {"duration_s": (24.0 - state["lmst_h"]) * SOL_S / 24.0 + 120.0})
    expect(picker).to_have_value(str(sol + 1))
    expect(page.get_by_test_id("timeline-summary")).to_contain_text(f"Sol {sol + 1},")


def test_focus_shows_the_sol_with_the_hairline_at_the_time(page: Page, server: str) -> None:
    """roverops.emit("focus", {sol, t_s}) (the event log's link) shows that sol with the
    hairline on the event; the live rover, now on a later sol, leaves that view alone."""
    sols = httpx.get(f"{server}/api/rovers/spirit/sols").json()
    old = next(
        s
        for s in sols
        if httpx.get(f"{server}/api/rovers/spirit/sols/{s}/timeline").json()["summary"]["commands"]
        >= 2
    )
    assert old < sols[-1], "the previous test moved the rover to a later sol"
    timeline = httpx.get(f"{server}/api/rovers/spirit/sols/{old}/timeline").json()
    event = next(e for e in timeline["events"] if "Sungaze: converged" in e["text"])
    _loaded(page)
    picker = page.get_by_test_id("timeline-sol")
    expect(picker).to_have_value(str(sols[-1]))

    page.evaluate("([sol, t]) => window.roverops.emit('focus', {sol, t_s: t})", [old, event["t_s"]])
    expect(picker).to_have_value(str(old))
    expect(page.get_by_test_id("timeline-summary")).to_contain_text(f"Sol {old},")
    hairline = page.locator("#timeline-hairline")
    expect(hairline).to_be_visible()
    expect(hairline).to_have_attribute("data-focus-ts", str(event["t_s"]))
    mark = page.locator(f"[data-testid=timeline-event][data-t='{event['t_s']:.3f}']")
    line_box, mark_box = _box(page, "#timeline-hairline"), mark.bounding_box()
    assert mark_box is not None
    assert abs(line_box["x"] - (mark_box["x"] + mark_box["width"] / 2)) <= 2.0
    page.get_by_test_id("timeline-panel").screenshot(path=str(ARTIFACTS / "timeline-focus.png"))

    count = page.get_by_test_id("timeline-command").count()
    seq_id = _command(server, "NADIR_UPDATE")
    _wait(lambda: httpx.get(f"{server}/api/sequences/{seq_id}").json()["status"] == "completed")
    expect(page.get_by_test_id("sol-clock")).to_contain_text(f"Sol {sols[-1]}")
    expect(picker).to_have_value(str(old))
    assert page.get_by_test_id("timeline-command").count() == count
    expect(hairline).to_have_attribute("data-focus-ts", str(event["t_s"]))
