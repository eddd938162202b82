"""What batching several pairs' windows into one set of flat arrays would save (docs/recording.md).

The tracked measurement (trackerd/detect/window_measure.py, coverage.py) runs three built lists of
NumPy calls (`flat.run`: the colour excess, the own samples' coverage, every pixel's coverage) on
one set of flat arrays holding a pair's four windows (two cameras, two ends). This times those
lists on a Workspace of 4 windows (one pair, as today) and of 16 and 64 (4 and 16 pairs), per pair,
on random pixels (the calls' cost does not depend on the values). Best of 7 rounds of 200 runs.

    .venv/bin/python scripts/bench_flat_batch.py
"""

from __future__ import annotations

import time

import numpy as np

from trackerd.detect.coverage import _solve_ops
from trackerd.detect.flat import Workspace, run
from trackerd.detect.window_measure import _excess_ops, _own_coverage_ops

WINDOWS_PER_PAIR = 4


def seconds_per_run(ws: Workspace, repeats: int = 200, rounds: int = 7) -> float:
    ops = ws.ops("excess", _excess_ops) + ws.ops("own coverage", _own_coverage_ops) + ws.ops("solve", _solve_ops)
    best = float("inf")
    for _ in range(rounds):
        start = time.perf_counter()
        for _ in range(repeats):
            run(ops)
        best = min(best, (time.perf_counter() - start) / repeats)
    return best


def main() -> None:
    rng = np.random.default_rng(1)
    print("half cells  windows  us a run  us a pair")
    for half_cells in (8, 12):
        side = 2 * half_cells + 3  # the window and its ring
        for windows in (4, 16, 64):
            ws = Workspace(windows, side, side)
            ws.planes[:] = rng.random(ws.planes.shape, dtype=np.float32) * 255.0
            with np.errstate(all="ignore"):  # random pixels divide by zero here and there
                seconds = seconds_per_run(ws)
            pairs = windows / WINDOWS_PER_PAIR
            print(f"{half_cells:10d}  {windows:7d}  {seconds * 1e6:8.1f}  {seconds * 1e6 / pairs:9.1f}")


if __name__ == "__main__":
    main()
