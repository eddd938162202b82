"""Validating a file's data, and a pydantic error as one line an operator can act on.

:func:`strictly` validates without type coercion; :func:`describe_validation_error` turns the
first problem into ``key.path: what is wrong (allowed ...)``, in the words of the TOML file (keys
as TOML spells them, TOML's type names, the key a misspelling was meant to be).
"""

from __future__ import annotations

import datetime
import difflib
import json
import re
from typing import Any, TypeVar, get_args, get_origin

from pydantic import BaseModel, ValidationError

ModelT = TypeVar("ModelT", bound=BaseModel)

_BARE_KEY = re.compile(r"[A-Za-z0-9_-]+")


def key_text(key: object) -> str:
    """A key as TOML spells it: bare when it can be, quoted with escapes otherwise. A file may hold any
    key (a line break, a control character, nothing at all), and an error naming it must stay one line."""
    text = str(key)
    return text if _BARE_KEY.fullmatch(text) else json.dumps(text)


def quoted(text: object) -> str:
    """``'text'`` as a message quotes a key or a tag the file gave; JSON-escaped in double quotes when it
    holds anything that is not printable (a line break, a control character, U+2028) or a quote."""
    text = str(text)
    return f"'{text}'" if text.isprintable() and "'" not in text else json.dumps(text)


def format_location(loc: tuple[int | str, ...]) -> str:
    """``('cameras', 1, 'intrinsics', 'opencv', 'fx_px')`` -> ``cameras[1].intrinsics.fx_px``.

    The discriminator tag pydantic inserts for tagged unions ('opencv' above) is
    dropped, because it is not a key the user wrote.
    """
    text = ""
    for part in loc:
        if isinstance(part, int):
            text += f"[{part}]"
        elif part in ("fov", "opencv", "pose") and text.endswith(("intrinsics", "extrinsics")):
            continue
        else:
            text += f".{key_text(part)}" if text else key_text(part)
    return text or "(top level)"


def _model_at(model: type[BaseModel], loc: tuple[int | str, ...]) -> type[BaseModel] | None:
    """Walk a model class along an error location to find the model that owns the last key."""
    current: Any = model
    for part in loc[:-1]:
        if isinstance(part, int) or current is None:
            continue
        if isinstance(current, type) and issubclass(current, BaseModel):
            field = current.model_fields.get(str(part))
            if field is None:
                # a discriminator tag, or a dict key such as a camera id
                current = _union_member(current, str(part)) or current
                continue
            current = _unwrap(field.annotation)
        else:
            current = _union_member(current, str(part))
    if isinstance(current, type) and issubclass(current, BaseModel):
        return current
    return None


