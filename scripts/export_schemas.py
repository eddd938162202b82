#!/usr/bin/env python3
"""Write the wire protocol's JSON Schemas (docs/schema/*.json) and the field tables of docs/protocol.md.

Run after changing trackerd/publish/messages/; tests/publish/test_schema.py fails until you do.
Usage: .venv/bin/python scripts/export_schemas.py
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from trackerd.publish.schema import render_markdown, schema_files

REPO = Path(__file__).resolve().parent.parent


def main() -> int:
    argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter).parse_args()
    schema_dir = REPO / "docs" / "schema"
    schema_dir.mkdir(parents=True, exist_ok=True)
    for name, text in schema_files().items():
        (schema_dir / name).write_text(text)
        print(f"wrote docs/schema/{name}")
    protocol = REPO / "docs" / "protocol.md"
    protocol.write_text(render_markdown(protocol.read_text()))
    print("updated the field tables in docs/protocol.md")
    return 0


if __name__ == "__main__":
    sys.exit(main())
