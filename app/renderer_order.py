"""The draw order of a ``SplatRenderer`` (its part ``DrawOrder``): the back-to-front order comes from a sorter thread
(``app/depth_sort.py``: a counting sort of quantised depth keys in a numba kernel that releases the GIL). A new view
(its depth row) or detail submits a sort and returns at once; a frame draws with the newest finished order, uploading
only the index buffer when a new one arrives (the data textures do not move). ``prepare(wait=True)`` (screenshots,
exports, tests) waits for the order of its own view; the studio's paced view (``app/scene_view.py``) never waits. A
still camera submits nothing and uploads nothing. ``draw_points`` draws a slice of the order in chunks.
"""

from __future__ import annotations

import contextlib
import math
import time
from typing import NamedTuple

import moderngl
import numpy as np

from gstyle_core.cameras.camera import Camera

from .depth_sort import DepthSorter, SortRequest, SortResult

NEAR = 0.01  # the near plane of the depth sort and the projection


class Gaussians(NamedTuple):
    """What the order is sorted from: the renderer's centres, its Gaussians most important first, its geometry's
    version and the depth key's bits."""

    means: np.ndarray
    by_importance: np.ndarray
    geometry_version: int
    sort_bits: int

    @property
    def count(self) -> int:
        """How many Gaussians there are."""
        return int(self.means.shape[0])


class DrawOrder:
    """A renderer's back-to-front order: the sorter thread, the index buffer holding the newest finished order, and
    what it was sorted for."""

    def __init__(self, ctx: moderngl.Context, sorter: DepthSorter | None = None) -> None:
        self.sorter = sorter if sorter is not None else DepthSorter()
        self.index_buffer = ctx.buffer(reserve=4)
        self._requested: tuple | None = None  # key of the last sort submitted: (depth row, keep, geometry, bits)
        self.key: tuple | None = None  # key of the order in the index buffer (None: no usable order)
        self.instances = 0  # Gaussians in that order (those in front of the camera)
        self.sort_count = 0  # orders received from the sorter and uploaded (for tests and stats)
        self.last_wait_ms = 0.0  # how long the last ``prepare`` waited for a sort (0 unless asked to wait)

    def prepare(self, gaussians: Gaussians, camera: Camera, detail: float = 1.0, wait: bool = True) -> bool:
        """Bring the order up to date for ``camera``: submit a sort when the view's depth row, the detail or the
        geometry changed, and use the newest finished order (``wait``: the order of this request, waiting for it).
        True when the order in use is this request's."""
        if not gaussians.count:
            return True
        want = self._request(gaussians, camera, detail)
        self._use(self.sorter.take(), gaussians.geometry_version)
        if wait and self.key != want:
            t0 = time.perf_counter()
            self._use(self.sorter.wait(want), gaussians.geometry_version)
            self.last_wait_ms = (time.perf_counter() - t0) * 1e3
        else:
            self.last_wait_ms = 0.0
        return self.key == want

    def forget(self) -> None:
        """The order's indices mean nothing now (a geometry of another count): none until the next one arrives."""
        self.key, self.instances = None, 0

    def detail(self, count: int) -> float:
        """Fraction of the ``count`` Gaussians the loaded order was sorted from (the detail it draws)."""
        return self.key[1] / count if self.key is not None and count else 1.0

    def read(self) -> np.ndarray:
        """The order in use (int32 Gaussian indices, back to front), read back from the index buffer."""
        return np.frombuffer(self.index_buffer.read(size=4 * self.instances), np.int32).copy()

    def _request(self, gaussians: Gaussians, camera: Camera, detail: float) -> tuple:
        """Submit a sort of the view's depth row at this detail unless it is the last one submitted; its key."""
        count = gaussians.count
        keep = count if detail >= 1.0 else max(1, int(math.ceil(float(detail) * count)))
        row = np.array(np.asarray(camera.world_to_cam, np.float64)[2], np.float64)
        want = (row.tobytes(), keep, gaussians.geometry_version, gaussians.sort_bits)
        if want != self._requested:
            subset = gaussians.by_importance[:keep] if keep < count else None
            self.sorter.submit(SortRequest(want, gaussians.means, row, NEAR, gaussians.sort_bits, subset))
            self._requested = want
        return want

    def _use(self, result: SortResult | None, geometry_version: int) -> None:
        """Upload a finished order into the index buffer (one of an older geometry is dropped)."""
        if result is None or result.order is None or result.key[2] != geometry_version:
            return
        order = result.order
        if order.nbytes > self.index_buffer.size:
            self.index_buffer.orphan(max(order.nbytes, 4))
        if order.size:
            self.index_buffer.write(order)
        self.key = result.key
        self.instances = int(order.size)
        self.sort_count += 1


def draw_points(ctx: moderngl.Context, vao: moderngl.VertexArray, first: int, count: int, chunk: int) -> None:
    """Draw ``count`` projected splats of the order from ``first`` in calls of ``chunk`` (0: one call); after each
    call, wait for the one before it (a query's result), never for the last: the binning of one overlaps the raster
    of the other, and at most two are in flight."""
    step = chunk if 0 < chunk < count else count
    previous = None
    for start in range(first, first + count, step):
        query = ctx.query(primitives=True) if step < count else None
        with query if query is not None else contextlib.nullcontext():
            vao.render(moderngl.POINTS, vertices=min(step, first + count - start), first=start)
        if previous is not None:
            _ = previous.primitives  # blocks until that call is rasterised
        previous = query
