"""The example rigs shipped inside the package, so commands have a default rig from any directory.

The repository's top-level ``config/`` holds the one copy of each example (the files an
operator copies and edits). ``trackerd/examples`` is a symbolic link to it, and pyproject's
package-data puts its ``*.toml`` into the wheel, so a checkout, an editable install and
a wheel in site-packages all find the same files here, wherever the command runs.
"""

from __future__ import annotations

from importlib.resources import files
from pathlib import Path

EXAMPLE_RIGS = ("datawall", "simulated", "gentl-emulated", "gentl-viky")
"""``datawall``: the report's geometry, to copy for a new wall; ``simulated``: the rig the simulator renders;
``gentl-emulated``: two of pylon's emulated cameras (PYLON_CAMEMU=2) through the pylon backend;
``gentl-viky``: two virtual devices of genicam's test producer viky.cti through the gentl backend."""


def example_rig(name: str) -> Path:
    """The file of the bundled example rig ``name`` (one of :data:`EXAMPLE_RIGS`).

    A path, not a resource handle, because the loader names the file in its errors and
    resolves a ``calibration`` it names next to it; trackerd is installed unzipped.
    """
    if name not in EXAMPLE_RIGS:
        raise ValueError(f"no example rig {name!r}; there are {', '.join(EXAMPLE_RIGS)}")
    return Path(str(files("trackerd") / "examples" / f"{name}.toml"))
