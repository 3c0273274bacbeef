"""The event log and the live event list in a real browser (Chromium, Playwright) against the
real server (issue 14): a sequence over two sols runs at max speed while the page is open.
The readouts' live list shows each event at its own LMST (item 5: at max speed Nadir
Update, Sunfind and Sungaze came in one message and were all shown at its time); the event
log lists every event, its rows change with the kind and text filters, and clicking a row
fires the "focus" hook and turns the sol timeline to that sol. Screenshots in
test-artifacts/ (eventlog.png, the page; eventlog-panel-{760,1280,1920}.png)."""

from __future__ import annotations

import math
import re
from collections.abc import Iterator
from typing import Any

import httpx
import pytest

# first: it skips the module without Chromium (and brings Playwright's names)
from tests.browser.test_console_browser import ARTIFACTS, Page, console_page, expect
from tests.server.test_server_restart import _wait, serving

TOKEN = "eventlog-browser-token"
AUTH = {"Authorization": f"Bearer {TOKEN}"}
LAST = "DRIVE_TO refused"


def _sequence(sol: int) -> str:
    """A Fine attitude and a Site on ``sol``, another Site the next morning, then a refusal."""
    return (
        "SEQUENCE two_sols\nGET_FINE_ATTITUDE\nPLANT_SITE\n"
        f"@ sol {sol + 1} 09:00 LMST  PLANT_SITE\nDRIVE_TO x_m=500 y_m=0\n"
    )


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    with serving(tmp_path_factory.mktemp("eventlog"), TOKEN, three_d=False) as base:
        yield base


@pytest.fixture(scope="module")
def page(server: str) -> Iterator[Page]:
    """The console, open while the sequence runs (the events come live), then the log."""
    with console_page(f"{server}/?rover=spirit", "eventlog.png") as pg:
        expect(pg.get_by_test_id("eventlog-status")).to_contain_text(re.compile(r"of \d+ events"))
        pg.wait_for_function("roverops.state.ws && roverops.state.ws.readyState === 1")
        with httpx.Client(base_url=server, headers=AUTH, timeout=10.0) as c:
            sol = c.get("/api/rovers/spirit/state").json()["sol"]
            c.post("/api/rovers/spirit/clock", json={"speed": "max"}).raise_for_status()
            r = c.post("/api/rovers/spirit/sequences", content=_sequence(sol))
            assert r.status_code == 201, r.text
        expect(pg.get_by_test_id("events")).to_contain_text(LAST)
        with httpx.Client(base_url=server, headers=AUTH, timeout=10.0) as c:
            # the sequence's end is the server's last event; paused, nothing more happens
            # (alarms come and go with a running rover), so the counts below hold
            _wait(lambda: any("two_sols failed" in e["text"] for e in _log(server)))
            c.post("/api/rovers/spirit/clock", json={"action": "pause"}).raise_for_status()
        yield pg


def _log(server: str, **params: Any) -> list[dict[str, Any]]:
    r = httpx.get(f"{server}/api/rovers/spirit/events", params={"limit": 1000, **params})
    assert r.status_code == 200, r.text
    events: list[dict[str, Any]] = r.json()["events"]
    return events


def _lmst(h: float) -> str:
    """console.js's lmst(): hh:mm:ss, floored."""
    total = math.floor(h * 3600)
    return f"{total // 3600:02d}:{total % 3600 // 60:02d}:{total % 60:02d}"


def test_the_live_list_shows_each_event_at_its_own_time(page: Page, server: str) -> None:
    """Item 5: the stored times, not the batch's last one, in the readouts' live list."""
    live = page.get_by_test_id("events").locator("li").all_text_contents()
    stored = {e["text"]: _lmst(e["lmst_h"]) for e in _log(server)}
    shown = {}
    for line in live:
        clock, text = line.split(" ", 1)
        shown[text] = clock
    for start in ("Nadir Update", "Sunfind", "Sungaze", "GetFineAttitude"):
        text = next(t for t in stored if t.startswith(start))
        assert shown[text] == stored[text], text
    nadir = next(t for t in shown if t.startswith("Nadir Update"))
    sungaze = next(t for t in shown if t.startswith("Sungaze"))
    assert shown[nadir] != shown[sungaze]  # minutes apart, though one message brought both
    refusal = page.get_by_test_id("events").locator("li", has_text=LAST)
    expect(refusal).to_have_class("sev-error")


