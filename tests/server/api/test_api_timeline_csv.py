"""The sol CSV download (``GET /api/rovers/{rover}/sols/{sol}/telemetry.csv``) against a
real app on a temporary SQLite database, after the example sequence ran at full speed: the
file is the sol's frames (the same rows as the JSON telemetry over the sol), named for the
rover and sol, decimated by ``every`` without losing an event row; bad input is a 4xx
naming the problem. The console's vendored plot library is served from /static."""

from __future__ import annotations

import csv
import io
import posixpath
import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from server.api.telemetry_csv import CSV_COLUMNS
from server.app import ServerConfig, create_app, data_dir_url
from tests.server.api.test_api import _wait

TOKEN = "csv-test-token"
AUTH = {"Authorization": f"Bearer {TOKEN}"}
EXAMPLE = Path(__file__).resolve().parents[3] / "sequences/examples/fine_attitude_then_drive.seq"


@pytest.fixture(scope="module")
def client(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    url = data_dir_url(tmp_path_factory.mktemp("csv"))
    app = create_app(ServerConfig(database_url=url, operator_token=TOKEN))
    with TestClient(app) as c:
        r = c.post("/api/rovers/spirit/sequences", content=EXAMPLE.read_text(), headers=AUTH)
        assert r.status_code == 201, r.text
        seq_id = r.json()["id"]
        c.post("/api/rovers/spirit/clock", json={"speed": "max"}, headers=AUTH).raise_for_status()
        _wait(lambda: c.get(f"/api/sequences/{seq_id}").json()["status"] == "completed")
        _wait(lambda: not c.get("/api/rovers/spirit/state").json()["executing"])
        yield c


@pytest.fixture(scope="module")
def sol(client: TestClient) -> int:
    sols: list[int] = client.get("/api/rovers/spirit/sols").json()
    return sols[-1]


def _rows(text: str) -> list[dict[str, str]]:
    return list(csv.DictReader(io.StringIO(text)))


def _sol_frames(client: TestClient, sol: int, every: float = 0.0) -> list[dict[str, Any]]:
    timeline = client.get(f"/api/rovers/spirit/sols/{sol}/timeline").json()
    params = {
        "from": timeline["start"]["t_s"],
        "to": timeline["end"]["t_s"],
        "every": every,
        "limit": 200_000,
    }
    frames: list[dict[str, Any]] = client.get("/api/rovers/spirit/telemetry", params=params).json()
    return frames


def test_the_csv_is_the_sols_frames_as_an_attachment(client: TestClient, sol: int) -> None:
    r = client.get(f"/api/rovers/spirit/sols/{sol}/telemetry.csv")
    assert r.status_code == 200
    assert r.headers["content-type"].startswith("text/csv")
    assert r.headers["content-disposition"] == f'attachment; filename="spirit_sol{sol}.csv"'
    header = r.text.splitlines()[0].split(",")
    assert header[: len(CSV_COLUMNS)] == list(CSV_COLUMNS) and header[-1] == "events"
    rows = _rows(r.text)
    frames = _sol_frames(client, sol)
    assert len(rows) == len(frames) > 100
    assert [float(row["t_s"]) for row in rows] == [f["t_s"] for f in frames]
    assert {row["sol"] for row in rows} == {str(sol)}
    assert "Fine" in {row["aqf"] for row in rows}
    assert any("Sungaze: converged" in row["events"] for row in rows)
    assert all(len(row) == len(header) for row in rows)  # no ragged row (DictReader: None key)


def test_every_decimates_but_keeps_every_event_row(client: TestClient, sol: int) -> None:
    full = _rows(client.get(f"/api/rovers/spirit/sols/{sol}/telemetry.csv").text)
    r = client.get(f"/api/rovers/spirit/sols/{sol}/telemetry.csv", params={"every": 60})
    assert r.status_code == 200
    rows = _rows(r.text)
    assert [float(row["t_s"]) for row in rows] == [f["t_s"] for f in _sol_frames(client, sol, 60)]
    assert 5 < len(rows) < len(full) / 5
    events = [row["events"] for row in full if row["events"]]
    assert [row["events"] for row in rows if row["events"]] == events
    times = [float(row["t_s"]) for row in rows]
    quiet_gaps = [
        b - a for a, b, row in zip(times, times[1:], rows[1:], strict=False) if not row["events"]
    ]
    assert min(quiet_gaps) >= 60.0


def test_an_unknown_rover_or_a_sol_without_telemetry_is_404(client: TestClient, sol: int) -> None:
    r = client.get(f"/api/rovers/curiosity/sols/{sol}/telemetry.csv")
    assert r.status_code == 404 and "curiosity" in r.json()["detail"]
    r = client.get("/api/rovers/spirit/sols/99999/telemetry.csv")
    assert r.status_code == 404 and "sol 99999" in r.json()["detail"]
    r = client.get(f"/api/rovers/opportunity/sols/{sol}/telemetry.csv")  # spirit's sol only
    assert r.status_code == 404 and "opportunity" in r.json()["detail"]


@pytest.mark.parametrize("every", ["-1", "86401", "abc", "nan"])
def test_a_bad_every_is_422_naming_it(client: TestClient, sol: int, every: str) -> None:
    r = client.get(f"/api/rovers/spirit/sols/{sol}/telemetry.csv?every={every}")
    assert r.status_code == 422
    assert r.json()["detail"][0]["loc"] == ["query", "every"]


def test_a_sol_that_is_not_a_number_is_422(client: TestClient) -> None:
    r = client.get("/api/rovers/spirit/sols/latest/telemetry.csv")
    assert r.status_code == 422
    assert r.json()["detail"][0]["loc"] == ["path", "sol"]


def test_the_vendored_plot_library_is_served_locally(client: TestClient) -> None:
    page = client.get("/").text
    for path in ("/static/vendor/uplot/uPlot.iife.min.js", "/static/vendor/uplot/uPlot.min.css"):
        assert path in page
        r = client.get(path)
        assert r.status_code == 200 and len(r.content) > 1000
    js = client.get("/static/vendor/uplot/uPlot.iife.min.js")
    assert "javascript" in js.headers["content-type"] and "var uPlot=" in js.text
    assert '<script type="module" src="/static/main.js">' in page
    # the console's module graph from its one entry: every import served, as JavaScript
    # (a browser refuses a module of another type)
    seen, todo = set(), ["/static/main.js"]
    while todo:
        path = todo.pop()
        if path in seen:
            continue
        seen.add(path)
        r = client.get(path)
        assert r.status_code == 200 and "javascript" in r.headers["content-type"], path
        for spec in re.findall(r'^\s*import\b[^"\']*["\'](\.{1,2}/[^"\']+)["\']', r.text, re.M):
            todo.append(posixpath.normpath(posixpath.join(posixpath.dirname(path), spec)))
    assert {"/static/timeline/panel.js", "/static/lib/api.js"} <= seen  # the walk went deep
