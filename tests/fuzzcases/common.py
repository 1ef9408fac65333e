"""What every fuzz case shares: the source of choices, byte-level mutations and the checks on outcomes."""

from __future__ import annotations

import random
import tracemalloc
from collections.abc import Callable, Sequence
from typing import Protocol, TypeVar

T = TypeVar("T")

# Counts a lying header may claim: around the truth, at integer-width boundaries, absurdly large.
HUGE_COUNTS = [0, 1, 255, 256, 257, 65535, 2**31 - 1, 2**31, 2**32 - 1, 2**32, 2**53, 2**63 - 1, 2**64, 10**12, 10**30]
# Float values that break naive decoders.
NASTY_FLOATS = [float("nan"), float("inf"), float("-inf"), 3.4e38, -3.4e38, 1e-45, -0.0, 1e30, -1e30, 1e-30]


class FuzzFailure(AssertionError):
    """A reader broke its contract: an invalid result or a malformed error message."""


class Draw(Protocol):
    """Where a case generator gets its choices from."""

    def integer(self, lo: int, hi: int) -> int:
        """An integer in [lo, hi]."""
        ...

    def choice(self, options: Sequence[T]) -> T:
        """One of ``options``."""
        ...


class RandomDraw:
    """A :class:`Draw` backed by ``random.Random`` (the soak benchmark)."""

    def __init__(self, rng: random.Random) -> None:
        self.rng = rng

    def integer(self, lo: int, hi: int) -> int:
        return self.rng.randint(lo, hi)

    def choice(self, options: Sequence[T]) -> T:
        return options[self.rng.randrange(len(options))]


def draw_bytes(draw: Draw, n: int) -> bytes:
    """``n`` pseudo-random bytes from one drawn seed."""
    return random.Random(draw.integer(0, 2**32 - 1)).randbytes(n)


def _truncate(data: bytes, draw: Draw) -> bytes:
    return data[: draw.integer(0, max(len(data) - 1, 0))]


def _flip(data: bytes, draw: Draw) -> bytes:
    if not data:
        return data
    out = bytearray(data)
    for _ in range(draw.integer(1, 4)):
        out[draw.integer(0, len(out) - 1)] ^= draw.integer(1, 255)
    return bytes(out)


def _overwrite(data: bytes, draw: Draw) -> bytes:
    if not data:
        return data
    start = draw.integer(0, len(data) - 1)
    size = draw.integer(1, 16)
    fill = draw.choice([b"\x00" * size, b"\xff" * size, draw_bytes(draw, size)])
    return data[:start] + fill + data[start + size :]


def _insert(data: bytes, draw: Draw) -> bytes:
    at = draw.integer(0, len(data))
    return data[:at] + draw_bytes(draw, draw.integer(1, 32)) + data[at:]


def _delete(data: bytes, draw: Draw) -> bytes:
    if not data:
        return data
    start = draw.integer(0, len(data) - 1)
    return data[:start] + data[start + draw.integer(1, 64) :]


def _append(data: bytes, draw: Draw) -> bytes:
    return data + draw_bytes(draw, draw.integer(1, 64))


BYTE_MUTATIONS = {
    "truncate": _truncate,
    "flip": _flip,
    "overwrite": _overwrite,
    "insert": _insert,
    "delete": _delete,
    "append": _append,
}


def mutate_bytes(data: bytes, draw: Draw) -> bytes:
    """Apply one drawn byte-level mutation."""
    return BYTE_MUTATIONS[draw.choice(sorted(BYTE_MUTATIONS))](data, draw)


def one_line(exc: BaseException) -> None:
    """Raise FuzzFailure unless the error message is one non-empty line of printable text."""
    text = str(exc)
    if not text.strip() or "Traceback" in text or any(ord(c) < 32 or ord(c) == 127 for c in text):
        raise FuzzFailure(f"error message is not one printable line: {text!r}")


def rejected(exc: BaseException) -> str:
    """A reader's format error on hostile input: it must be one printable line, and must not be a MemoryError
    turned into a format error (the claimed size has to be checked against the file before allocating)."""
    one_line(exc)
    if "MemoryError" in str(exc):
        raise FuzzFailure(f"allocation attempted before the size check: {exc}") from None
    return "error"


MEMORY_LIMIT = 64 << 20  # bytes a reader may allocate on these small inputs (tracemalloc peak)


def run_bounded(check: Callable[[T], str], target: T, limit: int = MEMORY_LIMIT) -> tuple[str, int]:
    """Run ``check(target)`` under tracemalloc; FuzzFailure when its allocations peak above ``limit``.

    Returns the outcome and the peak in bytes.
    """
    tracemalloc.start()
    try:
        outcome = check(target)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    if peak > limit:
        raise FuzzFailure(f"allocated {peak:,} bytes (limit {limit:,})")
    return outcome, peak
