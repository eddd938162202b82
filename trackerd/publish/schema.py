"""JSON Schemas and field tables of the wire protocol, generated from the message models.

scripts/export_schemas.py writes them into docs/schema/ and docs/protocol.md;
tests/publish/test_schema.py checks the committed files match the code.
"""

from __future__ import annotations

import json
from typing import Any

from pydantic import BaseModel

from trackerd.publish.messages import SCHEMA_VERSION, TOPICS

SCHEMA_ID = "https://trackerd.invalid/schema/{topic}.json"


def json_schema(model: type[BaseModel]) -> dict[str, Any]:
    """The model's JSON Schema as subscribers should use it: unknown fields allowed (a newer MINOR adds them)."""
    schema = model.model_json_schema(mode="serialization")
    _open(schema)
    topic = model.model_fields["topic"].default
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "$id": SCHEMA_ID.format(topic=topic),
        "x-schema-version": SCHEMA_VERSION,
        **schema,
    }


def _open(node: Any) -> None:
    """Drop ``additionalProperties: false`` everywhere: the producer is strict, subscribers must not be."""
    if isinstance(node, dict):
        if node.get("additionalProperties") is False:
            del node["additionalProperties"]
        for value in node.values():
            _open(value)
    elif isinstance(node, list):
        for value in node:
            _open(value)


def schema_files() -> dict[str, str]:
    """File name -> text of every topic's schema, as committed in docs/schema/."""
    return {f"{topic}.json": json.dumps(json_schema(model), indent=2) + "\n" for topic, model in TOPICS.items()}


def _type_name(prop: dict[str, Any]) -> str:
    if "$ref" in prop:
        return str(prop["$ref"]).rsplit("/", 1)[-1]
    if "anyOf" in prop:
        return " or ".join(_type_name(p) for p in prop["anyOf"])
    if "const" in prop:
        return f'"{prop["const"]}"'
    if "enum" in prop:
        return " / ".join(f'"{v}"' for v in prop["enum"])
    kind = prop.get("type", "any")
    if kind == "array":
        if "prefixItems" in prop:
            return f"[{', '.join(_type_name(p) for p in prop['prefixItems'])}]"
        return f"array of {_type_name(prop.get('items', {}))}"
    if kind == "object" and "additionalProperties" in prop:
        return f"object of {_type_name(prop['additionalProperties'])}"
    return {"number": "number", "integer": "integer", "string": "string", "boolean": "boolean", "null": "null"}.get(
        kind, str(kind)
    )


def field_table(model: type[BaseModel]) -> str:
    """A markdown table of a model's own fields (the envelope's fields are listed once, separately)."""
    schema = model.model_json_schema(mode="serialization")
    required = set(schema.get("required", []))
    rows = ["| field | type | description |", "| --- | --- | --- |"]
    for name, prop in schema["properties"].items():
        description = " ".join((model.model_fields[name].description or "").split()).replace("|", "\\|")
        optional = "" if name in required else " (optional)"
        rows.append(f"| `{name}` | {_type_name(prop)}{optional} | {description} |")
    return "\n".join(rows)


def generated_sections() -> dict[str, str]:
    """Marker name -> generated markdown, for the ``<!-- generated:NAME -->`` blocks of docs/protocol.md."""
    from trackerd.publish.messages import CameraStatusPart, LatencyPart, Message, PairingPart

    envelope = set(Message.model_fields)
    sections = {"envelope": field_table(Message)}
    for topic, model in TOPICS.items():
        table = field_table(model).splitlines()
        own = table[:2] + [row for row in table[2:] if row.split("`")[1] not in envelope]
        sections[topic] = "\n".join(own)
    for part in (CameraStatusPart, PairingPart, LatencyPart):
        sections[part.__name__] = field_table(part)
    return sections


def render_markdown(text: str) -> str:
    """``text`` with every generated block replaced by the current tables."""
    for name, body in generated_sections().items():
        begin, end = f"<!-- generated:{name} -->", f"<!-- end:{name} -->"
        start = text.find(begin)
        stop = text.find(end)
        if start < 0 or stop < start:
            raise ValueError(f"docs/protocol.md has no '{begin}' ... '{end}' block")
        text = text[: start + len(begin)] + "\n" + body + "\n" + text[stop:]
    return text
