"""Back-to-front order of the viewer's Gaussians, computed off the UI thread.

The depth of a Gaussian is the third row of the view matrix applied to its mean. The order is a counting sort of
quantised keys: the visible depth range (in front of the near plane) is cut into ``2**bits`` buckets, the
farthest bucket first; Gaussians in one bucket keep their input order (the sort is stable). So every pair whose
depths differ by more than one bucket width is drawn in the exact order; pairs closer than that may swap, which
a bucket of 1/65,536 of the depth range does not show (``bench/viewer_scale.py`` compares the images).

One numba kernel does the whole sort (depths, range, histogram, scatter) without the GIL, so the UI thread keeps
running while ``DepthSorter``'s thread sorts. The sorter keeps one request pending: a newer view replaces an older
one that has not started (only the newest view is worth sorting), and the UI draws with the newest finished order.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numba import njit

DEFAULT_BITS = 16  # key bits; bench/viewer_scale.py measures 16 against bits from the count (key_bits)
MIN_BITS, MAX_BITS = 10, 20


def key_bits(count: int) -> int:
    """Key bits from the number of Gaussians: about log2(count / 4), clamped to 10-20 (as SuperSplat)."""
    return int(min(MAX_BITS, max(MIN_BITS, round(math.log2(max(count, 1) / 4)))))


@njit(cache=True, nogil=True)
def _depths(means, subset, use_subset, row, near, depth):  # pragma: no cover - numba
    """float32 view depth of each Gaussian (of ``subset`` when ``use_subset``) into ``depth``, NaN where not in
    front of the near plane or not finite; returns (visible count, nearest, farthest)."""
    count = subset.shape[0] if use_subset else means.shape[0]
    lo, hi, visible = np.inf, -np.inf, 0
    for k in range(count):
        i = subset[k] if use_subset else k
        z = np.float32(means[i, 0] * row[0] + means[i, 1] * row[1] + means[i, 2] * row[2] + row[3])
        if z > near and z < np.inf:
            depth[k] = z
            lo, hi, visible = min(lo, z), max(hi, z), visible + 1
        else:
            depth[k] = np.nan
    return visible, lo, hi


@njit(cache=True, nogil=True)
def _sort_kernel(means, subset, use_subset, row, near, bits, depth, counts, out):  # pragma: no cover - numba
    """Counting sort of the quantised depths, farthest first; writes Gaussian indices into ``out`` and returns how
    many (the visible ones)."""
    visible, lo, hi = _depths(means, subset, use_subset, row, near, depth)
    if visible == 0:
        return 0
    buckets = 1 << bits
    scale = (buckets - 1) / (np.float64(hi) - lo) if hi > lo else 0.0
    counts[:] = 0
    n = depth.shape[0]
    for k in range(n):
        d = depth[k]
        if d == d:
            counts[int((hi - np.float64(d)) * scale) + 1] += 1
    for b in range(buckets):
        counts[b + 1] += counts[b]
    for k in range(n):
        d = depth[k]
        if d == d:
            key = int((hi - np.float64(d)) * scale)
            out[counts[key]] = subset[k] if use_subset else k
            counts[key] += 1
    return visible


@dataclass
class SortScratch:
    """Work arrays one sorting thread reuses between sorts (depths and the histogram)."""

    depth: np.ndarray = field(default_factory=lambda: np.empty(0, np.float32))
    counts: np.ndarray = field(default_factory=lambda: np.empty(0, np.int64))

    def sized(self, n: int, bits: int) -> tuple[np.ndarray, np.ndarray]:
        """The depth array (at least n) and histogram (2**bits + 1) views, grown when needed."""
        if self.depth.shape[0] < n:
            self.depth = np.empty(n, np.float32)
        if self.counts.shape[0] < (1 << bits) + 1:
            self.counts = np.empty((1 << bits) + 1, np.int64)
        return self.depth[:n], self.counts[: (1 << bits) + 1]


def depth_order(means: np.ndarray, view: np.ndarray, near: float, bits: int = DEFAULT_BITS,
                subset: np.ndarray | None = None, scratch: SortScratch | None = None) -> np.ndarray:
    """int32 indices of the Gaussians (of ``subset``, int32 indices, when given) in front of ``near``, farthest
    first, ordered by ``bits``-bit depth keys. ``view``: the world-to-camera 4x4 (or its third row)."""
    if not MIN_BITS <= bits <= MAX_BITS:
        raise ValueError(f"key bits must be {MIN_BITS}-{MAX_BITS}, got {bits}")
    means = np.ascontiguousarray(means, np.float32)
    view = np.asarray(view, np.float64)
    row = np.ascontiguousarray(view[2] if view.shape == (4, 4) else view.reshape(4))
    use_subset = subset is not None
    index = np.ascontiguousarray(subset, np.int32) if use_subset else np.zeros(1, np.int32)
    n = index.shape[0] if use_subset else means.shape[0]
    depth, counts = (scratch or SortScratch()).sized(n, bits)
    out = np.empty(n, np.int32)
    visible = _sort_kernel(means, index, use_subset, row, float(near), bits, depth, counts, out)
    return out[:visible]


@dataclass(frozen=True)
class SortRequest:
    """What to sort: the means (and optional subset) seen with the view row; ``key`` names the request."""

    key: Any
    means: np.ndarray
    view_row: np.ndarray
    near: float
    bits: int = DEFAULT_BITS
    subset: np.ndarray | None = None


@dataclass(frozen=True)
class SortResult:
    """A finished sort: the request's key, the order (None if the sort raised ``error``) and its seconds."""

    key: Any
    order: np.ndarray | None
    seconds: float
    error: BaseException | None = None


