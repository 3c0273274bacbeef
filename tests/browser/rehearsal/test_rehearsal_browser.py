"""A rehearsal in a real browser (Debian's Chromium driven by Playwright, TESTING.md) against
the real server (its embedded Dask cluster) on a temporary database: an operator writes a
2 m drive in the editor, is refused a rehearsal of 0 runs by the console (and one of a
sequence with an error by the server, at its line), rehearses it with 8 runs, and watches
the progress bar finish; the risk table has a row per line, as the API's table says; the
3D view draws the cloud of predicted traverses and the ellipses (the scene's state counts
the paths, the viewer's page has the nodes, its note says "rehearsal #N: 8 runs"); the
timeline's Rehearsal lane has the line's predicted band. The sequence is then run, and the
predicted-vs-executed report shows each figure's place as the API computes it, the truth
part too (this server's truth view is everyone's). Screenshots go to test-artifacts/."""

from __future__ import annotations

import math
import re
from collections.abc import Iterator

import httpx
import pytest
from playwright.sync_api import Browser, Page, expect, sync_playwright

from tests.browser.test_console_browser import (
    ARTIFACTS,
    CHROMIUM,
    LAUNCH_ARGS,
    ROOT,
    TOKEN,
    new_token,
    open_console,
)
from tests.browser.test_view3d_browser import SCENE_LOADED, TIMEOUT_MS, VIEWER, _view_frame
from tests.server.test_server_restart import _wait, serving

