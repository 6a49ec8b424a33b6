"""The dashboard's types come from the API's own contract (issue 34 part 6): frontend/js/api-types.d.ts is what
saddlescope.api.frontend_types writes from app.openapi() now, so a field added to, renamed in or dropped from
a schema fails here until `make api-types` writes the file again (and `make lint`'s tsc then checks the pages
against it)."""

from __future__ import annotations

import copy

import pytest

from saddlescope.api.frontend_types import TYPES_FILE, openapi_schema, ts_type, type_name, typescript_of


@pytest.fixture(scope="module")
def spec():
    return openapi_schema()


def test_the_committed_types_are_what_the_api_schema_writes(spec):
    written = typescript_of(spec)
    assert TYPES_FILE.read_text(encoding="utf-8") == written, (
        f"{TYPES_FILE.name} is out of date with the API's schemas: run `make api-types` and commit it")


def test_a_field_added_to_an_answer_changes_the_types(spec):
    """The comparison above can fail: one more field of RideOut is one more line of its interface."""
    grown = copy.deepcopy(spec)
    ride = grown["components"]["schemas"]["RideOut"]
    ride["properties"]["arena_name"] = {"type": "string", "description": "where it was ridden"}
    ride["required"].append("arena_name")
    before, after = typescript_of(spec), typescript_of(grown)
    assert before != after
    ride_type = after.split("export interface RideOut {", 1)[1].split("\n}", 1)[0]
    assert "  /** where it was ridden */\n  arena_name: string;" in ride_type


def test_every_answer_the_pages_read_has_its_type(spec):
    written = typescript_of(spec)
    for name in ("RideOut", "RideDetail", "ResultOut", "LeaderboardOut", "HorseOut", "JobOut", "Page_RideOut_",
                 "MeOut", "ComparisonOut", "UploadCreatedOut"):
        assert f"export interface {name} {{" in written, name
    ride_comment = written.split("export interface RideDetail {")[0].rsplit("/**", 1)[1]
    assert "GET /api/rides/{ride_id} answers it" in ride_comment


@pytest.mark.parametrize(("schema", "expected"), [
    ({"anyOf": [{"type": "integer"}, {"type": "null"}]}, "number | null"),
    ({"type": "string", "enum": ["walk", "canter"]}, '"walk" | "canter"'),
    ({"type": "string", "const": "bearer"}, '"bearer"'),
    ({"type": "array", "prefixItems": [{"type": "integer"}, {"type": "number"}]}, "[number, number]"),
    ({"type": "array", "items": {"anyOf": [{"type": "number"}, {"type": "null"}]}}, "(number | null)[]"),
    ({"type": "array", "items": {}}, "unknown[]"),
    ({"type": "object", "additionalProperties": True}, "Record<string, unknown>"),
    ({"type": "object", "additionalProperties": {"$ref": "#/components/schemas/Band"}}, "Record<string, Band>"),
    ({"type": "object", "additionalProperties": {"type": "number"}, "propertyNames": {"enum": ["left", "right"]}},
     'Partial<Record<"left" | "right", number>>'),
    ({"type": "object", "additionalProperties": {"type": "string"}, "propertyNames": {"maxLength": 40}},
     "Record<string, string>"),
    ({"type": "object", "properties": {"a": {"type": "integer"}, "b-c": {"type": "string"}}, "required": ["a"]},
     '{ a: number; "b-c"?: string; }'),
    ({}, "unknown"),
])
def test_json_schemas_in_typescript(schema, expected):
    assert ts_type(schema) == expected


def test_module_qualified_schema_names_read_as_their_modules_words():
    assert type_name("saddlescope__api__similarity_schemas__PairOut") == "SimilarityPairOut"
    assert type_name("Page_RideOut_") == "Page_RideOut_"
    with pytest.raises(ValueError, match="no TypeScript name"):
        type_name("Page[RideOut]")
