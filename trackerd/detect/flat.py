"""Small windows of a Bayer frame laid end to end in flat arrays, so that a neighbour is an offset.

The ends are measured in small windows, a few hundred cells each. At that size
a NumPy call costs about a microsecond whatever it computes, half of it for
slicing its arguments, and a call on a 2-D slice costs about twice one on a 1-D
slice (it cannot run as one loop). So:

* the windows of both ends are measured together, in flat arrays: window e's
  cell (i, j) is element ``e * rows * cols + i * cols + j`` of a per-cell array,
  its right neighbour is the next element and the one below ``cols`` further,
  and an operation on every cell of both windows, neighbours included, is one
  call on 1-D slices. The three pixels of each cell other than the end's own
  colour sample are three such arrays end to end (``size`` apart), so that
  per-pixel work is one call too;
* the layout's buffers, and every slice of them a computation uses, are made
  once: a computation is built as a list of ufunc calls on fixed views (an
  :data:`Ops` list) when a layout is first used, and each frame just runs the
  list (:func:`run`);
* masks are float32 0/1, not bool (a product with a bool array converts it, at
  the cost of another call);
* a Python number in a computation is made a 0-d float32 array once, when the
  computation is built: NumPy converts a Python scalar on every call (about
  0.7 us a call at these sizes), and the array is the float32 value that
  conversion gives, so the results are the same.

Each window (``rows`` x ``cols`` cells) is the region measured with a ring of one
cell around it. Reading neighbours on the ring wraps round into the next row,
window or plane, so values computed there are meaningless; the measuring code
keeps every thresholded sample off the ring and off the region's border, and a
cell further than one cell from a thresholded sample counts for nothing, so they
never count.

A :class:`Workspace` holds the buffers and built computations of one layout;
a :class:`WorkspaceCache` keeps the last few layouts. A workspace is not
thread-safe: keep one cache per detector (per camera).
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable
from typing import Any

import numpy as np

F32 = np.float32

Ops = list[tuple[Any, ...]]
"""Calls to make in order, each ``(ufunc, *inputs, out)``."""

Calls = list[tuple[Any, tuple[Any, ...], Any]]
"""A built computation: each call as ``(ufunc, inputs, out)``, the inputs a tuple made once, so that
making a call builds no list (``for f, *args, out in ops`` makes one per call: 60 calls took 41 us
that way, 32 us so). (Not the output by position, which is cheaper still: np.maximum and
np.minimum warn about it.)"""


def run(calls: Calls) -> None:
    """Make the calls of a built computation."""
    for f, inputs, out in calls:
        f(*inputs, out=out)


class Workspace:
    """Buffers of ``n`` windows of ``rows`` x ``cols`` cells (ring included).

    Per-cell arrays have ``size = n * rows * cols`` elements; ``lo:hi`` is the
    range of those whose eight neighbours lie in the arrays (all but the first
    and last ``cols + 1``). Per-pixel arrays hold the three other pixels' planes
    end to end (``3 * size``), and their range is ``lo:3 * size - lo``.
    """

    def __init__(self, n: int, rows: int, cols: int) -> None:
        self.n, self.rows, self.cols = n, rows, cols
        self.cells = rows * cols
        size = n * self.cells
        self.size = size
        self.lo, self.hi = cols + 1, size - cols - 1

        # The frame's pixels, window by window, and the four samples of each cell as planes:
        # plane 2 * dy + dx is the pixel (dx, dy) from the end's own colour sample, so plane 0
        # is the own colour, 1 the green to its right, 2 the green below, 3 the other colour.
        # Plane 4 is the own sample's colour excess (trackerd.detect.window_measure).
        self.pixels = np.zeros((n, 2 * rows, 2 * cols), dtype=np.uint8)
        self.planes = np.zeros((5, size), dtype=F32)
        self.pixels_as_planes = self.pixels.reshape(n, rows, 2, cols, 2).transpose(2, 4, 0, 1, 3)
        self.planes_5d = self.planes[:4].reshape(2, 2, n, rows, cols)
        self.own = self.planes[0]
        self.excess = self.planes[4]
        self.own_and_excess = self.planes[0::4].reshape(2, n, self.cells)

        self.strong = np.zeros(size, dtype=F32)
        """The end's thresholded own samples, 1.0 (0.0 elsewhere)."""
        self.strong_2d = self.strong.reshape(n, self.cells)
        self.strong_3d = self.strong.reshape(n, rows, cols)
        # Coverage: rows 0-2 the other pixels of each cell (as the planes), row 3 the own
        # sample (``cover``).
        self.coverage = np.zeros((4, size), dtype=F32)
        self.coverage_2d = self.coverage.reshape(4 * n, self.cells)
        self.cover = self.coverage[3]
        self.cover_3d = self.cover.reshape(n, rows, cols)
        self.level = np.zeros(size, dtype=F32)
        """A per-window constant spread over its cells (filled through ``level_2d``)."""
        self.level_2d = self.level.reshape(n, self.cells)
        self.box = np.zeros(size, dtype=F32)
        self.box_3d = self.box.reshape(n, rows, cols)
        self.excess_min = np.zeros(size, dtype=F32)
        """Per cell, the excess a sample must reach (never, on the ring); see ``thresholds``."""
        self.value_min = np.zeros(size, dtype=F32)
        self.thresholds: tuple[tuple[int, int], ...] = ()
        """(min_excess, min_value) per window that ``excess_min`` and ``value_min`` hold."""

        # Scratch, per cell and per pixel. Each computation has its own: some rely on elements
        # they never write staying 0.
        self.cell = [np.zeros(size, dtype=F32) for _ in range(12)]
        self.pixel = [np.zeros(3 * size, dtype=F32) for _ in range(6)]
        self.ones = np.ones(3 * size, dtype=F32)
        self.zeros = np.zeros(3 * size, dtype=F32)

        # Per cell of a window: 1, twice its column and twice its row in the measured region
        # (the ring's first cell is -1), for the centroid's sums in one product.
        i, j = np.divmod(np.arange(self.cells), cols)
        moments = np.stack([np.ones(self.cells), 2.0 * (j - 1), 2.0 * (i - 1)], axis=1)
        self.moments = moments.astype(F32)
        self.window_starts = np.arange(n + 1) * self.cells
        self._built: dict[str, Calls] = {}

    def ops(self, name: str, build: Callable[[Workspace], Ops]) -> Calls:
        """The computation ``build`` makes for this layout (made on first use), as :func:`run` takes it."""
        calls = self._built.get(name)
        if calls is None:
            ops = build(self)
            calls = self._built[name] = [(op[0], tuple(_as_array(arg) for arg in op[1:-1]), op[-1]) for op in ops]
        return calls


