"""Every route's answer has a schema in the OpenAPI document (issue 21, "Typed boundaries"):
``/docs`` shows what each route answers, so a route that returns an untyped dict fails here.

A 2xx answer's JSON schema must name its fields (an object's ``properties``, an array's
``items`` with them, a ``$ref`` to a component that has them, or a scalar type); an empty
schema, ``{"type": "object"}`` alone or an array of those says nothing and fails.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest
from fastapi.testclient import TestClient

from server.app import ServerConfig, create_app, data_dir_url

SCALARS = {"string", "integer", "number", "boolean"}


@pytest.fixture(scope="module")
def openapi(tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict[str, Any]]:
    url = data_dir_url(tmp_path_factory.mktemp("openapi"))
    config = ServerConfig(database_url=url, start_clocks=False, validation_processes=0)
    with TestClient(create_app(config)) as client:
        yield client.get("/openapi.json").json()


def says_something(schema: dict[str, Any], components: dict[str, Any], seen: int = 0) -> bool:
    """Whether ``schema`` describes its values: fields, items that do, or a scalar type."""
    if seen > 20:
        return False
    if "$ref" in schema:
        name = schema["$ref"].rsplit("/", 1)[-1]
        return says_something(components[name], components, seen + 1)
    for key in ("anyOf", "oneOf", "allOf"):
        if key in schema:
            return all(
                says_something(s, components, seen + 1)
                for s in schema[key]
                if s.get("type") != "null"
            )
    kind = schema.get("type")
    if kind in SCALARS:
        return True
    if kind == "array":
        return says_something(schema.get("items", {}), components, seen + 1)
    if kind == "object":
        return bool(schema.get("properties"))
    return False


def test_says_something_tells_a_typed_schema_from_an_untyped_one() -> None:
    components = {"A": {"type": "object", "properties": {"x": {"type": "integer"}}}}
    assert says_something({"$ref": "#/components/schemas/A"}, components)
    assert says_something({"type": "array", "items": {"type": "integer"}}, components)
    assert not says_something({}, components)
    assert not says_something({"type": "object", "additionalProperties": True}, components)
    assert not says_something({"type": "array", "items": {"type": "object"}}, components)


def test_every_route_answer_has_a_schema(openapi: dict[str, Any]) -> None:
    components = openapi.get("components", {}).get("schemas", {})
    untyped = []
    for path, operations in openapi["paths"].items():
        for method, operation in operations.items():
            answers = {c: r for c, r in operation["responses"].items() if c.startswith("2")}
            assert answers, f"{method.upper()} {path} documents no 2xx answer"
            for code, answer in answers.items():
                content = answer.get("content", {})
                json_schema = content.get("application/json", {}).get("schema")
                if json_schema is None and content:  # a file (CSV): its own media type
                    continue
                if json_schema is None or not says_something(json_schema, components):
                    untyped.append(f"{method.upper()} {path} {code}")
    assert not untyped, "answers without a schema: " + ", ".join(untyped)
