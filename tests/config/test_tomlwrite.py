"""The TOML emitter writes what tomllib reads back unchanged, and refuses what it cannot write."""

from __future__ import annotations

import math
import tomllib

import numpy as np
import pytest
from hypothesis import example, given
from hypothesis import strategies as st

from trackerd.config.tomlwrite import dumps

finite = st.floats(allow_nan=False, allow_infinity=False)
keys = st.text(min_size=1, max_size=12)
scalars = st.one_of(finite, st.integers(-(2**63), 2**63 - 1), st.booleans(), st.text(max_size=20))


@given(st.dictionaries(keys, st.one_of(scalars, st.lists(finite, max_size=6)), max_size=6))
@example({"0\n": 0.0})  # a regex "$" lets a key ending in a newline pass as bare
def test_flat_tables_round_trip(data: dict) -> None:
    assert tomllib.loads(dumps(data)) == data


@given(st.lists(finite, min_size=1, max_size=20))
def test_floats_round_trip_bit_for_bit(values: list[float]) -> None:
    back = tomllib.loads(dumps({"v": values}))["v"]
    assert [math.copysign(1.0, v) for v in back] == [math.copysign(1.0, v) for v in values]
    assert back == values


def test_nested_tables_and_arrays_round_trip() -> None:
    data = {
        "version": 1,
        "cameras": {
            "left": {
                "intrinsics": {"model": "opencv", "fx_px": 1660.0000000001, "distortion": [-0.08, 5e-05]},
                "info": {"date": "2026-11-22", "views": 14},
            },
            "cam-2": {"extrinsics": {"kind": "opencv", "rvec": [0.0, 2.4, 0.7], "tvec_m": [1e-17, -3.5, 6.0]}},
        },
        "wall": {"corners_m": [[0.0, 0.0, 0.0], [3.6576, 0.0, 0.0]]},
    }
    assert tomllib.loads(dumps(data)) == data


def test_numpy_values_are_written_as_plain_numbers() -> None:
    text = dumps({"a": np.float64(0.1), "b": np.int64(3), "c": np.array([1.5, 2.0]), "d": np.bool_(True)})
    assert "np." not in text
    assert tomllib.loads(text) == {"a": 0.1, "b": 3, "c": [1.5, 2.0], "d": True}


def test_strings_and_keys_are_escaped() -> None:
    data = {"odd key.with dots": {'quote " and \\ and \n and \t and \x01': "ok"}}
    assert tomllib.loads(dumps(data)) == data


def test_header_becomes_comments() -> None:
    text = dumps({"a": 1}, header="written by a test\nsecond line")
    assert text.startswith("# written by a test\n# second line\n")
    assert tomllib.loads(text) == {"a": 1}


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_nan_and_infinity_are_refused(bad: float) -> None:
    with pytest.raises(ValueError, match=r"cameras\.left\.fx_px"):
        dumps({"cameras": {"left": {"fx_px": bad}}})


def test_unknown_types_are_refused() -> None:
    with pytest.raises(TypeError, match="object"):
        dumps({"x": object()})


def test_a_whole_rig_round_trips_through_arrays_of_tables() -> None:
    import tomllib
    from pathlib import Path

    from trackerd.config.loader import load_rig
    from trackerd.config.models import RigConfig

    rig = load_rig(Path(__file__).resolve().parents[2] / "config" / "simulated.toml").config
    text = dumps(rig.model_dump(mode="json", exclude_none=True, exclude_defaults=True))
    assert text.count("[[cameras]]") == 2
    assert RigConfig.model_validate(tomllib.loads(text)) == rig
