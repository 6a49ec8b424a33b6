"""The dashboard's types of the API's answers, written from the API's own OpenAPI schema (issue 34 part 6).

``python -m saddlescope.api.frontend_types`` (``make api-types``) writes ``frontend/js/api-types.d.ts``: one
TypeScript type per schema of ``app.openapi()`` (RideOut, ResultOut, ...; request bodies too), each said
with the calls that answer it. The dashboard's modules name them in JSDoc
(``/** @type {import("./api-types").RideOut} */``) and ``tsc --checkJs`` checks them (``make lint``), so a
page that reads a field the API does not send fails the check. ``tests/api/test_api_frontend_types.py``
fails when the committed file differs from what this writes now (a field added to a schema and the file
not written again).

Nothing here is typed by hand: what the schema leaves open (``dict[str, Any]``) is ``unknown`` to the pages.
"""

from __future__ import annotations

import re
import secrets
import sys
import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from pydantic import SecretStr

__all__ = ["TYPES_FILE", "openapi_schema", "typescript_of", "write_types"]

TYPES_FILE = Path(__file__).resolve().parents[3] / "frontend" / "js" / "api-types.d.ts"
REF_PREFIX = "#/components/schemas/"
IDENTIFIER = re.compile(r"^[A-Za-z_$][A-Za-z0-9_$]*$")
SCALARS = {"integer": "number", "number": "number", "string": "string", "boolean": "boolean", "null": "null"}
HEADER = """\
// Written by `make api-types` (python -m saddlescope.api.frontend_types) from the API's OpenAPI schema
// (app.openapi()): do not edit. One type per schema; the JSDoc of the dashboard's modules names them,
// e.g. /** @type {import("./api-types").RideOut} */, and `make lint` checks them with tsc --checkJs.
// tests/api/test_api_frontend_types.py fails when this file is not what the schema writes now.
"""

Schema = Mapping[str, Any]


def openapi_schema() -> dict[str, Any]:
    """``app.openapi()`` of an application built on a throw-away SQLite file (nothing is connected to)."""
    from saddlescope.api.app import create_app
    from saddlescope.settings import Settings

    with tempfile.TemporaryDirectory() as folder:
        settings = Settings(database_url=f"sqlite:///{folder}/unused.db", storage_dir=Path(folder) / "storage",
                            storage_url=None, secret_key=SecretStr(secrets.token_urlsafe(32)))
        app = create_app(settings)
        try:
            return app.openapi()
        finally:
            app.state.hash_pool.close()
            app.state.engine.dispose()


def type_name(schema_name: str) -> str:
    """A TypeScript name of a schema: its own where it is one ("RideOut", "Page_RideOut_").

    Pydantic's module-qualified names of two models of one name
    ("saddlescope__api__similarity_schemas__PairOut") become the module's words and the name
    ("SimilarityPairOut").
    """
    if "__" in schema_name:
        *modules, name = schema_name.split("__")
        words = modules[-1].removesuffix("_schemas").split("_")
        schema_name = "".join(w.capitalize() for w in words) + name
    if not IDENTIFIER.match(schema_name):
        raise ValueError(f"schema name {schema_name!r} is no TypeScript name")
    return schema_name


def _literal(value: object) -> str:
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int | float):
        return repr(value)
    raise ValueError(f"no TypeScript literal for {value!r}")


def _union(parts: Sequence[str]) -> str:
    unique = list(dict.fromkeys(parts))
    return unique[0] if len(unique) == 1 else " | ".join(unique)


def _grouped(text: str) -> str:
    """`text` as one operand of `[]` or `|` (a union in parentheses)."""
    return f"({text})" if " | " in text or " & " in text else text


def ts_type(schema: Schema) -> str:
    """The TypeScript type of a JSON schema (OpenAPI 3.1, as pydantic writes it)."""
    if "$ref" in schema:
        return type_name(str(schema["$ref"]).removeprefix(REF_PREFIX))
    if "const" in schema:
        return _literal(schema["const"])
    if "enum" in schema:
        return _union([_literal(v) for v in schema["enum"]])
    if "anyOf" in schema or "oneOf" in schema:
        return _union([ts_type(s) for s in schema.get("anyOf", schema.get("oneOf"))])
    if "allOf" in schema:
        return " & ".join(_grouped(ts_type(s)) for s in schema["allOf"])
    kind = schema.get("type")
    if isinstance(kind, list):
        return _union([ts_type({**schema, "type": k}) for k in kind])
    if kind in SCALARS:
        return SCALARS[kind]
    if kind == "array":
        if "prefixItems" in schema:
            return "[" + ", ".join(ts_type(s) for s in schema["prefixItems"]) + "]"
        return _grouped(ts_type(schema["items"])) + "[]" if "items" in schema else "unknown[]"
    if kind == "object" or "properties" in schema:
        return _object_type(schema)
    return "unknown"