def _unwrap(annotation: Any) -> Any:
    """The BaseModel class inside Optional[...], tuple[...], dict[str, ...] or Annotated unions."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    args = [a for a in get_args(annotation) if a is not type(None)]
    models = [a for a in args if isinstance(a, type) and issubclass(a, BaseModel)]
    if len(models) == 1:
        return models[0]
    if models:
        return tuple(models)
    for arg in args:
        inner = _unwrap(arg)
        if inner is not None:
            return inner
    if get_origin(annotation) is None:
        return None
    return None


def _union_member(current: Any, tag: str) -> Any:
    """Pick the member of a tagged union whose tag value is ``tag``."""
    candidates = current if isinstance(current, tuple) else ()
    for member in candidates:
        for name in ("model", "kind"):
            field = member.model_fields.get(name)
            if field is not None and tag in get_args(field.annotation):
                return member
    return None


def _union_tags(root: type[BaseModel], loc: tuple[int | str, ...], key: str) -> list[str]:
    """The values of the tag ``key`` that select the members of the tagged union at ``loc``."""
    owner = _model_at(root, loc)
    field = owner.model_fields.get(str(loc[-1])) if owner else None
    members = _unwrap(field.annotation) if field is not None else None
    members = members if isinstance(members, tuple) else ()
    tags: list[str] = []
    for member in members:
        if key in member.model_fields:
            tags += get_args(member.model_fields[key].annotation)
    return tags


def _meant_key(root: type[BaseModel], loc: tuple[int | str, ...]) -> tuple[int | str, ...] | None:
    """Where the key a misspelt one at ``loc`` was meant to be, or None when nothing is close."""
    owner = _model_at(root, loc)
    close = difflib.get_close_matches(str(loc[-1]), list(owner.model_fields) if owner else [], n=1)
    return (*loc[:-1], close[0]) if close else None


def describe_validation_error(err: ValidationError, root: type[BaseModel]) -> str:
    """The first error as ``key.path: what is wrong (allowed ...)``, plus a count of the rest."""
    errors = err.errors(include_url=False)
    # pydantic also reports a tuple whose items failed as too short ("... after validation,
    # not 0"); that follows from the item errors and is not a problem of its own.
    locs = [tuple(e["loc"]) for e in errors]

    def echoes_items(e: Any) -> bool:
        loc = tuple(e["loc"])
        inner = [o for o in locs if len(o) > len(loc) and o[: len(loc)] == loc]
        return e["type"] == "too_short" and bool(inner)

    errors = [e for e in errors if not echoes_items(e)] or errors
    # A misspelt key also shows up as the real key "missing": one problem, not two (for each
    # misspelling, not only the one reported). Report the misspelling first.
    meant = {_meant_key(root, tuple(e["loc"])) for e in errors if e["type"] == "extra_forbidden"}
    errors = [e for e in errors if not (e["type"] == "missing" and tuple(e["loc"]) in meant)]
    errors.sort(key=lambda e: e["type"] != "extra_forbidden")
    first = errors[0]
    loc = tuple(first["loc"])
    where = format_location(loc)
    kind = first["type"]
    if kind == "extra_forbidden":
        owner = _model_at(root, loc)
        names = list(owner.model_fields) if owner else []
        allowed = ", ".join(names) if names else "see docs/configuration.md"
        meant_here = _meant_key(root, loc)
        hint = f" (did you mean '{meant_here[-1]}'?)" if meant_here else ""
        message = f"unknown key {quoted(loc[-1])}{hint}; allowed keys here: {allowed}"
    elif kind == "missing" and isinstance(loc[-1], int):
        # A fixed-length array (a 3-vector, the four corners) with too few values: pydantic
        # reports each absent item; say once how many values were wanted.
        parent = loc[:-1]
        absent = [e for e in errors if e["type"] == "missing" and tuple(e["loc"][:-1]) == parent]
        errors = [e for e in errors if e not in absent[1:]]
        given = first.get("input")
        count = len(given) if isinstance(given, (list, tuple)) else loc[-1]
        where = format_location(parent)
        message = f"needs {count + len(absent)} values, got {count}"
    elif kind == "missing":
        message = "required key is missing"
    elif kind == "union_tag_invalid":
        # pydantic's message quotes the tag as given, line breaks and all.
        ctx = first.get("ctx", {})
        message = (
            f"tag {quoted(ctx.get('tag', ''))} in key {ctx.get('discriminator', '')} does not match"
            f" any of the expected tags: {ctx.get('expected_tags', '')}"
        )
    elif kind == "union_tag_not_found":
        key = str(first.get("ctx", {}).get("discriminator", "")).strip("'")
        tags = _union_tags(root, loc, key)
        allowed = f" (one of {', '.join(repr(t) for t in tags)})" if tags else ""
        message = f"required key '{key}' is missing; it selects the form{allowed}"
    elif kind in TOML_TYPE_NAMES:
        message = f"must be {TOML_TYPE_NAMES[kind]}"
        value = first.get("input")
        if not isinstance(value, (dict, list)):
            message += f" (got {_toml_literal(value)})"
    else:
        message = first["msg"]
        if message.startswith("Value error, "):
            message = message[len("Value error, ") :]
        value = first.get("input")
        if kind not in ("value_error",) and isinstance(value, (str, int, float)):
            message += f" (got {value!r})"
    more = len(errors) - 1
    suffix = f" (and {more} more problem{'s' if more > 1 else ''})" if more else ""
    return f"{where}: {message}{suffix}"


TOML_TYPE_NAMES = {
    "int_type": "an integer",
    "int_from_float": "an integer",
    "float_type": "a number",
    "bool_type": "true or false",
    "string_type": "a string",
    "dict_type": "a table",
    "model_type": "a table",
    "model_attributes_type": "a table",
    "list_type": "an array",
    "tuple_type": "an array",
}
"""pydantic's type errors (JSON-mode wording: "a valid dictionary", "an object") in TOML's terms."""


def _toml_literal(value: Any) -> str:
    """A value as the rig file spells it: ``"0.45"``, ``true``, ``7.0``."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value)
    return repr(value)


def strictly(model: type[ModelT], data: dict[str, Any]) -> ModelT:
    """Validate file data with no type coercion: ``width_px = "1920"`` or ``clutter = true`` is a
    type error, not a 1920 or a 1.

    Strict validation in pydantic's JSON mode still takes what a file can only spell one way (an
    array for a tuple, a string for a path, an integer for a float), so the data goes through
    JSON; TOML's dates and times, which no setting takes, become their ISO strings.
    """
    text = json.dumps(data, default=_json_fallback, allow_nan=True)
    return model.model_validate_json(text, strict=True)


def _json_fallback(value: Any) -> str:
    if isinstance(value, (datetime.date, datetime.time)):
        return value.isoformat()
    raise TypeError(f"cannot validate a {type(value).__name__}")
