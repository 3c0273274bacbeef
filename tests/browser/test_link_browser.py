"""A dead server does not look alive (issue 21): the console runs a drive at 10x, the server
is killed (SIGKILL), and the console says the link is lost (a banner) and greys its readouts
with their age; the server is started again on the same data directory and port, and the
banner goes, the readouts are live again, and the server's restart is listed in the event
log and marked on the sol timeline. Every wait is for a condition, never a fixed time.
Screenshots go to test-artifacts/."""

from __future__ import annotations

import re
import signal
import subprocess
from pathlib import Path

import httpx

from tests.browser.test_console_browser import ARTIFACTS, CHROMIUM, LAUNCH_ARGS
from tests.server.test_server_restart import _free_port, _start, _wait

from playwright.sync_api import expect, sync_playwright  # isort: skip

TOKEN = "link-browser-token"
AUTH = {"Authorization": f"Bearer {TOKEN}"}
DRIVE = "SEQUENCE long_drive\nDRIVE_STRAIGHT distance_m=100\n"  # 2,667 s: outlasts the test
TIMEOUT_MS = 90_000  # generous: the test must pass with both cores busy
AGE = re.compile(r"^(?:[2-9]|\d{2,}) s old$")  # the readouts at least 2 s old


def _up(data_dir: Path, port: int) -> subprocess.Popen[bytes]:
    proc = _start(data_dir, port, TOKEN, three_d=False)
    _wait(lambda: httpx.get(f"http://127.0.0.1:{port}/api/rovers").status_code == 200)
    return proc


def test_a_killed_server_is_shown_lost_and_its_restart_is_recorded(tmp_path: Path) -> None:
    ARTIFACTS.mkdir(exist_ok=True)
    expect.set_options(timeout=TIMEOUT_MS)
    port = _free_port()
    base = f"http://127.0.0.1:{port}"
    procs = [_up(tmp_path, port)]
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=LAUNCH_ARGS)
        page = browser.new_page(viewport={"width": 1280, "height": 800})
        page.set_default_timeout(TIMEOUT_MS)
        try:
            httpx.post(f"{base}/api/rovers/spirit/clock", json={"speed": 10}, headers=AUTH)
            answer = httpx.post(f"{base}/api/rovers/spirit/sequences", content=DRIVE, headers=AUTH)
            assert answer.status_code == 201, answer.text
            page.goto(f"{base}/?rover=spirit")
            banner = page.get_by_test_id("link-banner")
            readouts = page.get_by_test_id("readouts")
            age = page.get_by_test_id("readouts-age")
            expect(page.get_by_test_id("executing")).to_contain_text("DRIVE_STRAIGHT")
            expect(page.get_by_test_id("clock-speed")).to_have_text("running at 10×")
            expect(banner).to_be_hidden()
            expect(readouts).not_to_have_class(re.compile(r"\bstale\b"))

            procs[0].send_signal(signal.SIGKILL)
            procs[0].wait(timeout=30)
            expect(banner).to_be_visible()
            expect(banner).to_contain_text("lost")
            expect(readouts).to_have_class(re.compile(r"\bstale\b"))
            expect(page.get_by_test_id("clock-speed")).to_have_class(re.compile(r"\bstale\b"))
            expect(age).to_have_text(AGE)  # and it keeps counting while the link is down
            page.screenshot(path=str(ARTIFACTS / "link_lost.png"), full_page=True)

            procs.append(_up(tmp_path, port))
            expect(banner).to_be_hidden()
            expect(readouts).not_to_have_class(re.compile(r"\bstale\b"))
            expect(age).to_be_hidden()
            restart = page.get_by_test_id("eventlog-row").filter(has_text="server restarted")
            expect(restart).to_have_count(1)
            expect(restart).to_have_attribute("data-kind", "server")
            mark = page.locator("[data-testid=timeline-event][data-texts*='server restarted']")
            expect(mark).to_have_count(1)
            expect(page.get_by_test_id("executing")).to_contain_text("DRIVE_STRAIGHT")
            page.screenshot(path=str(ARTIFACTS / "link_back.png"), full_page=True)
        except Exception:
            page.screenshot(path=str(ARTIFACTS / "link_failed.png"), full_page=True)
            raise
        finally:
            browser.close()
            for proc in procs:
                if proc.poll() is None:
                    proc.kill()
                proc.wait(timeout=10)