FIRST = "SEQUENCE first\nDRIVE_STRAIGHT distance_m=0.5\n"
DRIVE = "SEQUENCE rehearse_me\nDRIVE_STRAIGHT distance_m=2\n"
BROKEN = "SEQUENCE broken\nDRIVE_STRAIGHT distance_m=-2\n"
RUNS = 8
CAMPAIGN_MS = 600_000  # the cluster's start, the workers' warm-up and 8 runs, both cores busy
CLOUD = "() => !!window.__viserMutable?.nodeRefFromName?.['/rehearsal/cloud']"
AUTH = {"Authorization": f"Bearer {TOKEN}"}


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    with serving(
        tmp_path_factory.mktemp("rehearsal_browser"),
        TOKEN,
        ready="/api/rovers/spirit/scene",
        three_d=True,
        # the Dask workers (processes of their own) import the engine from this checkout,
        # whatever checkout the environment's package was installed from
        env_extra={"PYTHONPATH": str(ROOT)},
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


def test_rehearse_then_run_then_read_predicted_against_executed(
    browser: Browser, server: str
) -> None:
    expect.set_options(timeout=TIMEOUT_MS)
    operator = new_token(server, "driver", "operator")
    page = open_console(browser, server, operator, "driver · operator", "spirit")
    page.context.set_default_timeout(TIMEOUT_MS)
    try:
        _rehearse_run_and_report(page, server)
    finally:
        page.screenshot(path=str(ARTIFACTS / "rehearsal_console.png"), full_page=True)
        page.context.close()


def _drive_first(server: str) -> None:
    """A short drive, so that the ground has the rover's report to rehearse from."""
    with httpx.Client(base_url=server, timeout=30.0, headers=AUTH) as c:
        r = c.post("/api/rovers/spirit/sequences", json={"text": FIRST})
        assert r.status_code == 201 and r.json()["status"] == "queued", r.text
        assert c.post("/api/rovers/spirit/clock", json={"speed": "max"}).status_code == 200
        _wait(lambda: c.get("/api/rovers/spirit/sequences").json()[0]["status"] == "completed",
              timeout_s=TIMEOUT_MS / 1000)  # fmt: skip
        _wait(lambda: not c.get("/api/rovers/spirit/state").json()["executing"])


def _rehearse_run_and_report(page: Page, server: str) -> None:
    _drive_first(server)
    controls = page.get_by_test_id("rehearse-controls")
    expect(controls).to_be_visible()  # an operator's
    status = page.get_by_test_id("rehearse-status")
    # checked before sending, then by the server: its words, the error at its line
    page.fill("#editor", DRIVE)
    page.fill("#rehearse-runs", "0")
    page.click("#rehearse")
    expect(status).to_have_text('runs must be a whole number from 1 to 1000, not "0"')
    page.fill("#editor", BROKEN)
    page.fill("#rehearse-runs", str(RUNS))
    page.click("#rehearse")
    expect(status).to_contain_text("Not rehearsed (400): the sequence has 1 error: line 2:")
    expect(page.get_by_test_id("rehearse-errors")).to_contain_text("line 2:")

    page.fill("#editor", DRIVE)
    page.fill("#rehearse-seed", "25")
    page.click("#rehearse")
    expect(status).to_contain_text(f"started: {RUNS} runs, seed 25")
    panel = page.get_by_test_id("rehearsal-panel")
    campaign = int(panel.get_attribute("data-campaign") or 0)
    assert campaign > 0
    words = page.get_by_test_id("rehearsal-words")
    expect(words).to_contain_text(f"/ {RUNS} runs")
    listed = page.locator(f"[data-testid=rehearsal-listed][data-id='{campaign}']")
    expect(listed).to_have_count(1)
    panel.screenshot(path=str(ARTIFACTS / "rehearsal_running.png"))
    over = re.compile("done|cancelled|failed")
    expect(panel).to_have_attribute("data-state", over, timeout=CAMPAIGN_MS)
    assert panel.get_attribute("data-state") == "done", words.text_content()
    expect(words).to_have_text(f"{RUNS} / {RUNS} runs · done")
    bar = page.get_by_test_id("rehearsal-progress")
    expect(bar).to_have_attribute("style", re.compile(r"width: 100(\.0)?%"))

    with httpx.Client(base_url=server, timeout=30.0, headers=AUTH) as c:
        detail = c.get(f"/api/rovers/spirit/rehearsals/{campaign}").json()
    risk = detail["risk"]
    assert detail["state"] == "done" and risk["runs"] == RUNS
    rows = page.get_by_test_id("risk-row")
    expect(rows).to_have_count(len(risk["lines"]))
    for row, line in zip(rows.all(), risk["lines"], strict=True):
        assert row.get_attribute("data-line") == str(line["line"])
        assert row.get_attribute("data-verdict") == line["verdict"]
        expect(row.get_by_test_id("risk-verdict")).to_have_text(line["verdict"])
    drive = next(line for line in risk["lines"] if line["command"].startswith("DRIVE"))
    assert drive["line"] == 2
    e95 = drive["end_true"]["ellipse_95"]
    expect(page.locator("[data-testid=risk-row][data-line='2']")).to_contain_text(
        f"{e95['a_m']:.2f} × {e95['b_m']:.2f} m"
    )
    expect(listed).to_have_attribute("data-state", "done")
    panel.screenshot(path=str(ARTIFACTS / "rehearsal_risk.png"))

    # the 3D view draws it: the scene's state, the viewer's nodes, the viewer's note
    note = f"rehearsal #{campaign}: {RUNS} runs"
    expect(page.get_by_test_id("rehearsal-3d")).to_contain_text(note)
    with httpx.Client(base_url=server, timeout=30.0, headers=AUTH) as c:
        scene = c.get("/api/rovers/spirit/scene").json()["rehearsal"]
    assert scene == {
        "id": campaign, "runs": RUNS, "paths": len(risk["paths"]), "ellipses": len(risk["lines"]),
        "note": note,
    }  # fmt: skip
    assert len(risk["paths"]) == RUNS  # one thinned traverse a run
    page.locator("section.view3d").scroll_into_view_if_needed()  # out of sight it is paused
    # Paused for minutes, the frame has the rover's live frames to catch up on, in software
    # WebGL; loaded again (its toggle: hidden unloads it), it gets the scene as it is now.
    toggle = page.get_by_test_id("view3d-toggle")
    toggle.click()
    expect(toggle).to_have_attribute("aria-expanded", "false")
    toggle.click()
    expect(toggle).to_have_attribute("aria-expanded", "true")
    frame = _view_frame(page)
    frame.wait_for_function(SCENE_LOADED)
    frame.wait_for_function(CLOUD)
    frame.wait_for_function(
        "() => !!window.__viserMutable?.nodeRefFromName?.['/rehearsal/line_2/ellipse_95']"
    )
    page.get_by_test_id("view3d").screenshot(path=str(ARTIFACTS / "rehearsal_view3d.png"))
    tab = page.context.new_page()
    tab.set_viewport_size({"width": VIEWER["width"], "height": VIEWER["height"]})
    tab.goto(f"{server}/viser/spirit/")
    tab.wait_for_function(CLOUD)
    expect(tab.get_by_text(note)).to_be_visible()
    tab.screenshot(path=str(ARTIFACTS / "rehearsal_view3d_tab.png"))
    tab.close()

    # the timeline: the line's predicted band
    bands = page.get_by_test_id("timeline-rehearsal")
    expect(bands).to_have_count(1)
    expect(bands.first).to_have_attribute("data-line", "2")

    # the sequence runs: the band moves onto it, and the report places what it did
    page.click("#upload-text")
    expect(page.get_by_test_id("sequence-status")).to_contain_text("queued")
    with httpx.Client(base_url=server, timeout=30.0, headers=AUTH) as c:
        _wait(lambda: c.get("/api/rovers/spirit/sequences").json()[0]["status"] == "completed",
              timeout_s=TIMEOUT_MS / 1000)  # fmt: skip
        sequence_id = c.get("/api/rovers/spirit/sequences").json()[0]["id"]
        report = c.get(f"/api/rovers/spirit/rehearsals/{campaign}/report").json()
    assert report["sequence_id"] == sequence_id
    lane = page.get_by_test_id("timeline-rehearsal-lane")
    expect(lane).to_have_attribute("data-executed", str(sequence_id))
    page.click("[data-testid=rehearsal-report-ask]")
    shown = page.get_by_test_id("rehearsal-report")
    expect(shown).to_be_visible()
    table = shown.get_by_test_id("report-table")
    figures = [(line["line"], f) for line in report["lines"] for f in line["figures"]]
    assert figures
    expect(table.get_by_test_id("report-row")).to_have_count(len(figures))
    outside = sum(f["outside_95"] for _, f in figures)
    expect(table.locator("[data-testid=report-row][data-outside='1']")).to_have_count(outside)
    expect(shown.get_by_test_id("report-flags").locator("li")).to_have_count(len(report["flags"]))
    for line, f in figures:
        if f.get("percentile") is not None and f["name"] != "end_est":
            row = table.locator(
                f"[data-testid=report-row][data-line='{line}'][data-figure='{f['name']}']"
            )
            expect(row).to_contain_text(
                re.compile(rf"{math.floor(f['percentile'] + 0.5)}(st|nd|rd|th) percentile")
            )
    assert report["truth"] is not None  # this server's truth view is everyone's
    truth_rows = shown.get_by_test_id("report-truth").get_by_test_id("report-row")
    expect(truth_rows).to_have_count(sum(len(t["figures"]) for t in report["truth"]["lines"]))
    page.get_by_test_id("rehearsal-panel").screenshot(path=str(ARTIFACTS / "rehearsal_report.png"))
