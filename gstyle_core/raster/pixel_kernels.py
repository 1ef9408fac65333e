"""The per-pixel arithmetic the blending kernels share: record layout, constants and the tile / row / column bounds.

Per-entry record layout (one row per Gaussian-tile pair, float32, contiguous per tile):
``[mean_x, mean_y, conic_a, conic_b, conic_c, opacity, r, g, b, depth, reach_x, reach_y]``; gradients use
the first ten fields. ``reach`` is the half-size of the box outside which the Gaussian's alpha is below
1/255 for sure: each tile first drops the entries whose box misses the tile (``tile_candidates``), then each pixel
row those whose box misses the row (``row_range``). Results are unchanged (the 3DGS tile lists and stats stay as
they are); about half of the pixel-Gaussian evaluations go. Within a pixel row, an entry then visits only the
columns of its ``column_span`` (where alpha can reach 1/255; a conservative bound, so images stay bit-identical).

numba's cache checks each kernel against its own file only: after editing a helper here, delete the numba
cache (``gstyle cache`` shows where it is), or the kernels of the other modules keep the old one inlined.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

RECORD_FIELDS = 12
GRAD_FIELDS = 10
FEATURES = 4  # r, g, b, depth
ALPHA_MIN = 1.0 / 255.0
ALPHA_MAX = 0.99
TRANSMITTANCE_MIN = 1e-4
# Reject a pixel-Gaussian pair before exp() when exp(power) < 1/255 for sure (opacity <= 1); the
# margin keeps the rejection conservative, the exact test on alpha follows.
POWER_REJECT = math.log(ALPHA_MIN) - 1e-3
# float32 twins for the kernels' hot loops (a Python float would promote the arithmetic to float64)
HALF32 = np.float32(0.5)
ZERO32 = np.float32(0.0)
ONE32 = np.float32(1.0)
ALPHA_MIN32 = np.float32(ALPHA_MIN)
ALPHA_MAX32 = np.float32(ALPHA_MAX)
POWER_REJECT32 = np.float32(POWER_REJECT)


@njit(cache=True, inline="always")
def pair_alpha(rec, j, px, py):  # pragma: no cover - numba
    """(alpha, gaussian value, dx, dy) of entry j at a pixel centre; alpha = 0 when the pair is skipped.

    Callers visit only the pixels of ``column_span``, inside the reach box (alpha < 1/255 outside, for sure).
    """
    dx = px - rec[j, 0]
    dy = py - rec[j, 1]
    power = -HALF32 * (rec[j, 2] * dx * dx + rec[j, 4] * dy * dy) - rec[j, 3] * dx * dy
    if not (power <= ZERO32 and power >= POWER_REJECT32):  # also rejects NaN
        return ZERO32, ZERO32, dx, dy
    gval = math.exp(power)
    alpha = min(ALPHA_MAX32, rec[j, 5] * gval)
    if alpha < ALPHA_MIN32:
        return ZERO32, gval, dx, dy
    return alpha, gval, dx, dy


@njit(cache=True)
def tile_candidates(rec, start, end, row0, col0, rows, cols, out):  # pragma: no cover - numba
    """Write into out the entries of [start, end) whose reach box meets the tile's pixel centres; count."""
    x_lo, x_hi = np.float32(col0 + 0.5), np.float32(col0 + cols - 0.5)
    y_lo, y_hi = np.float32(row0 + 0.5), np.float32(row0 + rows - 0.5)
    n = 0
    for j in range(start, end):
        mx, my, rx, ry = rec[j, 0], rec[j, 1], rec[j, 10], rec[j, 11]
        if rx >= 0 and mx + rx >= x_lo and mx - rx <= x_hi and my + ry >= y_lo and my - ry <= y_hi:
            out[n] = j
            n += 1
    return n


