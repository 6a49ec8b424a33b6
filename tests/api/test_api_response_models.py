"""Every JSON route declares its answer (issue 34, #34 "every route declares its response model"): no 2xx JSON
answer in app.openapi() is a bare object (``dict``: ``{"type": "object", "additionalProperties": true}``) or
anything at all (``{}``), so the OpenAPI, the docs and the dashboard's generated types (api-types.d.ts) say every
field a page reads. File downloads (an export, a PDF: a 2xx that also names a non-JSON media type) and HEAD (no
body) are not JSON answers."""

from __future__ import annotations

from typing import Any

import pytest
from fastapi import FastAPI, Response

from saddlescope.api.frontend_types import REF_PREFIX, openapi_schema

JSON = "application/json"


@pytest.fixture(scope="module")
def spec():
    return openapi_schema()


def _open(schema: dict[str, Any], components: dict[str, Any]) -> bool:
    """Whether `schema` leaves an answer (or one of its alternatives, or the items of a list) untyped."""
    if "$ref" in schema:
        return _open(components[schema["$ref"].removeprefix(REF_PREFIX)], components)
    alternatives = schema.get("anyOf") or schema.get("oneOf") or schema.get("allOf")
    if alternatives:
        return any(_open(s, components) for s in alternatives)
    if schema.get("type") == "array":
        return _open(schema.get("items", {}), components)
    if not {k: v for k, v in schema.items() if k not in ("title", "description")}:
        return True  # {}: any JSON at all
    if schema.get("type") == "object" and "properties" not in schema:
        return schema.get("additionalProperties", True) in (True, {})  # a dict of anything
    return False


def untyped_answers(document: dict[str, Any]) -> list[str]:
    """"METHOD /path status" of each JSON answer (2xx) whose schema is a bare object or empty."""
    components = document.get("components", {}).get("schemas", {})
    found = []
    for path, operations in document["paths"].items():
        for method, operation in operations.items():
            for status, answer in operation.get("responses", {}).items():
                content = answer.get("content", {})
                if not str(status).startswith("2") or method == "head" or JSON not in content:
                    continue
                if any(media != JSON for media in content):
                    continue  # a file download (CSV, XLSX, PDF, ...): its JSON stand-in is the file too
                if _open(content[JSON].get("schema", {}), components):
                    found.append(f"{method.upper()} {path} {status}")
    return found


def test_every_json_answer_has_a_declared_model(spec):
    assert untyped_answers(spec) == [], "JSON routes answering an untyped object: declare a response_model"


def test_the_five_answers_of_issue_34_name_their_models(spec):
    paths = spec["paths"]
    named = {
        ("get", "/api/rigs/{rig_id}/calibration-report"): "CalibrationReportOut",
        ("post", "/api/uploads/{upload_id}/parts"): "PartUrlsOut",
        ("get", "/api/uploads/{upload_id}/parts"): "DirectPartsOut",
        ("post", "/api/uploads/{upload_id}/finalize"): "BundleFinalisedOut",
        ("get", "/api/uploads/{upload_id}/bundle-meta"): "BundleMetaOut",
    }
    for (method, path), model in named.items():
        assert REF_PREFIX + model in str(paths[path][method]["responses"]["200"]["content"][JSON]["schema"]), path


def test_the_check_finds_a_bare_dict_and_passes_files_and_models():
    """The check can fail: a route answering ``dict`` (or anything) is found, a file download and a model are not."""
    from pydantic import BaseModel

    class Answer(BaseModel):
        n: int

    app = FastAPI()

    @app.get("/bare")
    def bare() -> dict:
        return {}

    @app.get("/anything")
    def anything():
        return 1

    @app.get("/bare-list")
    def bare_list() -> list[dict]:
        return []

    @app.get("/typed", response_model=Answer)
    def typed() -> Answer:
        return Answer(n=1)

    @app.get("/typed-map", response_model=dict[str, Answer])
    def typed_map() -> dict[str, Answer]:
        return {}

    @app.get("/file", response_class=Response,
             responses={200: {"content": {JSON: {}, "text/csv": {}}, "description": "a CSV"}})
    def file() -> Response:
        return Response("a,b\n", media_type="text/csv")

    assert untyped_answers(app.openapi()) == ["GET /bare 200", "GET /anything 200", "GET /bare-list 200"]
