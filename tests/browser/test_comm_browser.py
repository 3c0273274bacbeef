"""Operating across light time (issue 23) in a real browser against the real server run with
``ROVEROPS_COMM=mission`` and ``ROVEROPS_TRUTH_VIEW=conductor``: the header says the link
(the light time, the next pass and uplink window, the onboard store); an operator uploads a
drive outside the uplink window and sees it wait on the ground, be radiated in the window,
reach the rover (the onboard side) and be acknowledged there (its stages); a second sequence
cancelled once radiated shows its cancel sent; meanwhile a conductor (another browser
profile) sees the truth live while the operator's data is older; the drive's data arrives
with the next pass with its age shown, and greys as stale when the link brings nothing
newer; the alarms say their data's time and arrival; the sol timeline's Comm lane shows the
windows with what came down. The rover's clock runs at 200x, paused at the moments the test
looks at (found over the API): every wait is for a condition. Screenshots: test-artifacts/."""

from __future__ import annotations

import re
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest

from tests.browser.test_console_browser import (
    ARTIFACTS,
    CHROMIUM,
    LAUNCH_ARGS,
    TOKEN,
    new_token,
    open_console,
)
from tests.server.test_server_restart import _wait, serving

if not Path(CHROMIUM).exists():
    pytest.skip("Chromium not installed (make test installs it)", allow_module_level=True)

from playwright.sync_api import Browser, Locator, Page, expect, sync_playwright

ADMIN = {"Authorization": f"Bearer {TOKEN}"}
ROVER = "spirit"
# the drive, then a wait: the ground hears the sequence acknowledged while it still runs
DRIVE = "SEQUENCE drive_across\nDRIVE_STRAIGHT distance_m=3\nWAIT duration_s=900\n"
LATER = "SEQUENCE later\nNADIR_UPDATE\n"
WAIT_S = 240.0  # the API waits: generous, for a busy machine
MOVED = re.compile(r"^\((?:[3-9]|2\.[5-9])\d*\.?\d*, ")  # the true position after the drive


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    env = {"ROVEROPS_COMM": "mission", "ROVEROPS_TRUTH_VIEW": "conductor"}
    with serving(tmp_path_factory.mktemp("comm"), TOKEN, three_d=False, env_extra=env) as base:
        yield base


@pytest.fixture(scope="module")
def browser() -> Iterator[Browser]:
    ARTIFACTS.mkdir(exist_ok=True)
    with sync_playwright() as p:
        chromium = p.chromium.launch(executable_path=CHROMIUM, args=LAUNCH_ARGS)
        yield chromium
        chromium.close()


def _clock(server: str, body: dict[str, Any]) -> None:
    r = httpx.post(f"{server}/api/rovers/{ROVER}/clock", json=body, headers=ADMIN)
    assert r.status_code == 200, r.text


def _get(server: str, path: str) -> Any:
    r = httpx.get(f"{server}/api/rovers/{ROVER}/{path}", headers=ADMIN)
    assert r.status_code == 200, r.text
    return r.json()


def _entry(server: str, sequence_id: int) -> dict[str, Any] | None:
    return next(
        (q for q in _get(server, "queue")["queue"] if q["sequence_id"] == sequence_id), None
    )


def _pause_when(server: str, condition: Callable[[], Any]) -> Any:
    """The clock paused as soon as ``condition`` (read over the API) holds: what it found."""
    found = _wait(condition, timeout_s=WAIT_S)
    _clock(server, {"action": "pause"})
    return found


def _shot(what: Page | Locator, name: str) -> None:
    """A screenshot in test-artifacts/: a whole page, or one part of it."""
    if isinstance(what, Page):
        what.screenshot(path=str(ARTIFACTS / name), full_page=True)
    else:
        what.screenshot(path=str(ARTIFACTS / name))


