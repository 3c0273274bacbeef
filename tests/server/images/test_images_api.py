"""Images on the ground: stored once, as PNG, when they arrive (``server.storage.images``),
and served as stored (``server.images.api``): the same bytes on every read, decoding to the
pixels the rover sent; the routes validate their ids and filters and need a reader's token.
One image comes the whole way: NAVCAM_STEREO in a sequence, played out with its frames."""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient

from server.app import ServerConfig, create_app, data_dir_url
from server.storage.images import decode_png, image_png, list_images, stereo_pairs
from sim.loop.images import image_record

TOKEN = "images-admin-token"
AUTH = {"Authorization": f"Bearer {TOKEN}"}


def _record(t_s: float, kind: str = "vo_pair", seed: int = 1) -> Any:
    rng = np.random.default_rng(seed)
    left = rng.uniform(0.0, 4095.0, (64, 64)).astype(np.float32)
    right = rng.uniform(0.0, 4095.0, (64, 64)).astype(np.float32)
    vo = None
    features = None
    if kind == "vo_pair":
        vo = {"step": 1, "steps": 2, "status": "converged", "reason": "ok", "n_features": 3,
              "n_tracked": 2, "n_inliers": 1, "p_mission_vo": [1.0, 0.0, 0.0],
              "q_b_ll_vo": [0.0, 0.0, 0.0, 1.0]}  # fmt: skip
        features = {"features_uv_px": [[1.0, 2.0], [3.0, 4.0], [5.5, 6.5]],
                    "tracked_previous_uv_px": [[1.0, 1.0], [2.0, 2.0]],
                    "tracked_uv_px": [[1.5, 1.0], [2.5, 2.0]], "inlier": [True, False]}  # fmt: skip
    return image_record(
        t_s=t_s, kind=kind, left_dn=left, right_dn=right, f_px=77.0, baseline_m=0.2,  # type: ignore[arg-type]
        mast_az_rad=0.0, mast_el_rad=-0.6, site_index=0, p_s_est=[1.0, 0.0, 0.0],
        p_mission_est=[1.0, 0.0, 0.0], q_b_ll_est=[0.0, 0.0, 0.0, 1.0], vo=vo,  # type: ignore[arg-type]
        features=features,  # type: ignore[arg-type]
    )  # fmt: skip


