"""The Queue panel in a real browser (issue 14, "queue reorder and cancel"): with the clock
paused, three sequences uploaded; the third moved up and the second cancelled from the
panel; the order and every step's status shown in the panel and served by the API; then
the clock resumed: the first sequence's step shows as running and it keeps its place, and
at full speed the two left run in the new order. Screenshots in test-artifacts/."""

from __future__ import annotations

import re
from collections.abc import Iterator
from typing import Any

import httpx
import pytest
from playwright.sync_api import Page, expect

from tests.browser.test_console_browser import ARTIFACTS, TOKEN, console_page, sign_in
from tests.server.test_server_restart import serving

AUTH = {"Authorization": f"Bearer {TOKEN}"}
SEQ = "SEQUENCE {name}\nNADIR_UPDATE\nWAIT duration_s=60\n"


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """The real server, without the 3D view (this page does not need it)."""
    with serving(tmp_path_factory.mktemp("queue"), TOKEN, three_d=False) as base:
        yield base


def _clock(base: str, body: dict[str, Any]) -> None:
    httpx.post(f"{base}/api/rovers/spirit/clock", json=body, headers=AUTH).raise_for_status()


def _upload(base: str, name: str) -> int:
    r = httpx.post(
        f"{base}/api/rovers/spirit/sequences", content=SEQ.format(name=name), headers=AUTH
    )
    assert r.status_code == 201, r.text
    sequence_id: int = r.json()["id"]
    return sequence_id


def _order(page: Page) -> list[int]:
    ids: list[str] = page.eval_on_selector_all(
        "[data-testid=queue-list] > [data-testid=queue-item]",
        "els => els.map(e => e.dataset.sequenceId)",
    )
    return [int(i) for i in ids]


def test_reorder_and_cancel_from_the_panel_then_run_in_the_new_order(server: str) -> None:
    _clock(server, {"action": "pause"})
    alpha, bravo, charlie = (_upload(server, n) for n in ("alpha", "bravo", "charlie"))
    with console_page(f"{server}/?rover=spirit", "queue.png") as page:
        sign_in(page)
        items = page.locator("[data-testid=queue-list] > [data-testid=queue-item]")
        expect(items).to_have_count(3)
        assert _order(page) == [alpha, bravo, charlie]
        expect(items.nth(0).get_by_test_id("queue-up")).to_be_disabled()
        expect(items.nth(2).get_by_test_id("queue-down")).to_be_disabled()

        items.nth(2).get_by_test_id("queue-up").click()  # charlie up, past bravo
        expect(items.nth(1)).to_have_attribute("data-sequence-id", str(charlie))
        assert _order(page) == [alpha, charlie, bravo]
        expect(page.get_by_test_id("queue-status")).to_have_text(
            f"Sequence #{charlie} moved to position 2"
        )

        page.once("dialog", lambda dialog: dialog.accept())
        items.nth(2).get_by_test_id("queue-cancel").click()  # bravo, now third
        expect(items).to_have_count(2)
        assert _order(page) == [alpha, charlie]
        left = page.get_by_test_id("queue-recent-item")
        expect(left.first).to_have_attribute("data-sequence-id", str(bravo))
        expect(left.first).to_contain_text("cancelled")
        left.first.locator("summary").click()
        expect(left.first).to_contain_text("before it started (2 step(s) not run)")
        steps = left.first.get_by_test_id("queue-step")
        expect(steps).to_have_count(2)
        expect(steps.nth(0)).to_have_attribute("data-status", "skipped")

        items.nth(0).locator("summary").click()  # alpha's steps
        alpha_steps = items.nth(0).get_by_test_id("queue-step")
        expect(alpha_steps).to_have_count(2)
        expect(alpha_steps.nth(0)).to_contain_text("NADIR_UPDATE")
        expect(alpha_steps.nth(1)).to_have_attribute("data-status", "pending")
        page.get_by_test_id("queue-panel").screenshot(path=str(ARTIFACTS / "queue-panel.png"))
        page.set_viewport_size({"width": 760, "height": 900})  # a narrow window: no overflow
        panel = page.get_by_test_id("queue-panel")
        assert panel.evaluate("e => e.scrollWidth <= e.clientWidth")
        panel.screenshot(path=str(ARTIFACTS / "queue-panel-760.png"))
        page.set_viewport_size({"width": 1280, "height": 800})

        body = httpx.get(f"{server}/api/rovers/spirit/queue").json()
        assert [q["sequence_id"] for q in body["queue"]] == [alpha, charlie]
        assert all(s["status"] == "pending" for q in body["queue"] for s in q["steps"])
        assert body["recent"][0]["sequence_id"] == bravo
        assert body["recent"][0]["status"] == "cancelled"

        _clock(server, {"action": "resume", "speed": 1})  # alpha starts, and plays out slowly
        expect(alpha_steps.nth(0)).to_have_attribute("data-status", re.compile("running|completed"))
        expect(items.nth(0)).to_contain_text(
            re.compile(r"running, step [12] of 2|started, step 2 of 2 next")
        )
        up = items.nth(1).get_by_test_id("queue-up")  # charlie may not pass a started alpha
        expect(up).to_be_disabled()
        expect(up).to_have_attribute("title", f"#{alpha} keeps its place")
        expect(items.nth(0).get_by_test_id("queue-down")).to_have_attribute(
            "title", re.compile("has started")
        )
        page.get_by_test_id("queue-panel").screenshot(
            path=str(ARTIFACTS / "queue-panel-running.png")
        )

        _clock(server, {"speed": "max"})
        expect(page.get_by_test_id("queue-panel")).to_contain_text("The queue is empty.")
        expect(left).to_have_count(3)
        done = {
            s["sequence_id"]: s
            for s in httpx.get(f"{server}/api/rovers/spirit/queue").json()["recent"]
        }
        assert [done[i]["status"] for i in (alpha, bravo, charlie)] == [
            "completed", "cancelled", "completed"
        ]  # fmt: skip
        alpha_end = done[alpha]["steps"][-1]["end"]["t_s"]
        charlie_start = done[charlie]["steps"][0]["start"]["t_s"]
        assert alpha_end <= charlie_start  # in the new order
        page.get_by_test_id("queue-panel").screenshot(path=str(ARTIFACTS / "queue-panel-done.png"))
