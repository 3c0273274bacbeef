"""The Faults panel (issue 22, item 4) in a real browser against a real server in training
mode (``ROVEROPS_TRUTH_VIEW=conductor``): a conductor injects a sand trap across the rover's
path from the panel, sees it applied in the list and on the sol timeline; the operator's VO
drive halts on its slip check, and the operator's console shows the halt and its reason but
no Faults panel and no fault anywhere; after the conductor reveals the faults, the
operator's timeline shows the sand trap. Screenshots go to test-artifacts/."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

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
from tests.server.test_server_restart import serving

if not Path(CHROMIUM).exists():
    pytest.skip("Chromium not installed (make test installs it)", allow_module_level=True)

from playwright.sync_api import Browser, expect, sync_playwright

ADMIN = {"Authorization": f"Bearer {TOKEN}"}


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    env = {"ROVEROPS_TRUTH_VIEW": "conductor"}
    with serving(tmp_path_factory.mktemp("faults"), TOKEN, three_d=False, env_extra=env) as base:
        yield base


@pytest.fixture(scope="module")
def browser() -> Iterator[Browser]:
    ARTIFACTS.mkdir(exist_ok=True)
    with sync_playwright() as p:
        chromium = p.chromium.launch(executable_path=CHROMIUM, args=LAUNCH_ARGS)
        yield chromium
        chromium.close()


def test_a_conductor_injects_an_operator_sees_it_only_once_revealed(
    browser: Browser, server: str
) -> None:
    conductor = open_console(
        browser,
        server,
        new_token(server, "conductor_f", "conductor"),
        "conductor_f · conductor",
        "spirit",
    )
    operator_token = new_token(server, "operator_f", "operator")
    operator = open_console(browser, server, operator_token, "operator_f · operator", "spirit")
    expect(operator.get_by_test_id("faults-panel")).to_be_hidden()
    expect(conductor.get_by_test_id("faults-panel")).to_be_visible()
    conductor.select_option("[data-testid=fault-kind]", "sand_trap")
    for name, value in (("x_m", "2.5"), ("y_m", "0"), ("radius_m", "1.5")):
        conductor.fill(f"[data-testid=fault-param-{name}]", value)
    conductor.click("[data-testid=fault-inject]")
    expect(conductor.get_by_test_id("fault-status")).to_contain_text("injected: sand trap")
    # the operator drives into it with VO, a slip check every 2 m: the rover halts
    drive = (
        "SEQUENCE into_the_trap\n"
        "SET_PARAM param=mobility.slip_check_m value=2\n"
        "DRIVE_STRAIGHT distance_m=6 vo=on\n"
    )
    operator_auth = {"Authorization": f"Bearer {operator_token}"}
    sent = httpx.post(f"{server}/api/rovers/spirit/sequences", content=drive, headers=operator_auth)
    assert sent.status_code == 201, sent.text
    assert httpx.post(f"{server}/api/rovers/spirit/clock", json={"speed": "max"},
                      headers=ADMIN).is_success  # fmt: skip
    expect(operator.get_by_test_id("mobility")).to_contain_text(
        "HALTED: slip check", timeout=120_000
    )
    expect(operator.get_by_test_id("events")).to_contain_text("drive halted by fault protection")
    row = conductor.get_by_test_id("fault-row")
    expect(row).to_have_attribute("data-state", "applied", timeout=30_000)
    expect(row).to_have_attribute("data-revealed", "")
    conductor.click("#timeline-refresh")
    expect(conductor.get_by_test_id("timeline-fault")).to_have_count(1)
    # the operator's console: no fault anywhere, not on the timeline
    operator.click("#timeline-refresh")
    expect(operator.get_by_test_id("timeline-summary")).to_contain_text("Sol")
    expect(operator.get_by_test_id("timeline-fault")).to_have_count(0)
    expect(operator.locator("body")).not_to_contain_text("sand trap")
    conductor.click("[data-testid=fault-reveal]")
    expect(conductor.get_by_test_id("fault-status")).to_contain_text("1 fault revealed")
    expect(row).to_have_attribute("data-revealed", "1")
    # for the debrief: the operator's timeline shows it now
    operator.click("#timeline-refresh")
    mark = operator.get_by_test_id("timeline-fault")
    expect(mark).to_have_count(1)
    assert "sand trap" in (mark.get_attribute("title") or "")
    conductor.screenshot(path=str(ARTIFACTS / "faults-conductor.png"), full_page=True)
    operator.screenshot(path=str(ARTIFACTS / "faults-operator-debrief.png"), full_page=True)
