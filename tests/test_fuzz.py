"""Fuzzing what trackerd reads from outside: rig and calibration files, recordings, and what a peer
sends the publisher (issue 15, "Hostile files").

The inputs are the real ones, mutated: config/simulated.toml, config/datawall.toml, a calibration
file for the simulated rig, the bundled recording (tests/data/recording) and a live Publisher on
loopback. Every file must end as a valid result or as a TrackerdError with one line, never another
exception and never a hang; the publisher must still serve its own last status afterwards.

Reproducible and bounded: hypothesis runs derandomized (the same cases in every run, no example
database) with a fixed number of examples; the file takes well under a minute. Each test prints
how many cases it ran and how they ended (``pytest -s``). For a deliberate hunt, run with
``HYPOTHESIS_PROFILE=thorough`` (FUZZ_SCALE below multiplies the cases).
"""

from __future__ import annotations

import contextlib
import copy
import io
import json
import math
import os
import random
import shutil
import struct
import subprocess
import sys
import time
import tomllib
import zlib
from collections import Counter
from collections.abc import Callable, Iterator
from datetime import date, datetime
from datetime import time as time_of_day
from pathlib import Path
from typing import Any

import pytest
import zmq
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.publish.conftest import hit_message, status_message
from trackerd.cli.main import main as trackerd_main
from trackerd.config.loader import LoadedRig, load_calibration, load_rig
from trackerd.config.models import ZmqOutput
from trackerd.errors import TrackerdError
from trackerd.publish import Publisher, decode
from trackerd.recording.format import (
    DATA_FILE,
    FILE_HEADER,
    INDEX_ENTRY,
    INDEX_FILE,
    METADATA_FILE,
    RECORD_FIXED,
)
from trackerd.recording.reader import Recording
from trackerd.recording.replay import ReplayPairSource

REPO = Path(__file__).resolve().parent.parent
BUNDLE = REPO / "tests" / "data" / "recording" / "figure8-leave.trec"

pytestmark = pytest.mark.slow  # about 40 s in all

FUZZ_SCALE = 10 if os.environ.get("HYPOTHESIS_PROFILE") == "thorough" else 1


def _fuzz(examples: int) -> settings:
    """Derandomized: CI runs the same cases every time, and a failure names an example to replay."""
    return settings(
        max_examples=examples * FUZZ_SCALE,
        deadline=None,
        derandomize=True,
        database=None,
        suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.filter_too_much],
    )


def _one_line(err: BaseException | str) -> str:
    """The error's message (or a reported problem), checked to be one non-empty line as the CLI prints it."""
    message = str(err)
    what = type(err).__name__ if isinstance(err, BaseException) else "a problem"
    assert message.strip(), f"{what} with an empty message"
    # splitlines: what a terminal, a log or the journal may break a line at (\x1e and \u2028 too)
    assert len(message.splitlines()) == 1, f"{what} of several lines: {message!r}"
    return message


def _summary(name: str, tally: Counter[str]) -> str:
    total = tally.pop("cases")
    parts = ", ".join(f"{count} {what}" for what, count in sorted(tally.items()))
    line = f"{name}: {total} cases: {parts}"
    print(line)
    return line


# =========================================================================== mutations

HOSTILE_SNIPPETS = [
    b"\x00",
    b"\xff\xfe",
    b"\xc3",
    b"[",
    b"]",
    b"[[",
    b"{",
    b"}",
    b"=",
    b'"',
    b"'",
    b"\\",
    b"#",
    b",",
    b"\n",
    b"\r",
    b"\n[cameras]\n",
    b"\n[[cameras]]\n",
    b"\n[wall]\n",
    b"nan",
    b"-inf",
    b"1e999",
    b"9" * 5000,
    b"9" * 30,
    b"0x",
    b"1979-05-27T07:32:00Z",
    b'"""',
    b"\xe2\x80\xae",
    "\u00e9\u4e2d".encode(),
]
"""Bytes a hand, a bad editor or an attacker puts into a text file: syntax, encodings, a number too
long to convert (5000 digits: Python refuses to parse more than 4300), a date, an RTL override."""