def _as_array(arg: Any) -> Any:
    """A Python number as the 0-d float32 array NumPy would convert it to (the arrays are float32)."""
    if isinstance(arg, (float, int)) and not isinstance(arg, bool):
        return np.array(arg, dtype=F32)
    return arg


class WorkspaceCache:
    """The last few workspaces used, by layout.

    While tracking, one or two layouts are in use at a time and the window's size
    changes only as the ball's image grows or shrinks; a new layout costs about
    0.1 ms. A workspace takes about 200 bytes per cell of its windows (0.3 MB for
    two 27 x 27 windows), hence the small default.
    """

    def __init__(self, size: int = 8) -> None:
        self._size = size
        self._spaces: OrderedDict[tuple[int, int, int, str], Workspace] = OrderedDict()

    def get(self, n: int, rows: int, cols: int, use: str = "") -> Workspace:
        """The workspace of that layout for that use (two uses may need one at the same time)."""
        key = (n, rows, cols, use)
        space = self._spaces.get(key)
        if space is None:
            space = Workspace(n, rows, cols)
            self._spaces[key] = space
            if len(self._spaces) > self._size:
                self._spaces.popitem(last=False)
        else:
            self._spaces.move_to_end(key)
        return space


def round_up(cells: int, multiple: int = 4) -> int:
    """``cells`` rounded up to a multiple (fewer distinct layouts, each reused more)."""
    return -(-cells // multiple) * multiple