def test_the_log_filters_by_kind_and_text(page: Page, server: str) -> None:
    rows = page.get_by_test_id("eventlog-row")
    everything = _log(server)
    expect(rows).to_have_count(len(everything))
    expect(rows.filter(has_text=LAST)).to_have_count(1)
    # newest first, as the server orders them (the refusal, made at a moment already
    # reported, is stamped with the rover's next frame: sim.loop.frames)
    expect(rows.first).to_contain_text(everything[0]["text"])
    page.select_option("[data-testid=eventlog-kind]", "site")
    expect(rows).to_have_count(2)
    expect(rows.nth(0)).to_contain_text("Site 2 planted")
    expect(rows.nth(1)).to_contain_text("Site 1 planted")
    page.select_option("[data-testid=eventlog-kind]", "")
    page.fill("[data-testid=eventlog-text]", "sunFIND")
    expect(rows).to_have_count(1)
    expect(rows.first).to_have_attribute("data-kind", "sunfind")
    page.fill("[data-testid=eventlog-text]", "")
    page.select_option("[data-testid=eventlog-severity]", "error")
    expect(rows).to_have_count(sum(e["severity"] == "error" for e in everything))
    expect(rows.filter(has_text=LAST)).to_have_count(1)
    page.select_option("[data-testid=eventlog-severity]", "")
    expect(rows).to_have_count(len(everything))
    expect(page.get_by_test_id("eventlog-status")).to_have_text(
        f"{len(everything)} of {len(everything)} events"
    )


def test_a_row_focuses_the_timeline_on_its_sol(page: Page, server: str) -> None:
    first = next(e for e in _log(server) if e["text"] == "Site 1 planted")
    second = next(e for e in _log(server) if e["text"] == "Site 2 planted")
    assert second["sol"] == first["sol"] + 1
    picker = page.get_by_test_id("timeline-sol")
    page.click("#timeline-refresh")  # the timeline follows the latest sol: the second
    expect(picker).to_have_value(str(second["sol"]))
    page.evaluate("window.__focus = []; roverops.on('focus', (v) => window.__focus.push(v))")
    page.get_by_test_id("eventlog-row").filter(has_text="Site 1 planted").click()
    page.wait_for_function("window.__focus.length === 1")
    assert page.evaluate("window.__focus[0]") == {"sol": first["sol"], "t_s": first["t_s"]}
    expect(picker).to_have_value(str(first["sol"]))
    expect(page.locator("#timeline-hairline")).to_be_visible()
    expect(page.get_by_test_id("eventlog-row").filter(has_text="Site 1 planted")).to_have_class(
        "sev-info selected"
    )
    panel = page.get_by_test_id("eventlog-panel")
    for width in (760, 1280, 1920):
        page.set_viewport_size({"width": width, "height": 800})
        expect(panel.locator("table")).to_be_visible()
        fits = "e => e.getBoundingClientRect().right <= document.documentElement.clientWidth"
        assert panel.evaluate(fits), f"the event log is wider than the page at {width} px"
        panel.screenshot(path=str(ARTIFACTS / f"eventlog-panel-{width}.png"))
    page.set_viewport_size({"width": 1280, "height": 800})


def test_panels_opened_before_any_telemetry_follow_it_when_it_comes(page: Page) -> None:
    """The page opened on a rover with no telemetry yet ("No telemetry yet"): once frames
    come, the telemetry panel finds the sol and plots without a reload."""
    plot = page.get_by_test_id("channel-plot")
    expect(plot).to_have_attribute("data-channel", "hga_margin_deg")
    expect(plot).not_to_have_attribute("data-points", "0")


def test_live_events_take_their_place_in_time_not_in_order_of_arrival(page: Page) -> None:
    """The hub sends notices before frames, so a sequence's end (a notice) can arrive before
    the frame that holds its last step's refusal, at the same moment. The list stays newest
    first, and at one moment the server's own event comes above the rover's, as stored."""
    page.select_option("[data-testid=eventlog-kind]", "")
    t = 9.0e9  # after everything the rover has done
    at = {"sol": 999, "lmst_h": 9.0}
    page.evaluate(
        """([t, at]) => {
             roverops.emit("notice", {type: "event", event: {...at, t_s: t,
               text: "sequence #99 later failed", kind: "sequence", severity: "error"}});
             roverops.emit("frame", {...at, t_s: t, events: [
               {text: "DRIVE_TO later refused", kind: "command", severity: "error"}]});
             roverops.emit("frame", {...at, t_s: t - 60, events: [
               {text: "Nadir Update earlier", kind: "nadir", severity: "info"}]});
           }""",
        [t, at],
    )
    rows = page.get_by_test_id("eventlog-row")
    expect(rows.nth(0)).to_contain_text("sequence #99 later failed")
    expect(rows.nth(1)).to_contain_text("DRIVE_TO later refused")
    expect(rows.nth(2)).to_contain_text("Nadir Update earlier")