@st.composite
def byte_mutation(draw: st.DrawFn, data: bytes) -> bytes:
    """``data`` after one random byte-level edit: a flip, a cut, an insertion, a deletion, or a line
    deleted, duplicated (a duplicate key or table) or swapped."""
    kind = draw(st.sampled_from(["flip", "truncate", "insert", "delete", "line"]), label="byte edit")
    if not data:
        return draw(st.binary(max_size=64))
    at = draw(st.integers(0, len(data) - 1), label="at")
    if kind == "flip":
        mask = draw(st.integers(1, 255))
        return data[:at] + bytes([data[at] ^ mask]) + data[at + 1 :]
    if kind == "truncate":
        return data[:at]
    if kind == "insert":
        inserted = draw(st.sampled_from(HOSTILE_SNIPPETS) | st.binary(min_size=1, max_size=16))
        return data[:at] + inserted + data[at:]
    if kind == "delete":
        length = draw(st.integers(1, 64))
        return data[:at] + data[at + length :]
    lines = data.split(b"\n")
    i = draw(st.integers(0, len(lines) - 1))
    j = draw(st.integers(0, len(lines) - 1))
    edit = draw(st.sampled_from(["delete", "duplicate", "swap"]))
    if edit == "delete":
        del lines[i]
    elif edit == "duplicate":
        lines.insert(j, lines[i])
    else:
        lines[i], lines[j] = lines[j], lines[i]
    return b"\n".join(lines)


HUGE_INTEGER = "<an integer of 5000 digits>"
"""Stands for an integer literal longer than Python converts (4300 digits) in a parsed document; the
writers below spell it out (no int of that length can be made into text in this process either)."""


def _spell_huge_integers(text: str) -> str:
    return text.replace(json.dumps(HUGE_INTEGER), "9" * 5000)


def _nested_list(depth: int) -> list:
    value: list = []
    for _ in range(depth):
        value = [value]
    return value


def hostile_values(*, toml: bool) -> st.SearchStrategy[Any]:
    """Values swapped in for a key: wrong types, huge and tiny numbers, NaN and infinities, long and
    odd strings, arrays nested around the nesting limit (32), tables; TOML's dates and times too."""
    scalars = [
        st.integers(),
        st.sampled_from([0, -1, 1, 2**31, 2**63 - 1, -(2**63), 2**64, 10**30, -(10**30)]),
        st.floats(),
        st.sampled_from([math.nan, math.inf, -math.inf, 1e308, -1e308, 5e-324, -0.0]),
        st.booleans(),
        st.text(max_size=24),
        st.sampled_from(
            [
                "",
                "x" * 100_000,
                "Mono8",
                "BayerRG8",
                "fov",
                "opencv",
                "pose",
                "red",
                "blue",
                "\u202e\x00\n\t",
                "../../../etc/passwd",
                "tcp://0.0.0.0:5560",
                "1.0",
                "2.0",
                "0.9",
                "trackerd-recording",
                "left",
                "right",
                "camera left",
            ]
        ),
    ]
    if toml:
        scalars += [st.dates(), st.times(), st.datetimes()]
    else:
        scalars += [st.none()]
    scalars.append(st.just(HUGE_INTEGER))  # a branch of its own: Python's parsers fail on it differently
    leaf = st.one_of(*scalars)
    return st.one_of(
        leaf,
        st.integers(20, 40).map(_nested_list),
        st.recursive(
            leaf,
            lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=12), inner, max_size=4),
            max_leaves=8,
        ),
    )


def _paths(value: Any, prefix: tuple[Any, ...] = ()) -> Iterator[tuple[Any, ...]]:
    """Every key path in parsed TOML or JSON, the root included."""
    yield prefix
    if isinstance(value, dict):
        for key, child in value.items():
            yield from _paths(child, (*prefix, key))
    elif isinstance(value, list):
        for index, child in enumerate(value):
            yield from _paths(child, (*prefix, index))


def _at(value: Any, path: tuple[Any, ...]) -> Any:
    for part in path:
        value = value[part]
    return value


KNOWN_KEYS = [
    "version",
    "name",
    "calibration",
    "cameras",
    "id",
    "width_px",
    "intrinsics",
    "extrinsics",
    "model",
    "kind",
    "wall",
    "corners_m",
    "pointer",
    "detector",
    "outputs",
    "zmq",
    "endpoints",
    "pointer_colours",
    "format",
    "format_version",
    "end",
    "pairs",
    "rig",
    "clock_offset_ns",
    "pixel_format",
    "height_px",
]


