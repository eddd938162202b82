"""`trackerd recording import`'s timestamp CSV (trackerd/recording/importer.py: read_timestamps)."""

from __future__ import annotations

import pytest

from trackerd.errors import RecordingError
from trackerd.recording.importer import read_timestamps


@pytest.mark.parametrize(
    ("column", "value", "says"),
    [
        ("timestamp_ns", "1e300", "is not a whole number"),
        ("timestamp_s", "1e300", "is not a time a recording can hold"),
        ("timestamp_s", "inf", "is not a time a recording can hold"),
        ("timestamp_s", "nan", "is not a time a recording can hold"),
        ("timestamp_ns", "9" * 30, "is not a time a recording can hold"),
        ("timestamp_ms", "seven", "is not a whole number"),
    ],
)
def test_a_time_no_recording_can_hold_is_one_line_naming_its_row(tmp_path, column: str, value: str, says: str) -> None:
    # A new user's audit: 1e300 in an integer column was "not a number"; 1e300, inf and nan in seconds escaped
    # as OverflowError / ValueError tracebacks from the conversion to nanoseconds.
    csv_path = tmp_path / "times.csv"
    csv_path.write_text(f"name,{column}\n01,12\n02,{value}\n")
    with pytest.raises(RecordingError) as caught:
        read_timestamps(csv_path, ["left", "right"])
    message = str(caught.value)
    assert message.startswith(f"{csv_path}:3: {column} '{value}' ") and says in message, message


def test_times_a_recording_can_hold_are_read_in_nanoseconds(tmp_path) -> None:
    csv_path = tmp_path / "times.csv"
    csv_path.write_text("name,timestamp_s\n01,12.5\n02,13.25\n")
    stamps = read_timestamps(csv_path, ["left", "right"])
    assert [stamps[(name, None)].ns for name in ("01", "02")] == [12_500_000_000, 13_250_000_000]