def test_a_drive_across_light_time(browser: Browser, server: str) -> None:
    _clock(server, {"action": "pause"})
    comm = _get(server, "comm")
    assert comm["mode"] == "mission"
    operator = open_console(
        browser, server, new_token(server, "opal", "operator"), "opal · operator", ROVER
    )
    conductor = open_console(
        browser, server, new_token(server, "cora", "conductor"), "cora · conductor", ROVER
    )

    # ---- the header: the link, as the ground knows it ----------------------------------
    expect(operator.get_by_test_id("link-mode")).to_have_text("link: mission")
    light = operator.get_by_test_id("light-time")
    expect(light).to_have_text(re.compile(r"^light time 1?\d:\d\d$"))
    shown = (light.text_content() or "").split()[-1].split(":")
    assert abs(int(shown[0]) * 60 + int(shown[1]) - comm["one_way_light_time_s"]) < 2.0
    uplink = comm["next_uplink"]
    assert uplink["start_t_s"] > comm["now"]["t_s"]  # the upload is outside the window
    expect(operator.get_by_test_id("next-uplink")).to_have_text(
        re.compile(r"^uplink: 09:00 LMST, in (\d+ min|\d+ h \d\d min)$")
    )
    expect(operator.get_by_test_id("next-pass")).to_have_text(
        re.compile(r"^next pass: (relay pass|direct-to-Earth) \d\d:\d\d LMST, (in|open)")
    )
    expect(operator.get_by_test_id("store-fill")).to_be_visible()
    expect(operator.get_by_test_id("data-age")).to_have_text(re.compile("^no data on the ground"))
    expect(operator.get_by_test_id("truth-panel")).to_be_hidden()  # the truth is the conductor's

    # ---- uploaded outside the window: it waits on the ground ---------------------------
    operator.fill("#editor", DRIVE)
    operator.click("#upload-text")
    expect(operator.get_by_test_id("sequence-status")).to_contain_text("queued")
    drive = _get(server, "sequences")[0]["id"]
    r = httpx.post(f"{server}/api/rovers/{ROVER}/sequences", content=LATER, headers=ADMIN)
    assert r.status_code == 201, r.text
    later = r.json()["id"]
    ground = operator.get_by_test_id("queue-ground")
    item = ground.locator(f"[data-sequence-id='{drive}']")
    expect(item).to_have_attribute("data-status", "waiting")
    expect(item.get_by_test_id("queue-latest-stage")).to_have_attribute("data-stage", "waiting")
    expect(item.get_by_test_id("queue-next")).to_have_text(
        re.compile(r"^radiates sol \d+ 09:00 LMST, in ")
    )
    expect(operator.get_by_test_id("queue")).to_have_text("2 on the ground, 0 onboard")
    _shot(operator.get_by_test_id("queue-panel"), "comm-queue-waiting.png")

    # ---- radiated in the window; the second one's cancel goes up too --------------------
    _clock(server, {"action": "resume", "speed": 200})
    _pause_when(server, lambda: (e := _entry(server, later)) and e["status"] == "radiated")
    expect(item).to_have_attribute("data-status", "radiated")
    expect(item.get_by_test_id("queue-latest-stage")).to_contain_text(
        re.compile(r"^radiated sol \d+ 09:\d\d LMST \(\d{4}-\d\d-\d\d \d\d:\d\d UTC\)")
    )
    expect(item.get_by_test_id("queue-next")).to_have_text(re.compile("^reaches the rover sol "))
    second = ground.locator(f"[data-sequence-id='{later}']")
    expect(second).to_have_attribute("data-status", "radiated")
    operator.once("dialog", lambda dialog: dialog.accept())
    second.get_by_test_id("queue-cancel").click()
    expect(operator.get_by_test_id("queue-status")).to_have_text(
        re.compile(rf"^Cancel of #{later} later sent: cancel accepted by the ground")
    )
    expect(second.get_by_test_id("queue-cancel-sent")).to_have_text("cancel sent")
    expect(second.get_by_test_id("queue-latest-stage")).to_have_attribute(
        "data-stage", re.compile("^cancel ")
    )
    _shot(operator, "comm-radiated.png")

    # ---- onboard, as the ground knows it: the conductor sees the truth live meanwhile -----
    _clock(server, {"action": "resume", "speed": 100})
    onboard = operator.get_by_test_id("queue-onboard").locator(f"[data-sequence-id='{drive}']")
    expect(onboard).to_have_attribute("data-side", "onboard", timeout=WAIT_S * 1000)
    true_position = conductor.get_by_test_id("true-position")
    expect(true_position).to_have_text(MOVED, timeout=WAIT_S * 1000)
    _clock(server, {"action": "pause"})
    # the drive is done on Mars; its data is on its way down: the operator does not see it
    assert not MOVED.search(operator.get_by_test_id("position").text_content() or "")
    expect(operator.get_by_test_id("position")).not_to_contain_text("est (2.")
    expect(operator.get_by_test_id("position")).not_to_contain_text("est (3.")
    expect(conductor.get_by_test_id("truth-live")).to_be_visible()
    expect(conductor.get_by_test_id("truth-live-note")).to_have_text(
        re.compile(r"^The truth now, sol \d+ \d\d:\d\d LMST; the rover's data on the ground is of ")
    )
    truth_ts = float(conductor.get_by_test_id("truth-live").get_attribute("data-truth-ts") or 0)
    newest = _get(server, "comm")["newest_data"]
    assert newest is None or newest["data"]["t_s"] < truth_ts  # live, ahead of the data
    _shot(conductor, "comm-conductor-live.png")
    _shot(operator, "comm-operator-meanwhile.png")

    # ---- the rover's acknowledgement comes down: received onboard ----------------------
    _clock(server, {"action": "resume", "speed": 200})
    _pause_when(
        server,
        lambda: (e := _entry(server, drive)) and any(s["stage"] == "received" for s in e["stages"]),
    )
    expect(onboard.get_by_test_id("queue-latest-stage")).to_have_attribute(
        "data-stage", re.compile("^(received|started)$")
    )
    onboard.locator("summary").click()
    stages = onboard.get_by_test_id("queue-stage")
    expect(stages.filter(has_text="received")).to_have_count(1)
    expect(stages.first).to_have_attribute("data-stage", "accepted")
    expect(stages.filter(has_text="received")).to_contain_text(re.compile(r"sol \d+ 09:\d\d LMST"))
    _shot(operator.get_by_test_id("queue-panel"), "comm-queue-onboard.png")

    # ---- the drive's data comes down: with its age ---------------------------------------
    _clock(server, {"action": "resume", "speed": 200})
    expect(operator.get_by_test_id("position")).to_have_text(
        re.compile(r"est \((?:[3-9]|2\.[5-9])"), timeout=WAIT_S * 1000
    )
    age = operator.get_by_test_id("data-age")
    expect(age).to_have_text(
        re.compile(r"^data of sol \d+ \d\d:\d\d LMST, received (just now|\d+ min ago)$")
    )
    expect(age).to_have_attribute("data-stale", "false")
    alarm_time = operator.get_by_test_id("alarm-data-time").first
    expect(alarm_time).to_have_text(
        re.compile(r"^data of sol \d+ \d\d:\d\d LMST, received \d+ min later$")
    )
    done = operator.get_by_test_id("queue-recent-item").filter(has_text="drive_across")
    expect(done).to_contain_text("completed", timeout=WAIT_S * 1000)
    # the sol timeline read the sol again as data came down; its Comm lane has the passes
    past = operator.locator("[data-testid=timeline-window][data-when=past][data-kind=dte]")
    expect(past.first).to_have_attribute("data-received-mbit", re.compile(r"^\d+\.?\d*(e-?\d+)?$"))
    assert float(past.first.get_attribute("data-received-mbit") or 0) > 0
    ahead = operator.locator("[data-testid=timeline-window][data-when=ahead]")
    expect(ahead.first).to_be_attached()
    _shot(operator, "comm-data-down.png")

    # ---- nothing newer comes down for long: the data is stale ----------------------------
    _clock(server, {"action": "resume", "speed": 1000})
    expect(age).to_have_attribute("data-stale", "true", timeout=WAIT_S * 1000)
    expect(age).to_have_text(re.compile(r"received (\d+ min|\d+ h \d\d min) ago$"))
    _clock(server, {"action": "pause"})
    expect(operator.get_by_test_id("readouts")).to_have_class(re.compile("data-stale"))
    _shot(operator.get_by_test_id("readouts"), "comm-readouts-stale.png")
    _shot(operator.locator("header"), "comm-header.png")
    _shot(operator, "comm-stale.png")
    _shot(conductor, "comm-conductor.png")