@st.composite
def structural_mutation(draw: st.DrawFn, document: dict[str, Any], *, toml: bool) -> dict[str, Any]:
    """``document`` (parsed) with one key's value replaced, a key or array item deleted, an unknown
    or misplaced key added, or a value wrapped in an array or a table."""
    doc = copy.deepcopy(document)
    paths = list(_paths(doc))
    path = draw(st.sampled_from(paths), label="path")
    kind = draw(st.sampled_from(["replace", "delete", "add", "wrap"]), label="structure edit")
    if not path or kind == "add":
        node = _at(doc, path)
        if not isinstance(node, dict):
            path, node = path[:-1], _at(doc, path[:-1])
        if isinstance(node, dict):
            key = draw(st.sampled_from(KNOWN_KEYS) | st.text(max_size=16), label="key")
            node[key] = draw(hostile_values(toml=toml))
        else:  # an array: one more item
            node.append(draw(hostile_values(toml=toml)))
        return doc
    parent, last = _at(doc, path[:-1]), path[-1]
    if kind == "replace":
        parent[last] = draw(hostile_values(toml=toml), label="value")
    elif kind == "delete":
        del parent[last]
    else:
        parent[last] = [parent[last]] if draw(st.booleans()) else {"x": parent[last]}
    return doc


def _toml_string(text: str) -> str:
    escaped = text.replace("\\", "\\\\").replace('"', '\\"')
    return '"' + "".join(f"\\u{ord(c):04x}" if ord(c) < 0x20 or ord(c) == 0x7F else c for c in escaped) + '"'


def _toml_value(value: Any) -> str:
    """``value`` as TOML (inline tables and arrays, so any nesting has one spelling)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)
    if isinstance(value, str):
        return _toml_string(value)
    if isinstance(value, (datetime, date, time_of_day)):
        return value.isoformat()
    if isinstance(value, list):
        return "[" + ", ".join(_toml_value(item) for item in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{_toml_string(str(k))} = {_toml_value(v)}" for k, v in value.items()) + "}"
    raise TypeError(type(value))


def toml_dumps(document: dict[str, Any]) -> str:
    lines = (f"{_toml_string(str(key))} = {_toml_value(value)}\n" for key, value in document.items())
    return _spell_huge_integers("".join(lines))


# =========================================================================== rig and calibration files

CALIBRATION = """\
# A calibration file for config/simulated.toml, as `trackerd calibrate intrinsics`, `wall` and
# `pointer` write one (the pointer_colours as `trackerd calibrate pointer --live --source simulated
# --frames 5` learned them).
version = 1

[cameras.left]
info = { date = "2026-12-02", views = 24, rms_px = 0.21, board = "9x6 chessboard 25 mm" }

[cameras.left.intrinsics]
model = "opencv"
fx_px = 1661.0
fy_px = 1659.5
cx_px = 962.0
cy_px = 538.5
distortion = [-0.08, 0.05, 0.0004, -0.0003, 0.0]

[cameras.right]
extrinsics = { kind = "pose", position_m = [4.9576, 1.4, 3.0], yaw_deg = -72.3, pitch_deg = -16.9, roll_deg = -0.4 }

[wall]
corners_m = [[0.0, 0.0, 0.0], [3.6576, 0.0, 0.0], [3.6576, 0.9144, 0.0], [0.0, 0.9144, 0.0]]
display_width_px = 7680
display_height_px = 1920

[pointer_colours]
learned = "2026-12-02T15:48:11"
frames = 5

[pointer_colours.red]
min_excess = 65
min_value = 65
ball_excess = 118
background_excess = 134

[pointer_colours.blue]
min_excess = 57
min_value = 57
ball_excess = 103
background_excess = 134
"""


def _simulated_with_calibration() -> str:
    text = (REPO / "config" / "simulated.toml").read_text()
    return text.replace('name = "simulated-datawall"\n', 'name = "simulated-datawall"\ncalibration = "cal.toml"\n', 1)


SEEDS = {
    "simulated": _simulated_with_calibration(),
    "datawall": (REPO / "config" / "datawall.toml").read_text(),
    "calibration": CALIBRATION,
}


def _finite(value: Any, where: str = "") -> None:
    """A rig that was accepted holds no NaN or infinity anywhere (no setting can take them)."""
    if isinstance(value, float):
        assert math.isfinite(value), f"accepted {value} at {where}"
    elif isinstance(value, dict):
        for key, child in value.items():
            _finite(child, f"{where}.{key}")
    elif isinstance(value, (list, tuple)):
        for index, child in enumerate(value):
            _finite(child, f"{where}[{index}]")


def _load(load: Callable[[], Any]) -> tuple[str, Any]:
    """('accepted', result) or ('refused', message); any other exception fails the test."""
    try:
        result = load()
    except TrackerdError as err:
        return "refused", _one_line(err)
    return "accepted", result


def _check_in_process(path: Path) -> tuple[int, str, str]:
    """`trackerd config check PATH` through the CLI's own entry point, in this process: what it prints
    after loading (the cameras' models, the wall's frame, the description) is exercised too."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = trackerd_main(["config", "check", str(path)])
    return code, out.getvalue(), err.getvalue()


