"""The draw order of a ``SplatRenderer`` (its part: a mixin): sorts of the view's depth row submitted to the
renderer's sorter thread (``app/depth_sort.py``), the newest finished order uploaded into the index buffer, and what
callers read of it. It reads the renderer's ``count``, ``geometry_version``, ``sort_bits``, ``_means``,
``_by_importance``, ``_sorter``, ``_index_buffer`` and ``_instances``.
"""

from __future__ import annotations

import math
import time

import numpy as np

from gstyle_core.cameras.camera import Camera

from .depth_sort import DepthSorter, SortRequest, SortResult

NEAR = 0.01  # the near plane of the depth sort and the projection


class DrawOrderMixin:
    """``SplatRenderer``'s back-to-front order: ``prepare``, ``has_order``, ``order_detail``, ``order``,
    ``sorter``."""

    def prepare(self, camera: Camera, detail: float = 1.0, wait: bool = True) -> bool:
        """Bring the draw order up to date for ``camera``: submit a sort when the view's depth row, the detail or
        the geometry changed, and use the newest finished order (``wait``: the order of this request, waiting for
        it). True when the order in use is this request's."""
        if not self.count:
            return True
        want = self._request_order(camera, detail)
        self._use_order(self._sorter.take())
        if wait and self._order_key != want:
            t0 = time.perf_counter()
            self._use_order(self._sorter.wait(want))
            self.last_wait_ms = (time.perf_counter() - t0) * 1e3
        else:
            self.last_wait_ms = 0.0
        return self._order_key == want

    @property
    def has_order(self) -> bool:
        """An order of the current geometry's Gaussians is loaded (perhaps of an older view)."""
        return self._order_key is not None or not self.count

    @property
    def order_detail(self) -> float:
        """Fraction of the Gaussians the loaded order was sorted from (the detail it draws)."""
        return self._order_key[1] / self.count if self._order_key is not None and self.count else 1.0

    def order(self) -> np.ndarray:
        """The draw order in use (int32 Gaussian indices, back to front), read back from the index buffer."""
        return np.frombuffer(self._index_buffer.read(size=4 * self._instances), np.int32).copy()

    @property
    def sorter(self) -> DepthSorter:
        """The thread that sorts this renderer's Gaussians."""
        return self._sorter

    def _request_order(self, camera: Camera, detail: float) -> tuple:
        """Submit a sort of the view's depth row at this detail unless it is the last one submitted; its key."""
        keep = self.count if detail >= 1.0 else max(1, int(math.ceil(float(detail) * self.count)))
        row = np.array(np.asarray(camera.world_to_cam, np.float64)[2], np.float64)
        want = (row.tobytes(), keep, self.geometry_version, self.sort_bits)
        if want != self._requested:
            subset = self._by_importance[:keep] if keep < self.count else None
            self._sorter.submit(SortRequest(want, self._means, row, NEAR, self.sort_bits, subset))
            self._requested = want
        return want

    def _use_order(self, result: SortResult | None) -> None:
        """Upload a finished order into the index buffer (one of an older geometry is dropped)."""
        if result is None or result.order is None or result.key[2] != self.geometry_version:
            return
        order = result.order
        if order.nbytes > self._index_buffer.size:
            self._index_buffer.orphan(max(order.nbytes, 4))
        if order.size:
            self._index_buffer.write(order)
        self._order_key = result.key
        self._instances = int(order.size)
        self.sort_count += 1
