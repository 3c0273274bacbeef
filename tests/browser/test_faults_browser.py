"""The Faults panel (issue 22, item 4) in a real browser against a real server in training
mode (``ROVEROPS_TRUTH_VIEW=conductor``): a conductor injects a gyro bias fault from the
panel, sees it applied in the list and on the sol timeline; an operator's console shows no
Faults panel and no fault anywhere; after the conductor reveals the faults, the operator's
timeline shows it. Screenshots go to test-artifacts/."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest

from tests.browser.test_console_browser import ARTIFACTS, CHROMIUM, LAUNCH_ARGS, TOKEN, sign_in
from tests.server.test_server_restart import serving

if not Path(CHROMIUM).exists():
    pytest.skip("Chromium not installed (make test installs it)", allow_module_level=True)

from playwright.sync_api import Browser, Page, expect, sync_playwright

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


def _token(server: str, role: str) -> str:
    r = httpx.post(f"{server}/api/users", json={"name": f"{role}_f", "role": role}, headers=ADMIN)
    assert r.status_code == 201, r.text
    token: str = r.json()["token"]
    return token


def _console(browser: Browser, server: str, token: str, who: str) -> Page:
    page = browser.new_context(viewport={"width": 1280, "height": 900}).new_page()
    page.goto(f"{server}/?rover=spirit")
    expect(page.get_by_test_id("sol-clock")).to_contain_text("LMST")
    sign_in(page, token, who)
    return page


def test_a_conductor_injects_an_operator_sees_it_only_once_revealed(
    browser: Browser, server: str
) -> None:
    conductor = _console(browser, server, _token(server, "conductor"), "conductor_f · conductor")
    operator = _console(browser, server, _token(server, "operator"), "operator_f · operator")
    expect(operator.get_by_test_id("faults-panel")).to_be_hidden()
    expect(conductor.get_by_test_id("faults-panel")).to_be_visible()
    conductor.select_option("[data-testid=fault-kind]", "gyro_bias")
    conductor.select_option("[data-testid=fault-param-axis]", "z")
    conductor.fill("[data-testid=fault-param-bias_deg_per_h]", "10")
    conductor.click("[data-testid=fault-inject]")
    expect(conductor.get_by_test_id("fault-status")).to_contain_text(
        "injected: gyro z bias step +10 deg/h"
    )
    # the fault takes effect as the next command starts
    assert httpx.post(f"{server}/api/rovers/spirit/clock", json={"speed": "max"},
                      headers=ADMIN).is_success  # fmt: skip
    wait = {"command": "WAIT", "args": {"duration_s": 20.0}}
    assert httpx.post(f"{server}/api/rovers/spirit/commands", json=wait, headers=ADMIN).is_success
    row = conductor.get_by_test_id("fault-row")
    expect(row).to_have_attribute("data-state", "applied", timeout=30_000)
    expect(row).to_have_attribute("data-revealed", "")
    conductor.click("#timeline-refresh")
    expect(conductor.get_by_test_id("timeline-fault")).to_have_count(1)
    # the operator's console: no fault anywhere, not on the timeline
    operator.click("#timeline-refresh")
    expect(operator.get_by_test_id("timeline-summary")).to_contain_text("Sol")
    expect(operator.get_by_test_id("timeline-fault")).to_have_count(0)
    expect(operator.locator("body")).not_to_contain_text("bias step")
    conductor.click("[data-testid=fault-reveal]")
    expect(conductor.get_by_test_id("fault-status")).to_contain_text("1 fault revealed")
    expect(row).to_have_attribute("data-revealed", "1")
    # for the debrief: the operator's timeline shows it now
    operator.click("#timeline-refresh")
    mark = operator.get_by_test_id("timeline-fault")
    expect(mark).to_have_count(1)
    assert "gyro z bias step +10 deg/h" in (mark.get_attribute("title") or "")
    conductor.screenshot(path=str(ARTIFACTS / "faults-conductor.png"), full_page=True)
    operator.screenshot(path=str(ARTIFACTS / "faults-operator-debrief.png"), full_page=True)