def _fuzz_config_case(folder: Path, target: str, mutated: bytes, tally: Counter[str]) -> None:
    """Write the mutated file (the others as they are) and load it every way trackerd does."""
    rig = folder / "rig.toml"
    calibration = folder / "cal.toml"
    if target == "calibration":
        rig.write_text(SEEDS["simulated"])
        calibration.write_bytes(mutated)
        outcome, result = _load(lambda: load_calibration(calibration))
        tally[f"calibration file {outcome}"] += 1
        if outcome == "accepted":
            _finite(result.model_dump(), "calibration")
    else:
        rig.write_bytes(mutated)
        calibration.write_text(CALIBRATION)
    outcome, result = _load(lambda: load_rig(rig))
    tally[f"rig {outcome}"] += 1
    if outcome == "accepted":
        assert isinstance(result, LoadedRig)
        _finite(result.config.model_dump(), "rig")
    code, _out, err = _check_in_process(rig)
    assert code in (0, 2), (code, err)
    if code == 2:
        lines = err.splitlines()
        assert len(lines) == 1 and lines[0].startswith("trackerd config: "), err
    tally["cases"] += 1


def test_mutated_rig_and_calibration_files_load_or_are_refused_in_one_line(tmp_path: Path) -> None:
    """Byte edits of the real files (flips, cuts, insertions, deleted/duplicated/swapped lines) and
    edits of their parsed contents (a hostile value in place of any key's, keys deleted or added),
    for config/simulated.toml naming a calibration file, config/datawall.toml and that calibration
    file: load_rig and load_calibration return a valid result (no NaN or infinity in it) or raise a
    TrackerdError of one line; `trackerd config check` exits 0 or 2, with one line on stderr for 2."""
    tally: Counter[str] = Counter()

    @_fuzz(700)
    @given(data=st.data())
    def case(data: st.DataObject) -> None:
        target = data.draw(st.sampled_from(sorted(SEEDS)), label="file")
        text = SEEDS[target]
        if data.draw(st.booleans(), label="byte edits"):
            mutated = text.encode()
            for _ in range(data.draw(st.integers(1, 3), label="edits")):
                mutated = data.draw(byte_mutation(mutated))
        else:
            document = tomllib.loads(text)
            for _ in range(data.draw(st.integers(1, 3), label="edits")):
                document = data.draw(structural_mutation(document, toml=True))
            mutated = toml_dumps(document).encode()
        _fuzz_config_case(tmp_path, target, mutated, tally)

    case()
    line = _summary("rig and calibration files", tally)
    # The fuzzer reached both sides of the loader: it is not only breaking the syntax.
    assert tally["rig accepted"] and tally["rig refused"] and tally["calibration file refused"], line


