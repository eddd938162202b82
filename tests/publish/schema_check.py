"""Validate payloads against the exported JSON Schemas.

Uses the `jsonschema` package when it is installed. Otherwise it falls back on
this small validator, which covers exactly the keywords pydantic emits for the
message models and refuses any other keyword, so it cannot silently pass a
schema it does not understand.
"""

from __future__ import annotations

from typing import Any

_ANNOTATIONS = {"title", "description", "default", "$schema", "$id", "x-schema-version", "$defs"}
_TYPES = {
    "object": dict,
    "array": list,
    "string": str,
    "boolean": bool,
    "null": type(None),
}


class SchemaError(AssertionError):
    """A payload that does not match its schema."""


def validate(instance: Any, schema: dict[str, Any]) -> None:
    try:
        import jsonschema
    except ImportError:
        _check(instance, schema, schema, "$")
    else:
        try:
            jsonschema.Draft202012Validator(schema).validate(instance)
        except jsonschema.ValidationError as err:
            raise SchemaError(str(err)) from err


def _is_type(value: Any, kind: str) -> bool:
    if kind == "integer":
        return isinstance(value, int) and not isinstance(value, bool)
    if kind == "number":
        return isinstance(value, int | float) and not isinstance(value, bool)
    return isinstance(value, _TYPES[kind])


def _check(value: Any, schema: dict[str, Any], root: dict[str, Any], where: str) -> None:
    unknown = (
        set(schema)
        - _ANNOTATIONS
        - {
            "type",
            "properties",
            "required",
            "additionalProperties",
            "items",
            "prefixItems",
            "minItems",
            "maxItems",
            "anyOf",
            "enum",
            "const",
            "minimum",
            "maximum",
            "exclusiveMinimum",
            "$ref",
        }
    )
    if unknown:
        raise NotImplementedError(f"{where}: schema keywords {sorted(unknown)} are not supported here")
    if "$ref" in schema:
        name = schema["$ref"].removeprefix("#/$defs/")
        _check(value, root["$defs"][name], root, where)
    if "anyOf" in schema:
        errors = []
        for option in schema["anyOf"]:
            try:
                _check(value, option, root, where)
                break
            except SchemaError as err:
                errors.append(str(err))
        else:
            raise SchemaError(f"{where}: matches none of anyOf ({'; '.join(errors)})")
    if "type" in schema and not _is_type(value, schema["type"]):
        raise SchemaError(f"{where}: {value!r} is not of type {schema['type']}")
    if "const" in schema and value != schema["const"]:
        raise SchemaError(f"{where}: {value!r} is not {schema['const']!r}")
    if "enum" in schema and value not in schema["enum"]:
        raise SchemaError(f"{where}: {value!r} is not one of {schema['enum']}")
    if "minimum" in schema and value < schema["minimum"]:
        raise SchemaError(f"{where}: {value!r} is below {schema['minimum']}")
    if "maximum" in schema and value > schema["maximum"]:
        raise SchemaError(f"{where}: {value!r} is above {schema['maximum']}")
    if "exclusiveMinimum" in schema and value <= schema["exclusiveMinimum"]:
        raise SchemaError(f"{where}: {value!r} is not above {schema['exclusiveMinimum']}")
    if isinstance(value, dict):
        for key in schema.get("required", []):
            if key not in value:
                raise SchemaError(f"{where}: required field '{key}' is missing")
        properties = schema.get("properties", {})
        for key, item in value.items():
            if key in properties:
                _check(item, properties[key], root, f"{where}.{key}")
            elif isinstance(schema.get("additionalProperties"), dict):
                _check(item, schema["additionalProperties"], root, f"{where}.{key}")
            elif schema.get("additionalProperties") is False:
                raise SchemaError(f"{where}: unexpected field '{key}'")
    if isinstance(value, list):
        if "minItems" in schema and len(value) < schema["minItems"]:
            raise SchemaError(f"{where}: fewer than {schema['minItems']} items")
        if "maxItems" in schema and len(value) > schema["maxItems"]:
            raise SchemaError(f"{where}: more than {schema['maxItems']} items")
        prefix = schema.get("prefixItems", [])
        for index, item in enumerate(value):
            if index < len(prefix):
                _check(item, prefix[index], root, f"{where}[{index}]")
            elif "items" in schema and isinstance(schema["items"], dict):
                _check(item, schema["items"], root, f"{where}[{index}]")
