"""The committed docs match the code: docs/schema/*.json and the field tables of docs/protocol.md."""

from __future__ import annotations

from pathlib import Path

from trackerd.publish import SCHEMA_VERSION, TOPICS
from trackerd.publish.messages import CameraStatusPart, LatencyPart, PairingPart
from trackerd.publish.schema import render_markdown, schema_files

REPO = Path(__file__).resolve().parents[2]
FIX = "run `.venv/bin/python scripts/export_schemas.py` and commit the result"


def test_committed_schemas_match_the_models():
    committed = {path.name: path.read_text() for path in (REPO / "docs" / "schema").glob("*.json")}
    assert committed == schema_files(), FIX


def test_protocol_doc_tables_match_the_models():
    text = (REPO / "docs" / "protocol.md").read_text()
    assert render_markdown(text) == text, FIX
    assert f"protocol version **{SCHEMA_VERSION}**" in text


def test_every_field_is_documented():
    for model in (*TOPICS.values(), CameraStatusPart, PairingPart, LatencyPart):
        for name, field in model.model_fields.items():
            assert field.description, f"{model.__name__}.{name} has no docstring"
