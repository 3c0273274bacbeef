"""The console's Truth panel (issue 21, item 3) in a real browser against a real server run
with ``ROVEROPS_TRUTH_VIEW=conductor``: a reader without a token and a signed-in viewer see
no Truth panel and no truth plots; a conductor sees every truth readout there (the position
and attitude errors, the true HGA margin, the true position and suspension, the sol's truth
summary) and none of them in the Rover panel; signing out hides it again. A screenshot of
the panel goes to test-artifacts/truth-panel.png."""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest

from tests.browser.test_console_browser import ARTIFACTS, CHROMIUM, TOKEN, console_page, sign_in
from tests.server.test_server_restart import serving

if not Path(CHROMIUM).exists():
    pytest.skip("Chromium not installed (make test installs it)", allow_module_level=True)

from playwright.sync_api import Page, expect

ADMIN = {"Authorization": f"Bearer {TOKEN}"}


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    env = {"ROVEROPS_TRUTH_VIEW": "conductor"}
    with serving(tmp_path_factory.mktemp("truth"), TOKEN, three_d=False, env_extra=env) as base:
        yield base


def _token(server: str, role: str) -> str:
    r = httpx.post(
        f"{server}/api/users", json={"name": f"{role}_user", "role": role}, headers=ADMIN
    )
    assert r.status_code == 201, r.text
    token: str = r.json()["token"]
    return token


def _hidden_truth(page: Page) -> None:
    expect(page.get_by_test_id("truth-panel")).to_be_hidden()
    expect(page.get_by_test_id("plot-position-error")).to_be_hidden()
    expect(page.locator("section.readouts .truth-tag")).to_have_count(0)
    # the telemetry plot lists no truth channel and falls back on the rover's own margin
    expect(page.locator("#plot-channel")).to_have_value("hga_margin_predicted_deg")
    expect(page.locator("#plot-channel option", has_text="· truth")).to_have_count(0)


def test_only_the_truth_view_has_the_truth_panel(server: str) -> None:
    me = httpx.get(f"{server}/api/me").json()
    assert me["truth_view"] == "conductor" and me["sees_truth"] is False
    viewer, conductor = _token(server, "viewer"), _token(server, "conductor")
    drive = {"command": "DRIVE_STRAIGHT", "args": {"distance_m": 2.0}}
    httpx.post(f"{server}/api/rovers/spirit/clock", json={"speed": "max"}, headers=ADMIN)
    assert httpx.post(f"{server}/api/rovers/spirit/commands", json=drive, headers=ADMIN).is_success
    with console_page(f"{server}/?rover=spirit", "truth-panel-page.png") as page:
        expect(page.get_by_test_id("sol-clock")).to_contain_text("LMST")
        expect(page.get_by_test_id("position")).to_contain_text("est")
        _hidden_truth(page)  # reading without a token
        sign_in(page, viewer, "viewer_user · viewer")
        _hidden_truth(page)
        page.click("[data-testid=sign-out]")
        sign_in(page, conductor, "conductor_user · conductor")
        panel = page.get_by_test_id("truth-panel")
        expect(panel).to_be_visible()
        expect(page.get_by_test_id("position-error")).to_have_text(
            re.compile(r"^\d+\.\d\d m \(mission frame, 3D: est .*, true .* m\)$")
        )
        expect(page.get_by_test_id("attitude-error")).to_have_text(re.compile(r"^\d+\.\d{3}°$"))
        expect(page.get_by_test_id("hga-margin")).to_have_text(re.compile(r"°|horizon"))
        expect(page.get_by_test_id("true-position")).to_contain_text("m (Site")
        expect(page.get_by_test_id("true-joints")).to_contain_text("rocker")
        expect(page.get_by_test_id("truth-sol")).to_contain_text("driven (true)")
        expect(page.get_by_test_id("plot-position-error")).to_be_visible()
        expect(page.locator("section.readouts .truth-tag")).to_have_count(0)
        expect(page.locator("#plot-channel option", has_text="· truth").first).to_be_attached()
        ARTIFACTS.mkdir(exist_ok=True)
        panel.screenshot(path=str(ARTIFACTS / "truth-panel.png"))
        page.click("[data-testid=sign-out]")
        _hidden_truth(page)
