"""A rejected upload is listed with the name its text declares and a detail that says why
(issue 14, item 6: rejected sequences were listed with an empty detail). Nothing is queued."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from fastapi.testclient import TestClient

from server.app import ServerConfig, create_app, data_dir_url

TOKEN = "rejected-test-token"
AUTH = {"Authorization": f"Bearer {TOKEN}"}
TWO_ERRORS = "SEQUENCE broken\nDRIVE_STRAIGHT distance_m=-3\nNADIR_UPDATE\nFLY_AWAY\n"
FIVE_ERRORS = "SEQUENCE many\n" + "FLY_AWAY\n" * 5


@pytest.fixture(scope="module")
def client(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    url = data_dir_url(tmp_path_factory.mktemp("rejected"))
    config = ServerConfig(
        database_url=url, operator_token=TOKEN, start_clocks=False, validation_processes=0
    )
    with TestClient(create_app(config)) as c:
        yield c


def _listed(client: TestClient, seq_id: int) -> dict[str, object]:
    rows = client.get("/api/rovers/spirit/sequences").json()
    found: dict[str, object] = next(r for r in rows if r["id"] == seq_id)
    return found


def test_a_rejected_upload_is_listed_with_its_name_and_errors(client: TestClient) -> None:
    r = client.post("/api/rovers/spirit/sequences", content=TWO_ERRORS, headers=AUTH)
    assert r.status_code == 422
    row = _listed(client, r.json()["id"])
    assert (row["name"], row["status"]) == ("broken", "rejected")
    detail = str(row["detail"])
    assert detail.startswith("rejected: 2 errors: line 2: ")
    assert "; line 4: " in detail and "FLY_AWAY" in detail
    assert client.get("/api/rovers/spirit/state").json()["queue"] == []


def test_a_long_list_of_errors_is_quoted_in_part(client: TestClient) -> None:
    r = client.post("/api/rovers/spirit/sequences", content=FIVE_ERRORS, headers=AUTH)
    detail = str(_listed(client, r.json()["id"])["detail"])
    assert detail.startswith("rejected: 5 errors: line 2: ")
    assert detail.count("line ") == 3 and detail.endswith("; 2 more")


def test_a_json_upload_keeps_its_declared_name(client: TestClient) -> None:
    body = {"name": "json_broken", "steps": [{"command": "FLY_AWAY"}]}
    r = client.post("/api/rovers/spirit/sequences", json=body, headers=AUTH)
    assert r.status_code == 422
    row = _listed(client, r.json()["id"])
    assert row["name"] == "json_broken" and str(row["detail"]).startswith("rejected: 1 error: ")
