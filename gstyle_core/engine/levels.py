"""The widths a run works at, coarse to fine: the working width, then the finer levels (``phases/refine.py``).

Torch-free (the command line checks ``--refine-widths`` with it)."""

from __future__ import annotations

from collections.abc import Sequence

MIN_LEVEL_WIDTH = 16
MAX_LEVEL_WIDTH = 4096  # a level's ground truth at 4096 px is ~140 MB a view; beyond it a CPU runs out of time first
MAX_LEVEL_VIEWS = 24  # a level's targets are kept for at most this many views (memory: 1024 px × 24 ≈ 0.3 GB)


def check_refine_widths(widths: Sequence[int], working_width: int | None = None) -> tuple[int, ...]:
    """``widths`` as a tuple of ints, each finer than the one before (and than ``working_width`` when given) and
    within [MIN_LEVEL_WIDTH, MAX_LEVEL_WIDTH]; ``ValueError`` saying why not."""
    out = tuple(int(w) for w in widths)
    for w in out:
        if not MIN_LEVEL_WIDTH <= w <= MAX_LEVEL_WIDTH:
            raise ValueError(f"a level's width must be {MIN_LEVEL_WIDTH} to {MAX_LEVEL_WIDTH} px, got {w}")
    previous = working_width
    for w in out:
        if previous is not None and w <= previous:
            raise ValueError(f"levels go from coarse to fine: {w} px after {previous} px")
        previous = w
    return out


def level_widths(working_width: int, refine_widths: Sequence[int]) -> tuple[int, ...]:
    """Every width a run works at, in order: the working width, then its finer levels."""
    return (int(working_width), *(int(w) for w in refine_widths))


def end_width(settings) -> int:
    """The width a run with these settings ends at: its last level (the working width without finer levels)."""
    return level_widths(settings.working_width, settings.refine_widths)[-1]


def capped_levels(refine_widths: Sequence[int], working_width: int, limit: int | None) -> tuple[int, ...]:
    """``refine_widths`` no wider than ``limit`` (the photos' width: a level fits its ground truth, and photos hold
    no detail finer than their own pixels): a wider level becomes ``limit``, once; levels not finer than the working
    width go. ``limit`` None: unchanged."""
    if limit is None:
        return tuple(int(w) for w in refine_widths)
    out: list[int] = []
    for w in (min(int(w), int(limit)) for w in refine_widths):
        if w > int(working_width) and (not out or w > out[-1]):
            out.append(w)
    return tuple(out)


def next_width(widths: Sequence[int]) -> int:
    """The width of the level after ``widths`` (the last one doubled, at most ``MAX_LEVEL_WIDTH``)."""
    return min(MAX_LEVEL_WIDTH, 2 * int(widths[-1]))