@pytest.fixture(scope="module")
def client(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    url = data_dir_url(Path(tmp_path_factory.mktemp("images")))
    config = ServerConfig(database_url=url, operator_token=TOKEN, public_read=False)
    with TestClient(create_app(config)) as c:
        yield c


@pytest.fixture(scope="module")
def stored(client: TestClient) -> dict[str, Any]:
    """Three images written through the storage sink's writer, one of them twice."""
    server = client.app.state.server  # type: ignore[attr-defined]
    records = [_record(10.0, seed=1), _record(20.0, "navcam_stereo", seed=2), _record(30.0, seed=3)]
    server.writer.images("opportunity", records, None)
    server.writer.images("opportunity", records[:1], 99.0)  # delivered again: stored once
    listed, total = list_images(server.store, "opportunity")
    assert total == 3
    return {"records": records, "ids": [i["id"] for i in listed]}


def test_an_image_is_stored_once_and_served_as_stored(
    client: TestClient, stored: dict[str, Any]
) -> None:
    server = client.app.state.server  # type: ignore[attr-defined]
    first = stored["ids"][0]
    url = f"/api/rovers/opportunity/images/{first}"
    one, two = (client.get(f"{url}/left.png", headers=AUTH) for _ in range(2))
    assert one.status_code == two.status_code == 200
    assert one.headers["content-type"] == "image/png"
    assert "immutable" in one.headers["cache-control"]
    assert one.content == two.content == image_png(server.store, "opportunity", first, "left")
    assert one.content[:8] == b"\x89PNG\r\n\x1a\n"
    record = stored["records"][0]
    assert np.array_equal(decode_png(one.content), record["left"])  # lossless: as sent
    right = client.get(f"{url}/right.png", headers=AUTH).content
    assert np.array_equal(decode_png(right), record["right"])
    detail = client.get(url, headers=AUTH).json()
    assert detail["received_t_s"] is None  # the first delivery's, not the repeat's
    assert detail["features"] == record["features"] and detail["vo"] == record["vo"]
    assert detail["p_mission_est"] == [1.0, 0.0, 0.0] and detail["width_px"] == 64
    pairs = stereo_pairs(server.store, "opportunity", t_from=15.0)
    assert [p.t_s for p in pairs] == [20.0, 30.0]
    assert np.array_equal(pairs[1].right, stored["records"][2]["right"])
    assert pairs[0].meta["mast_el_deg"] == pytest.approx(np.degrees(-0.6))


def test_the_list_filters_by_time_and_kind_and_pages(
    client: TestClient, stored: dict[str, Any]
) -> None:
    def get(**params: Any) -> dict[str, Any]:
        answer = client.get("/api/rovers/opportunity/images", params=params, headers=AUTH)
        assert answer.status_code == 200, answer.text
        body: dict[str, Any] = answer.json()
        return body

    assert [i["t_s"] for i in get()["images"]] == [10.0, 20.0, 30.0]
    assert [i["t_s"] for i in get(kind="vo_pair")["images"]] == [10.0, 30.0]
    assert [i["t_s"] for i in get(**{"from": 15.0, "to": 30.0})["images"]] == [20.0, 30.0]
    page = get(limit=1, offset=1)
    assert [i["t_s"] for i in page["images"]] == [20.0] and page["total"] == 3
    assert "features" not in page["images"][0] and "left" not in page["images"][0]
    assert get(kind="navcam_stereo")["images"][0]["vo"] is None
    assert client.get("/api/rovers/spirit/images", headers=AUTH).json()["total"] == 0


@pytest.mark.parametrize(
    ("path", "status"),
    [
        ("/api/rovers/opportunity/images/0", 422),
        ("/api/rovers/opportunity/images/-3", 422),
        ("/api/rovers/opportunity/images/abc", 422),
        ("/api/rovers/opportunity/images/99999999999", 422),
        ("/api/rovers/opportunity/images/4242", 404),
        ("/api/rovers/opportunity/images/4242/left.png", 404),
        ("/api/rovers/opportunity/images/1/middle.png", 404),
        ("/api/rovers/curiosity/images", 404),
        ("/api/rovers/opportunity/images?kind=selfie", 422),
        ("/api/rovers/opportunity/images?limit=0", 422),
        ("/api/rovers/opportunity/images?limit=100000", 422),
        ("/api/rovers/opportunity/images?offset=-1", 422),
        ("/api/rovers/opportunity/images?from=nan", 422),
        ("/api/rovers/opportunity/images?from=5&to=1", 422),
    ],
)
def test_bad_ids_and_filters_are_refused(
    client: TestClient, stored: dict[str, Any], path: str, status: int
) -> None:
    assert client.get(path, headers=AUTH).status_code == status


def test_another_rovers_image_is_not_found_by_its_id(
    client: TestClient, stored: dict[str, Any]
) -> None:
    first = stored["ids"][0]
    assert client.get(f"/api/rovers/spirit/images/{first}", headers=AUTH).status_code == 404
    assert client.get(f"/api/rovers/spirit/images/{first}/left.png",
                      headers=AUTH).status_code == 404  # fmt: skip


def test_reading_images_needs_a_readers_token(client: TestClient, stored: dict[str, Any]) -> None:
    url = f"/api/rovers/opportunity/images/{stored['ids'][0]}"
    for path in ("/api/rovers/opportunity/images", url, f"{url}/left.png"):
        assert client.get(path).status_code == 401  # reading is private here
        bad = {"Authorization": "Bearer not-a-token"}
        assert client.get(path, headers=bad).status_code == 403
    accounts = client.app.state.server.accounts  # type: ignore[attr-defined]
    viewer = accounts.add_user("image_reader", "viewer").token
    answer = client.get(f"{url}/left.png", headers={"Authorization": f"Bearer {viewer}"})
    assert answer.status_code == 200


def test_a_navcam_stereo_pair_comes_down_with_its_frames(client: TestClient) -> None:
    posted = client.post(
        "/api/rovers/spirit/sequences",
        content="SEQUENCE look\nNAVCAM_STEREO az_deg=-40 el_deg=-25\n",
        headers=AUTH,
    )
    assert posted.status_code == 201, posted.text
    client.post("/api/rovers/spirit/clock", json={"speed": "max"}, headers=AUTH)
    deadline = time.monotonic() + 120.0
    while True:
        found = client.get("/api/rovers/spirit/images", headers=AUTH).json()
        if found["total"]:
            break
        assert time.monotonic() < deadline, "the pair never reached storage"
        time.sleep(0.1)
    (image,) = found["images"]
    assert image["kind"] == "navcam_stereo" and image["width_px"] == 256
    assert (image["mast_az_deg"], image["mast_el_deg"]) == pytest.approx((-40.0, -25.0))
    assert image["received_t_s"] is None  # the link is instant here
    # the frames around it are stored too, and the pair's pose is the one they report
    span = {"from": image["t_s"] - 1.0, "to": image["t_s"] + 30.0}
    frames = client.get("/api/rovers/spirit/telemetry", headers=AUTH, params=span).json()
    assert frames and frames[-1]["t_s"] >= image["t_s"]
    assert image["p_mission_est"] == pytest.approx(frames[-1]["p_mission_est"], abs=1e-9)
    png = client.get(f"/api/rovers/spirit/images/{image['id']}/left.png", headers=AUTH)
    assert decode_png(png.content).shape == (256, 256)