@njit(cache=True)
def span_coefficients(rec, cand, n_cand, row0, rows, out):  # pragma: no cover - numba
    """Per tile candidate, the row-independent numbers of ``column_span`` (see there): out[ci] =
    (b / a, 1 / a, b^2 - a c, -2 a thr); out[ci, 1] = NaN where there is no bound (a <= 0, opacity <= 0, or an
    unbounded reach)."""
    for ci in range(n_cand):
        j = cand[ci]
        a, b, c = np.float64(rec[j, 2]), np.float64(rec[j, 3]), np.float64(rec[j, 4])
        opac, rx = np.float64(rec[j, 5]), np.float64(rec[j, 10])
        if not (a > 0.0 and opac > 0.0 and rx < 1e30 and abs(b) < 1e30 and abs(c) < 1e30):
            out[ci, 1] = np.nan
            continue
        # the largest |dy| over the tile's pixel centres bounds the float32 rounding slack for every row
        my = np.float64(rec[j, 1])
        dy_max = max(abs(row0 + 0.5 - my), abs(row0 + rows - 0.5 - my))
        thr = max(POWER_REJECT, math.log(ALPHA_MIN / opac))
        thr -= 1e-6 * (0.5 * a * rx * rx + 0.5 * abs(c) * dy_max * dy_max + abs(b) * rx * dy_max) + 1e-5
        out[ci, 0] = b / a
        out[ci, 1] = 1.0 / a
        out[ci, 2] = b * b - a * c
        out[ci, 3] = -2.0 * a * thr


@njit(cache=True, inline="always")
def column_span(rec, j, coef, ci, py, col0, cols):  # pragma: no cover - numba
    """Tile-local columns [first, end) where entry j (tile candidate ci) can reach alpha >= 1/255 on the pixel
    row at py.

    Conservative: outside the span the exact float32 test in ``pair_alpha`` rejects the pair for sure, so
    skipping those pixels changes no result (inside, that test still decides). alpha >= 1/255 needs
    power >= thr := max(POWER_REJECT, ln(1 / (255 opacity))): on a row, 0.5 a dx^2 + b dy dx + 0.5 c dy^2 + thr
    <= 0, whose roots dx = -(b/a) dy +- sqrt((b^2 - a c) dy^2 - 2 a thr) / a bound the span (float64, with thr
    lowered by a bound on the float32 rounding of power, exp and the product with opacity;
    ``span_coefficients``). The reach box bounds it too.
    """
    mx, rx = np.float64(rec[j, 0]), np.float64(rec[j, 10])
    lo, hi = mx - rx, mx + rx
    inv_a = coef[ci, 1]
    if inv_a == inv_a:  # not NaN: a bound exists
        dy = np.float64(py) - np.float64(rec[j, 1])
        disc = coef[ci, 2] * dy * dy + coef[ci, 3]
        if disc < 0.0:
            return 0, 0
        half = math.sqrt(disc) * inv_a
        centre = mx - coef[ci, 0] * dy
        lo, hi = max(lo, centre - half), min(hi, centre + half)
    if not (lo <= hi):  # also NaN: fall back to the whole tile row (the exact test decides)
        if lo > hi:
            return 0, 0
        return 0, cols
    # clamp to the tile first: math.ceil/floor give int64 in numba, which huge values overflow
    lo = max(lo - 0.5 - col0, -1.0)
    hi = min(hi - 0.5 - col0, np.float64(cols))
    if hi < lo:
        return 0, 0
    first = max(0, math.ceil(lo))
    end = min(cols, math.floor(hi) + 1)
    if end <= first:
        return 0, 0
    return first, end


@njit(cache=True)
def tile_setup(offsets, rec, t, width, height, tile_size, tiles_x):  # pragma: no cover - numba
    """Tile ``t``'s pixel rectangle and the entries of its list that can reach it (depth order), with their column
    span coefficients: (row0, col0, rows, cols, cand, n_cand, coef), as the forward, count and fill passes walk it."""
    start, end = offsets[t], offsets[t + 1]
    row0, col0 = (t // tiles_x) * tile_size, (t % tiles_x) * tile_size
    rows, cols = min(tile_size, height - row0), min(tile_size, width - col0)
    cand = np.empty(end - start, np.int64)
    n_cand = tile_candidates(rec, start, end, row0, col0, rows, cols, cand)
    coef = np.empty((n_cand, 4), np.float64)
    span_coefficients(rec, cand, n_cand, row0, rows, coef)
    return row0, col0, rows, cols, cand, n_cand, coef


@njit(cache=True, inline="always")
def row_range(rec, j, row0, rows):  # pragma: no cover - numba
    """Tile-local rows [first, end), a superset of those whose pixel centres lie in entry j's reach (the loops
    test each row exactly)."""
    my, ry = np.float64(rec[j, 1]), np.float64(rec[j, 11])
    lo, hi = my - ry - 0.5 - row0, my + ry - 0.5 - row0
    if not (lo <= hi):  # NaN: every row
        return 0, rows
    lo = min(max(lo, -1.0), np.float64(rows))  # clamped first: numba's floor/ceil give int64
    hi = min(max(hi, -1.0), np.float64(rows))
    return max(0, math.floor(lo)), min(rows, math.ceil(hi) + 1)