def test_the_real_cli_refuses_a_few_mutated_rigs_in_one_line(tmp_path: Path) -> None:
    """A handful of mutated files through `trackerd config check` as a process: exit 0 or 2, one
    error line on stderr, never a traceback (seeded: the same files every run)."""
    generator = random.Random(15)
    simulated = SEEDS["simulated"]
    (tmp_path / "cal.toml").write_text(CALIBRATION)
    cases = [
        simulated.replace("fx_px = 1660.0", "fx_px = " + "9" * 5000),  # an integer too long to convert
        simulated.replace("fx_px = 1660.0", "fx_px = nan"),
        simulated.replace("[wall]", "[wall]\n[wall]"),
        simulated.replace('id = "left"', 'id = "left\\nright"'),
        simulated[: len(simulated) // 2],
    ]
    for _ in range(4):
        data = bytearray(simulated.encode())
        for _ in range(3):
            data[generator.randrange(len(data))] = generator.randrange(256)
        cases.append(data.decode("utf-8", errors="surrogateescape"))
    codes = Counter()
    for k, text in enumerate(cases):
        rig = tmp_path / f"rig{k}.toml"
        rig.write_bytes(text.encode("utf-8", errors="surrogateescape"))
        run = subprocess.run(
            [sys.executable, "-m", "trackerd", "config", "check", str(rig)],
            capture_output=True,
            text=True,
            timeout=60,
            cwd=tmp_path,
        )  # the timeout is only a guard
        assert run.returncode in (0, 2), (k, run.returncode, run.stderr)
        assert "Traceback" not in run.stderr, run.stderr
        if run.returncode == 2:
            assert len(run.stderr.splitlines()) == 1 and run.stderr.startswith("trackerd config: "), run.stderr
        codes[run.returncode] += 1
    print(f"trackerd config check: {len(cases)} mutated rigs, exit codes {dict(codes)}")
    assert codes[2] >= 5


# =========================================================================== recordings

SMALL_PAIRS = 4


def _small_recording(folder: Path) -> Path:
    """The bundled recording's first SMALL_PAIRS pairs, closed cleanly: what the fuzzer mutates (the
    whole bundle is 16 pairs; four keep each case to milliseconds)."""
    small = folder / "small.trec"
    small.mkdir()
    with Recording.open(BUNDLE) as whole:
        end = whole.entries[SMALL_PAIRS].offset
    with (BUNDLE / DATA_FILE).open("rb") as handle:
        (small / DATA_FILE).write_bytes(handle.read(end))
    index = (BUNDLE / INDEX_FILE).read_bytes()
    (small / INDEX_FILE).write_bytes(index[: FILE_HEADER.size + SMALL_PAIRS * INDEX_ENTRY.size])
    meta = json.loads((BUNDLE / METADATA_FILE).read_text())
    meta["end"] = {**meta["end"], "pairs": SMALL_PAIRS, "data_bytes": end}
    (small / METADATA_FILE).write_text(json.dumps(meta, indent=1))
    with Recording.open(small) as recording:
        assert len(recording) == SMALL_PAIRS and not recording.problems, recording.problems
    return small


def _crc_fixed(record: bytearray, header_bytes: int) -> None:
    """Recompute a record header's checksum (its last four bytes): a crafted header, not a damaged one."""
    record[header_bytes - 4 : header_bytes] = zlib.crc32(bytes(record[: header_bytes - 4])).to_bytes(4, "little")


@st.composite
def recording_mutation(draw: st.DrawFn, small: Path) -> Callable[[Path], None]:
    """One edit of a recording folder: byte edits of any of its files (aimed at the headers half the
    time), a hostile value in recording.json, a record header or index entry field set to any value
    with its checksum made to match again (a crafted file), sections swapped, a file missing or something
    else in its place (a directory, a FIFO, a device)."""
    layout = [(entry.offset, entry.record_bytes) for entry in _entries(small)]
    kind = draw(
        st.sampled_from(
            [
                "json bytes",
                "json value",
                "data bytes",
                "index bytes",
                "forged header",
                "forged index",
                "swap",
                "missing",
            ]
        ),
        label="recording edit",
    )
    if kind == "json bytes":
        data = (small / METADATA_FILE).read_bytes()
        mutated = draw(byte_mutation(data))
        return lambda folder: _rewrite(folder / METADATA_FILE, lambda _: mutated)
    if kind == "json value":
        document = json.loads((small / METADATA_FILE).read_text())
        mutated_doc = draw(structural_mutation(document, toml=False))
        text = _spell_huge_integers(json.dumps(mutated_doc))
        return lambda folder: _rewrite(folder / METADATA_FILE, lambda _: text.encode())
    if kind in ("data bytes", "index bytes"):
        name = DATA_FILE if kind == "data bytes" else INDEX_FILE
        size = (small / name).stat().st_size
        if kind == "data bytes" and draw(st.booleans(), label="aim at a header"):
            offset, _ = draw(st.sampled_from(layout))
            at = offset + draw(st.integers(0, 143))
        elif draw(st.booleans(), label="aim at the file header"):
            at = draw(st.integers(0, FILE_HEADER.size - 1))
        else:
            at = draw(st.integers(0, size - 1))
        edit = draw(st.sampled_from(["flip", "truncate", "insert", "delete"]))
        value = draw(st.integers(1, 255))
        inserted = draw(st.binary(min_size=1, max_size=64))

        def edit_bytes(data: bytearray) -> bytearray:
            if edit == "flip" and at < len(data):
                data[at] ^= value
            elif edit == "truncate":
                del data[at:]
            elif edit == "insert":
                data[at:at] = inserted
            else:
                del data[at : at + value]
            return data

        return lambda folder: _rewrite(folder / name, edit_bytes)
    if kind == "forged header":
        offset, _ = draw(st.sampled_from(layout))
        fields = {  # byte offset in the record header: struct format (RECORD_FIXED, FRAME_ENTRY)
            "header_bytes": (4, "<I"),
            "n_frames": (8, "<H"),
            "frame_entry_bytes": (10, "<H"),
            "pair_index": (16, "<Q"),
            "timestamp_ns": (32, "<q"),
            "stored_bytes 0": (RECORD_FIXED.size + 24, "<Q"),
            "encoding 0": (RECORD_FIXED.size + 36, "<B"),
            "stored_bytes 1": (RECORD_FIXED.size + 64, "<Q"),
            "encoding 1": (RECORD_FIXED.size + 76, "<B"),
        }
        field_at, fmt = fields[draw(st.sampled_from(sorted(fields)), label="field")]
        bits = {"<I": 32, "<H": 16, "<Q": 64, "<q": 63, "<B": 8}[fmt]
        number = draw(st.integers(0, 2**bits - 1) | st.sampled_from([0, 1, 2, 3, 144, 145, 1 << 20])) % (1 << bits)

        def forge(data: bytearray) -> bytearray:
            header = bytearray(data[offset : offset + 144])
            if len(header) == 144:
                struct.pack_into(fmt, header, field_at, number)
                _crc_fixed(header, 144)
                data[offset : offset + 144] = header
            return data

        return lambda folder: _rewrite(folder / DATA_FILE, forge)
    if kind == "forged index":
        k = draw(st.integers(0, len(layout) - 1))
        field = draw(st.integers(0, 4), label="index field")
        number = draw(st.integers(0, 2**63 - 1) | st.sampled_from([0, 16, layout[-1][0], 2**64 - 1]))

        def forge_index(data: bytearray) -> bytearray:
            at = FILE_HEADER.size + k * INDEX_ENTRY.size
            if len(data) < at + INDEX_ENTRY.size:
                return data
            values = list(INDEX_ENTRY.unpack_from(data, at))
            values[field] = number if field < 3 else number - 2**63  # sequence, timestamp_ns: signed
            entry = bytearray(INDEX_ENTRY.pack(*values))
            entry[-4:] = zlib.crc32(bytes(entry[:-4])).to_bytes(4, "little")
            data[at : at + INDEX_ENTRY.size] = entry
            return data

        return lambda folder: _rewrite(folder / INDEX_FILE, forge_index)
    if kind == "swap":
        what = draw(st.sampled_from(["two records", "data and index", "index and metadata", "data and metadata"]))
        i, j = draw(st.integers(0, len(layout) - 1)), draw(st.integers(0, len(layout) - 1))

        def swap(folder: Path) -> None:
            if what == "two records":
                (a, la), (b, lb) = sorted([layout[i], layout[j]])
                _rewrite(
                    folder / DATA_FILE,
                    lambda data: (
                        data[:a] + data[b : b + lb] + data[a + la : b] + data[a : a + la] + data[b + lb :]
                        if a != b
                        else data
                    ),
                )
                return
            first, second = {
                "data and index": (DATA_FILE, INDEX_FILE),
                "index and metadata": (INDEX_FILE, METADATA_FILE),
                "data and metadata": (DATA_FILE, METADATA_FILE),
            }[what]
            (folder / first).rename(folder / "swap")
            (folder / second).rename(folder / first)
            (folder / "swap").rename(folder / second)

        return swap
    name = draw(st.sampled_from([METADATA_FILE, DATA_FILE, INDEX_FILE]))
    instead = draw(st.sampled_from(["nothing", "a directory", "a FIFO", "/dev/zero"]), label="in its place")

    def remove(folder: Path) -> None:
        path = folder / name
        if path.is_file():
            path.unlink()
        if path.exists():
            return
        if instead == "a directory":
            path.mkdir()
        elif instead == "a FIFO":  # opening it to read would wait for a writer
            os.mkfifo(path)
        elif instead == "/dev/zero":  # reading it would never end
            path.symlink_to("/dev/zero")

    return remove


def _rewrite(path: Path, edit: Callable[[bytearray], bytes | bytearray]) -> None:
    """Edit a file of the recording in place; nothing when an earlier edit left no file there."""
    if path.is_file():
        path.write_bytes(bytes(edit(bytearray(path.read_bytes()))))


def _entries(folder: Path) -> list[Any]:
    with Recording.open(folder) as recording:
        return list(recording.entries)


def _read_recording(folder: Path, tally: Counter[str]) -> None:
    """Open, read every pair (checksums checked) and the recorded rig, then replay it: each step a
    valid result or a one-line TrackerdError; the replay must finish (no hang)."""
    try:
        recording = Recording.open(folder)
    except TrackerdError as err:
        _one_line(err)
        tally["refused at open"] += 1
        return
    with recording:
        for problem in recording.problems:
            _one_line(problem)
        tally["opened"] += 1
        for index in range(len(recording)):
            try:
                pair = recording.pair(index)
            except TrackerdError as err:
                _one_line(err)
                tally["pairs refused"] += 1
                continue
            assert len(pair.frames) == len(recording.cameras)
            for frame, cam in zip(pair.frames, recording.cameras, strict=True):
                assert frame.image.shape == cam.shape
            tally["pairs read"] += 1
        try:
            recording.rig()
        except TrackerdError as err:
            _one_line(err)
    try:
        source = ReplayPairSource(folder, speed=None)
    except TrackerdError as err:
        _one_line(err)
        return
    with source:
        for _ in range(len(source.recording) + 1):
            # The timeout is only a guard: at speed "max" each pair is there at once.
            if source.next_pair(10.0) is None:
                break
        assert source.finished, "the replay neither delivered its pairs nor finished"
    for problem in source.problems:
        _one_line(problem)


def test_mutated_recordings_open_or_are_refused_in_one_line_and_replay_to_the_end(tmp_path: Path) -> None:
    """Copies of a real recording (the bundle's first pairs) with their metadata, data or index
    damaged or crafted: Recording.open, reading every pair, the recorded rig and a replay each give a
    valid result or a one-line TrackerdError, and the replay always ends."""
    small = _small_recording(tmp_path)
    tally: Counter[str] = Counter()

    @_fuzz(300)
    @given(data=st.data())
    def case(data: st.DataObject) -> None:
        edits = [data.draw(recording_mutation(small)) for _ in range(data.draw(st.integers(1, 2), label="edits"))]
        folder = tmp_path / "case.trec"
        shutil.rmtree(folder, ignore_errors=True)
        shutil.copytree(small, folder)
        for edit in edits:
            edit(folder)
        _read_recording(folder, tally)
        tally["cases"] += 1

    case()
    line = _summary("recordings", tally)
    assert tally["opened"] and tally["refused at open"] and tally["pairs read"] and tally["pairs refused"], line


@pytest.mark.parametrize("mode", ["compressed", "windowed"])
def test_mutated_compressed_and_windowed_recordings_are_refused_in_one_line(tmp_path: Path, mode: str) -> None:
    """The same edits on the bundle's first pairs rewritten compressed (a keyframe, then differences) or
    windowed (a keyframe, then windows): a crafted header may make a difference read as windows or point
    a payload at the wrong bytes; every read is a valid frame or one line, and the replay ends."""
    from trackerd.recording.convert import convert_recording

    small = tmp_path / f"small-{mode}.trec"
    with Recording.open(_small_recording(tmp_path)) as source:
        convert_recording(source, small, mode)
    with Recording.open(small) as recording:
        assert {recording.header(i).frames[0].encoding for i in range(len(recording))} == (
            {2, 3} if mode == "compressed" else {2, 4}
        ), "the pairs after the first are not keyframes"
    tally: Counter[str] = Counter()

    @_fuzz(60)
    @given(data=st.data())
    def case(data: st.DataObject) -> None:
        edits = [data.draw(recording_mutation(small)) for _ in range(data.draw(st.integers(1, 2), label="edits"))]
        folder = tmp_path / "case.trec"
        shutil.rmtree(folder, ignore_errors=True)
        shutil.copytree(small, folder)
        for edit in edits:
            edit(folder)
        _read_recording(folder, tally)
        tally["cases"] += 1

    case()
    line = _summary(f"{mode} recordings", tally)
    assert tally["opened"] and tally["pairs read"] and tally["pairs refused"], line


# =========================================================================== the publisher

TOPICS = [b"", b"s", b"status", b"statu", b"statusX", b"hit", b"pointer", b"\x00", b"\x01"]


def upstream_frames() -> st.SearchStrategy[bytes]:
    """Frames a peer may send upstream: subscriptions and unsubscriptions (\\x01 / \\x00 + a prefix),
    topics, random bytes, empty frames, forged statuses, frames up to a megabyte."""
    forged = st.integers(0, 10**6).map(
        lambda n: json.dumps({**json.loads(status_message(n).model_dump_json()), "state": "FORGED"}).encode()
    )
    return st.one_of(
        st.tuples(st.sampled_from([b"\x00", b"\x01"]), st.sampled_from(TOPICS) | st.binary(max_size=12)).map(
            lambda parts: parts[0] + parts[1]
        ),
        st.sampled_from(TOPICS),
        st.binary(max_size=64),
        forged,
        st.integers(100_001, 1 << 20).map(lambda n: random.Random(n).randbytes(n)),
    )


def _recv_status(sock: zmq.Socket, deadline: float) -> dict[str, Any] | None:
    """The next status on ``sock`` (other topics skipped); None past ``deadline``."""
    while (left_ms := int((deadline - time.monotonic()) * 1000)) > 0:
        if not sock.poll(left_ms):
            return None
        parts = sock.recv_multipart()
        if parts[0] != b"status":
            continue
        assert len(parts) == 2, parts[:3]
        message = decode(parts[0], parts[1])
        return message.model_dump()
    return None


def test_what_a_peer_sends_upstream_never_stops_the_publisher(tmp_path: Path) -> None:
    """A real publisher on loopback; a raw XSUB peer sends random multipart messages (random frame
    counts, subscriptions, unsubscriptions, forged statuses, empty and megabyte frames) while the
    publisher publishes statuses. Afterwards a new status subscriber gets the publisher's last status
    (never anything the peer sent), and publishing still works."""
    tally: Counter[str] = Counter()
    context = zmq.Context()
    action = st.one_of(
        st.lists(upstream_frames(), min_size=1, max_size=6).map(lambda frames: ("send", frames)),
        st.just(("status", None)),
    )

    # 25 cases: each waits for the peer's reconnection (the socket cuts off a peer sending over 4 kB)
    # and for an answer interval, about 0.6 s a case.
    @_fuzz(25)
    @given(actions=st.lists(action, min_size=4, max_size=24))
    def case(actions: list[tuple[str, Any]]) -> None:
        with Publisher(ZmqOutput(endpoints=("tcp://127.0.0.1:*",))) as publisher:
            sequence = 1
            publisher.publish_status(status_message(sequence))
            peer = context.socket(zmq.XSUB)
            peer.setsockopt(zmq.LINGER, 0)
            peer.setsockopt(zmq.SNDTIMEO, 10_000)  # a guard: sending never blocks this long
            peer.connect(publisher.endpoints[0])
            try:
                for kind, frames in actions:
                    if kind == "send":
                        peer.send_multipart(frames)
                        tally["messages sent"] += 1
                        tally["frames sent"] += len(frames)
                        tally["megabyte frames sent"] += sum(len(frame) > 100_000 for frame in frames)
                    else:
                        sequence += 1
                        assert publisher.publish_status(status_message(sequence))
                # An XSUB drops a frame that unsubscribes from what it never subscribed to, even the
                # last frame of a multipart message, which then stays open on the wire and swallows
                # the peer's next frame: a plain frame first closes it. Then everything the peer sent
                # has passed the proxy once its own status subscription is answered or the last
                # status reaches it (the proxy keeps each peer's order).
                peer.send(b"\x02end of the fuzz")
                peer.send(b"\x01status")
                deadline = time.monotonic() + 10.0  # a guard: the answer comes within ANSWER_INTERVAL_S
                while True:
                    status = _recv_status(peer, deadline)
                    assert status is not None, "the peer never got the last status"
                    assert status["state"] != "FORGED" and status["sequence"] <= sequence, status
                    if status["sequence"] == sequence:
                        break
                late = context.socket(zmq.SUB)
                late.setsockopt(zmq.LINGER, 0)
                late.subscribe(b"status")
                late.connect(publisher.endpoints[0])
                status = _recv_status(late, time.monotonic() + 10.0)
                assert status is not None and status["sequence"] == sequence and status["state"] == "running", status
                assert publisher.publish(hit_message()) in (True, False)
                assert publisher.publish_status(status_message(sequence + 1))
                status = _recv_status(late, time.monotonic() + 10.0)
                assert status is not None and status["sequence"] == sequence + 1, status
                late.close()
            finally:
                peer.close()
        tally["cases"] += 1

    try:
        case()
    finally:
        context.destroy(linger=0)
    line = _summary("publisher", tally)
    assert tally["messages sent"] > 100 and tally["megabyte frames sent"], line
