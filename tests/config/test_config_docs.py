"""docs/configuration.md stays true: tables match the models, the calibration example loads."""

from __future__ import annotations

import importlib.util
import re
import sys
from pathlib import Path
from types import ModuleType

import pytest

from trackerd.config.loader import load_rig

REPO_ROOT = Path(__file__).resolve().parents[2]
DOC = REPO_ROOT / "docs" / "configuration.md"


def load_generator() -> ModuleType:
    spec = importlib.util.spec_from_file_location("gen_config_docs", REPO_ROOT / "scripts" / "gen_config_docs.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules.setdefault(spec.name, module)  # its dataclasses look their module up there
    spec.loader.exec_module(sys.modules[spec.name])
    return sys.modules[spec.name]


def test_reference_tables_match_the_models() -> None:
    generator = load_generator()
    document = DOC.read_text(encoding="utf-8")
    assert generator.splice(document, generator.render()) == document, (
        "docs/configuration.md is out of date: run .venv/bin/python scripts/gen_config_docs.py"
    )


def test_every_field_has_a_row() -> None:
    from trackerd.config.models import CalibrationFile, RigConfig

    generator = load_generator()
    document = DOC.read_text(encoding="utf-8")
    for section in [
        *generator._sections(RigConfig, "rig"),
        *generator._sections(CalibrationFile, "cal"),
    ]:
        for name in section.model.model_fields:
            assert f"| `{name}` |" in document, f"{section.model.__name__}.{name}"


def test_splice_needs_the_markers() -> None:
    generator = load_generator()
    with pytest.raises(ValueError, match="markers"):
        generator.splice("# no markers here\n", generator.render())


def test_calibration_example_loads_with_the_datawall_rig(tmp_path: Path) -> None:
    document = DOC.read_text(encoding="utf-8")
    intro = document.index("A calibration file has one table per calibrated camera")
    example = re.search(r"```toml\n(.*?)```", document[intro:], re.DOTALL)
    assert example is not None
    (tmp_path / "datawall-calibration.toml").write_text(example.group(1), encoding="utf-8")
    rig = (REPO_ROOT / "config" / "datawall.toml").read_text(encoding="utf-8")
    rig = rig.replace('# calibration = "datawall-calibration.toml"', 'calibration = "datawall-calibration.toml"')
    (tmp_path / "datawall.toml").write_text(rig, encoding="utf-8")
    loaded = load_rig(tmp_path / "datawall.toml")
    assert loaded.sources == {
        "left": "from datawall-calibration.toml",
        "right": "intrinsics from datawall-calibration.toml, extrinsics inline in datawall.toml",
        "wall": "from datawall-calibration.toml",
    }
