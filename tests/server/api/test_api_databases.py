"""The whole server on each database: a sequence uploaded, run at full speed, and read back
through the sol timeline and telemetry, on SQLite and on PostgreSQL (``store_url``)."""

from __future__ import annotations

import time

from fastapi.testclient import TestClient

from server.app import ServerConfig, create_app

TOKEN = "db-test-token"
AUTH = {"Authorization": f"Bearer {TOKEN}"}
SEQ = "SEQUENCE db_check\nNADIR_UPDATE\nDRIVE_STRAIGHT distance_m=2\nPLANT_SITE\n"


def test_server_round_trip(store_url: str) -> None:
    app = create_app(ServerConfig(database_url=store_url, operator_token=TOKEN))
    with TestClient(app) as client:
        client.post("/api/rovers/opportunity/clock", json={"speed": "max"}, headers=AUTH)
        r = client.post("/api/rovers/opportunity/sequences", content=SEQ, headers=AUTH)
        assert r.status_code == 201, r.text
        seq_id = r.json()["id"]
        deadline = time.monotonic() + 60.0
        while client.get(f"/api/sequences/{seq_id}").json()["status"] != "completed":
            assert time.monotonic() < deadline
            time.sleep(0.1)
        while client.get("/api/rovers/opportunity/state").json()["executing"]:
            assert time.monotonic() < deadline
            time.sleep(0.1)
        sol = client.get("/api/rovers/opportunity/sols").json()[-1]
        timeline = client.get(f"/api/rovers/opportunity/sols/{sol}/timeline").json()
        assert [c["status"] for c in timeline["commands"]] == ["completed"] * 3
        assert 1.9 < timeline["distance_m"] < 2.2
        assert any("Site 1 planted" in e["text"] for e in timeline["events"])
        frames = client.get("/api/rovers/opportunity/telemetry").json()
        assert frames[-1]["site_index"] == 1 and frames[-1]["p_s_true"] == [0.0, 0.0, 0.0]
