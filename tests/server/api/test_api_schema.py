"""``GET /api/schema/downlink`` and ``/api/schema/truth``: the JSON schemas of a frame's two
records, and the console read against them.

Every frame field the console's scripts read must be in one of the schemas, so that renaming
a field of ``Downlink`` or ``Truth`` fails here rather than leaving a blank in the browser. The
modules that read frames name a frame ``f`` (readouts.js, plot.js, truth.js, the timeline's
modules) or ``frame`` (eventlog.js; in view3d.js ``frame`` is the 3D view's iframe); the
timeline's band lanes name the field they follow in a string (``bandLane(..., "nate_mode")``).
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from server.app import ServerConfig, create_app, data_dir_url
from sim.loop.downlink import downlink_schema
from sim.scoring.truth import truth_schema

WEB = Path(__file__).resolve().parents[3] / "web"
TOKEN = "schema-test-token"
# the name a script gives a telemetry frame
FRAME_NAMES = {
    "readouts.js": "f",
    "plot.js": "f",
    "truth.js": "f",
    "eventlog.js": "frame",
    "timeline/panel.js": "f",
    "timeline/plots.js": "f",
    "timeline/lanes.js": "f",
}


def _nan_as_null(value: Any) -> Any:
    if isinstance(value, float) and math.isnan(value):
        return None
    if isinstance(value, dict):
        return {k: _nan_as_null(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_nan_as_null(v) for v in value]
    return value


def frame_fields_read(script: str, name: str) -> set[str]:
    """The properties read of ``name`` in a script: ``f.sol``, ``f?.sol``, ``f["sol"]``.

    >>> sorted(frame_fields_read('x = f.sol + f?.t_s; y = f["aqf"]; g.no; ff.no', "f"))
    ['aqf', 'sol', 't_s']
    """
    dotted = re.findall(rf"(?<![\w$.]){name}\??\.([A-Za-z_$][\w$]*)", script)
    indexed = re.findall(rf"(?<![\w$.]){name}\[\s*[\"']([A-Za-z_$][\w$]*)[\"']\s*\]", script)
    return set(dotted) | set(indexed)


def lane_fields(script: str) -> set[str]:
    """The frame fields the timeline's band lanes follow (``bandLane``'s last argument)."""
    return set(re.findall(r"bandLane\([^()]*,\s*\"(\w+)\"\s*\)", script))


@pytest.fixture(scope="module", params=[True, False], ids=["public-read", "private"])
def client(
    request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory
) -> Iterator[tuple[TestClient, bool]]:
    config = ServerConfig(
        database_url=data_dir_url(tmp_path_factory.mktemp("schema")),
        operator_token=TOKEN,
        public_read=request.param,
        start_clocks=False,
    )
    with TestClient(create_app(config)) as c:
        yield c, request.param


def test_the_schema_route_answers_as_the_state_route_does(client: tuple[TestClient, bool]) -> None:
    c, public_read = client
    token = {"Authorization": f"Bearer {TOKEN}"}
    for headers in ({}, token):
        for record in ("downlink", "truth"):
            schema = c.get(f"/api/schema/{record}", headers=headers)
            state = c.get("/api/rovers/spirit/state", headers=headers)
            assert schema.status_code == state.status_code, (headers, schema.text)
    # as JSON: the schema's NaN default (no value yet) is null, as a frame sends it
    for record, schema_of in (("downlink", downlink_schema), ("truth", truth_schema)):
        sent = c.get(f"/api/schema/{record}", headers=token).json()
        assert sent == _nan_as_null(schema_of())
        if not public_read:
            assert c.get(f"/api/schema/{record}").status_code == 401
        bad = c.get(f"/api/schema/{record}", headers={"Authorization": "Bearer wrong"})
        assert bad.status_code == 403


def test_the_two_records_share_only_their_time() -> None:
    downlink = set(downlink_schema()["properties"])
    truth = set(truth_schema()["properties"])
    assert downlink & truth == {"t_s", "events", "estimators"}
    for name in truth - {"t_s", "events", "estimators"}:  # every truth figure described
        assert truth_schema()["properties"][name].get("description"), name


def test_every_frame_field_the_console_reads_is_in_the_schema(
    client: tuple[TestClient, bool],
) -> None:
    c, _ = client
    fields: set[str] = set()
    for record in ("downlink", "truth"):
        got = c.get(f"/api/schema/{record}", headers={"Authorization": f"Bearer {TOKEN}"})
        fields |= set(got.json()["properties"])
    # and what the WebSocket's frame message adds to the records (its arrival across light
    # time, the truth view's live truth time)
    ws = c.get("/api/schema/ws", headers={"Authorization": f"Bearer {TOKEN}"}).json()
    fields |= {"received_t_s", "truth_t_s"} & set(ws["$defs"]["FrameMessage"]["properties"])
    read: dict[str, set[str]] = {}
    for script, name in FRAME_NAMES.items():
        text = (WEB / script).read_text(encoding="utf-8")
        read[script] = frame_fields_read(text, name)
        assert read[script], f"{script}: no read of a frame named {name!r} found"
    lanes = lane_fields((WEB / "timeline/lanes.js").read_text(encoding="utf-8"))
    assert {"nate_mode", "aqf"} <= lanes  # the extraction finds the lanes
    read["timeline/lanes.js"] |= lanes
    unknown = {f"{script}: {field}" for script, got in read.items() for field in got - fields}
    assert not unknown, f"the console reads fields a frame does not have: {sorted(unknown)}"


def test_a_renamed_field_would_be_caught() -> None:
    console = (WEB / "readouts.js").read_text(encoding="utf-8")
    fields = set(downlink_schema()["properties"]) | set(truth_schema()["properties"])
    assert "hga_margin_predicted_deg" in frame_fields_read(console, "f")
    renamed = fields - {"hga_margin_predicted_deg"} | {"hga_margin_now_deg"}
    assert frame_fields_read(console, "f") - renamed == {"hga_margin_predicted_deg"}