VO_DRIVE = "SEQUENCE vo_drive\nDRIVE_STRAIGHT distance_m=4.0 vo=on\nPLANT_SITE\n"
SERVER_KINDS = ("sequence", "alarm")  # the server's own events: in no frame


def test_at_max_speed_the_live_log_lists_exactly_the_stored_events(page: Page, server: str) -> None:
    """Issue 21, "events missing live": at max speed a vo=on drive's frames come in one
    batch, and the live event log and the Rover panel missed VO steps 1-3, which a reload
    listed. Opened afresh (its stored events loaded while it subscribes), the page lists
    live exactly the events stored once the sequence has ended, as (t_s, text); the Rover
    panel every frame event that came after it opened."""
    page.reload()
    page.wait_for_function("roverops.state.ws && roverops.state.ws.readyState === 1")
    before = {(e["t_s"], e["text"]) for e in _log(server)}
    rows = page.get_by_test_id("eventlog-row")
    expect(rows).to_have_count(len(before))
    with httpx.Client(base_url=server, headers=AUTH, timeout=10.0) as c:
        c.post("/api/rovers/spirit/clock", json={"action": "resume"}).raise_for_status()
        c.post("/api/rovers/spirit/clock", json={"speed": "max"}).raise_for_status()
        r = c.post("/api/rovers/spirit/sequences", content=VO_DRIVE)
        assert r.status_code == 201, r.text
        _wait(lambda: any("vo_drive completed" in e["text"] for e in _log(server)), 120.0)
        c.post("/api/rovers/spirit/clock", json={"action": "pause"}).raise_for_status()
    stored = _log(server)
    assert any(e["text"].startswith("VO step 1/") for e in stored)
    # the log has the sequence's end, the server's last event, once it has it all
    expect(rows.filter(has_text="vo_drive completed")).to_have_count(1)
    expect(rows).to_have_count(len(stored))
    shown = rows.evaluate_all(
        "rows => rows.map(r => [Number(r.dataset.tS), r.lastElementChild.textContent])"
    )
    assert {(t, text) for t, text in shown} == {(e["t_s"], e["text"]) for e in stored}
    rover_panel = {
        line.split(" ", 1)[1]
        for line in page.get_by_test_id("events").locator("li").all_text_contents()
    }
    new = [e for e in stored if (e["t_s"], e["text"]) not in before]
    wanted = {e["text"] for e in new if e["kind"] not in SERVER_KINDS}
    assert wanted and wanted <= rover_panel


def test_events_made_while_the_socket_was_down_are_listed_after_it_reconnects(
    page: Page, server: str
) -> None:
    """Issue 21: a reconnect lost what happened while the socket was down. Here the page's
    socket is cut (its reconnection held: routed to nothing), a sequence runs at max,
    then the page reconnects: both lists show the sequence's events."""
    held: list[Any] = []

    def route(ws: Any) -> None:
        if not released:
            held.append(ws)  # answered by no one: open, silent
        else:
            ws.connect_to_server()

    released = False
    page.route_web_socket("**/ws/rovers/spirit/telemetry", route)
    page.evaluate("roverops.state.ws.close()")  # console.js reconnects after a second
    page.wait_for_function("roverops.state.ws && roverops.state.ws.readyState === 1")
    _wait(lambda: held)
    with httpx.Client(base_url=server, headers=AUTH, timeout=10.0) as c:
        c.post("/api/rovers/spirit/clock", json={"action": "resume"}).raise_for_status()
        r = c.post("/api/rovers/spirit/sequences", content="SEQUENCE gap\nPLANT_SITE\n")
        assert r.status_code == 201, r.text
        _wait(lambda: any("gap completed" in e["text"] for e in _log(server)), 120.0)
        c.post("/api/rovers/spirit/clock", json={"action": "pause"}).raise_for_status()
    rows = page.get_by_test_id("eventlog-row")
    assert rows.filter(has_text="gap completed").count() == 0  # nothing came while cut
    released = True
    held[0].close()  # the page reconnects, to the server this time
    expect(rows.filter(has_text="gap completed")).to_have_count(1)
    stored = _log(server)
    expect(rows).to_have_count(len(stored))
    planted = next(e for e in stored if e["text"].endswith("planted"))  # newest first: the gap's
    expect(page.get_by_test_id("events").locator("li", has_text=planted["text"])).to_have_count(1)