@dataclass
class SorterStats:
    """What the sorter did: requests submitted, sorts run, requests replaced before they started."""

    submitted: int = 0
    sorted: int = 0
    dropped: int = 0
    last_ms: float = 0.0
    max_ms: float = 0.0


def sort_request(request: SortRequest, scratch: SortScratch) -> np.ndarray:
    """The sorter's default work: ``depth_order`` of the request."""
    return depth_order(request.means, request.view_row, request.near, request.bits, request.subset, scratch)


def exact_sort_request(request: SortRequest, scratch: SortScratch) -> np.ndarray:
    """The exact order of a request (numpy's argsort of float64 depths, ``splat_data.back_to_front_order``): the
    reference the quantised order and the texture layouts are measured against (benches, tests)."""
    from .splat_data import back_to_front_order

    view = np.zeros((4, 4))
    view[2] = request.view_row
    if request.subset is None:
        return back_to_front_order(request.means, view, request.near)
    return request.subset[back_to_front_order(request.means[request.subset], view, request.near)]


class DepthSorter:
    """A thread that sorts the newest submitted view; ``submit`` never blocks, ``take`` returns the newest finished
    order (once), ``wait`` blocks until the order of a given request is finished."""

    def __init__(self, sort: Callable[[SortRequest, SortScratch], np.ndarray] = sort_request,
                 name: str = "depth-sorter") -> None:
        self._sort = sort
        self._name = name
        self._cond = threading.Condition()
        self._pending: SortRequest | None = None
        self._busy = False
        self._done: SortResult | None = None
        self._stopping = False
        self._thread: threading.Thread | None = None
        self.stats = SorterStats()

    def submit(self, request: SortRequest) -> None:
        """Queue ``request`` in place of any request not started yet, and return at once."""
        with self._cond:
            if self._stopping:
                raise RuntimeError("the depth sorter was stopped")
            if self._pending is not None:
                self.stats.dropped += 1
            self._pending = request
            self.stats.submitted += 1
            if self._thread is None:
                self._thread = threading.Thread(target=self._run, name=self._name, daemon=True)
                self._thread.start()
            self._cond.notify_all()

    def take(self) -> SortResult | None:
        """The newest finished result not taken yet (None if there is none); raises a sort's error."""
        with self._cond:
            result, self._done = self._done, None
        return _checked(result)

    def wait(self, key: Any, timeout: float | None = None) -> SortResult | None:
        """Block until the result of the request named ``key`` (submitted, not taken) is finished and take it; None
        after ``timeout`` seconds or when the request was replaced by a newer one."""
        def finished() -> bool:
            ours = self._done is not None and self._done.key == key
            gone = not self._busy and (self._pending is None or self._pending.key != key)
            return ours or gone or self._stopping

        with self._cond:
            self._cond.wait_for(finished, timeout)
            result = self._done if self._done is not None and self._done.key == key else None
            if result is not None:
                self._done = None
        return _checked(result)

    def idle(self, timeout: float | None = None) -> bool:
        """Wait until nothing is pending or running; False after ``timeout`` seconds."""
        with self._cond:
            return self._cond.wait_for(lambda: self._pending is None and not self._busy, timeout)

    def stop(self, timeout: float = 10.0) -> None:
        """Stop the thread (a running sort finishes first); pending requests are dropped."""
        with self._cond:
            self._stopping = True
            self._pending = None
            self._cond.notify_all()
            thread = self._thread
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout)

    @property
    def running(self) -> bool:
        """The thread is alive."""
        return self._thread is not None and self._thread.is_alive()

    def _run(self) -> None:
        scratch = SortScratch()
        while True:
            with self._cond:
                self._cond.wait_for(lambda: self._pending is not None or self._stopping)
                if self._stopping:
                    self._cond.notify_all()
                    return
                request, self._pending, self._busy = self._pending, None, True
            t0 = time.perf_counter()
            try:
                result = SortResult(request.key, self._sort(request, scratch), time.perf_counter() - t0)
            except Exception as exc:  # handed to the caller by take()/wait(), not lost in the thread
                result = SortResult(request.key, None, time.perf_counter() - t0, exc)
            with self._cond:
                self._done, self._busy = result, False
                ms = result.seconds * 1e3
                self.stats.sorted += 1
                self.stats.last_ms, self.stats.max_ms = ms, max(self.stats.max_ms, ms)
                self._cond.notify_all()


def _checked(result: SortResult | None) -> SortResult | None:
    if result is not None and result.error is not None:
        raise RuntimeError(f"depth sort failed: {result.error}") from result.error
    return result