def _object_type(schema: Schema) -> str:
    if "properties" in schema:
        return "{ " + " ".join(_property_lines(schema, with_comments=False)) + " }"
    values = schema.get("additionalProperties", True)
    value = "unknown" if values is True or values == {} else ts_type(values)
    keys = ts_type(schema.get("propertyNames", {}))
    if keys not in ("unknown", "string"):  # a dict keyed by an enum: not every key need be there
        return f"Partial<Record<{keys}, {value}>>"
    return f"Record<string, {value}>"


def _comment(text: str, indent: str) -> list[str]:
    lines = text.replace("*/", "*\\/").strip().splitlines()
    if len(lines) == 1:
        return [f"{indent}/** {lines[0]} */"]
    return [f"{indent}/**", *(f"{indent} * {line}".rstrip() for line in lines), f"{indent} */"]


def _property_lines(schema: Schema, *, with_comments: bool, indent: str = "") -> list[str]:
    required = set(schema.get("required", ()))
    lines: list[str] = []
    for name, prop in schema["properties"].items():
        if with_comments and prop.get("description"):
            lines += _comment(prop["description"], indent)
        key = name if IDENTIFIER.match(name) else _literal(name)
        lines.append(f"{indent}{key}{'' if name in required else '?'}: {ts_type(prop)};")
    return lines


def _answers(spec: Schema) -> dict[str, list[str]]:
    """Each schema's calls: "GET /api/rides/{ride_id}" for the schemas a call answers with (2xx) or takes."""
    calls: dict[str, list[str]] = {}
    for path, operations in spec.get("paths", {}).items():
        for method, operation in operations.items():
            bodies = [("answers", response) for status, response in operation.get("responses", {}).items()
                      if str(status).startswith("2")]
            bodies.append(("takes", operation.get("requestBody", {})))
            for role, body in bodies:
                for content in body.get("content", {}).values():
                    for name in _refs(content.get("schema", {})):
                        calls.setdefault(name, []).append(f"{method.upper()} {path} {role} it")
    return calls


def _refs(schema: object) -> list[str]:
    if isinstance(schema, Mapping):
        own = [str(schema["$ref"]).removeprefix(REF_PREFIX)] if "$ref" in schema else []
        return own + [name for value in schema.values() for name in _refs(value)]
    if isinstance(schema, list):
        return [name for value in schema for name in _refs(value)]
    return []


def _declaration(schema_name: str, schema: Schema, calls: Sequence[str]) -> list[str]:
    name = type_name(schema_name)
    about = [schema.get("description", "").strip(), *calls]
    if name != schema_name:
        about.append(f"(the schema {schema_name})")
    lines = _comment("\n".join(line for line in about if line), "") if any(about) else []
    if schema.get("type") == "object" and "properties" in schema:
        return [*lines, f"export interface {name} {{", *_property_lines(schema, with_comments=True, indent="  "), "}"]
    return [*lines, f"export type {name} = {ts_type(schema)};"]


def typescript_of(spec: Schema) -> str:
    """The text of api-types.d.ts for an OpenAPI document: its schemas in name order."""
    schemas = spec.get("components", {}).get("schemas", {})
    names = {type_name(n): n for n in schemas}
    if len(names) != len(schemas):
        raise ValueError("two schemas have one TypeScript name")
    calls = _answers(spec)
    blocks = [_declaration(names[name], schemas[names[name]], sorted(set(calls.get(names[name], []))))
              for name in sorted(names)]
    return HEADER + "\n" + "\n\n".join("\n".join(block) for block in blocks) + "\n"


def write_types(path: Path = TYPES_FILE) -> Path:
    """Write the types of the API's schemas now to `path` (default frontend/js/api-types.d.ts)."""
    path.write_text(typescript_of(openapi_schema()), encoding="utf-8")
    return path


if __name__ == "__main__":  # python -m saddlescope.api.frontend_types [FILE]
    print(f"wrote {write_types(Path(sys.argv[1]) if len(sys.argv) > 1 else TYPES_FILE)}")
