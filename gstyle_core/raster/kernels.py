"""Numba kernels for the 2D half of the fast backend: binning, alpha blending, its backward, blend weights.

Per-entry record layout (one row per Gaussian-tile pair, float32, contiguous per tile):
``[mean_x, mean_y, conic_a, conic_b, conic_c, opacity, r, g, b, depth, reach_x, reach_y]``; gradients use
the first ten fields. ``reach`` is the half-size of the box outside which the Gaussian's alpha is below
1/255 for sure: each tile first drops the entries whose box misses the tile, then each pixel row those
whose box misses the row. Results are unchanged (the 3DGS tile lists and stats stay as they are); about
half of the pixel-Gaussian evaluations go. Within a pixel row, an entry then visits only the columns of its
``_column_span`` (where alpha can reach 1/255; a conservative bound, so images stay bit-identical): the loops run
entry-major over a row and keep each pixel's state in small arrays (the torch twin: ``reference._blend_tile``).
Each list entry belongs to exactly one tile and each tile to one thread, so per-entry gradient rows are
written without collisions and summed into Gaussians afterwards (``scatter_entry_grads``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

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
_HALF = np.float32(0.5)
_ZERO = np.float32(0.0)
_ONE = np.float32(1.0)
_ALPHA_MIN32 = np.float32(ALPHA_MIN)
_ALPHA_MAX32 = np.float32(ALPHA_MAX)
_POWER_REJECT32 = np.float32(POWER_REJECT)


@njit(cache=True)
def bin_gaussians(order, tile_min, tile_max, tiles_x, n_tiles):  # pragma: no cover - numba
    """Per-tile lists of Gaussian ids in the given (depth) order: (offsets [T+1] int64, ids [P] int32)."""
    n = order.shape[0]
    rects = np.empty((n, 4), np.int32)  # tile rectangles in the given order: both passes then read in sequence
    offsets = np.zeros(n_tiles + 1, np.int64)
    for k in range(n):
        g = order[k]
        x0, y0, x1, y1 = tile_min[g, 0], tile_min[g, 1], tile_max[g, 0], tile_max[g, 1]
        rects[k, 0], rects[k, 1], rects[k, 2], rects[k, 3] = x0, y0, x1, y1
        for ty in range(y0, y1):
            for tx in range(x0, x1):
                offsets[ty * tiles_x + tx + 1] += 1
    for t in range(n_tiles):
        offsets[t + 1] += offsets[t]
    ids = np.empty(offsets[n_tiles], np.int32)
    cursor = offsets[:n_tiles].copy()
    for k in range(n):
        g = np.int32(order[k])
        for ty in range(rects[k, 1], rects[k, 3]):
            for tx in range(rects[k, 0], rects[k, 2]):
                t = ty * tiles_x + tx
                ids[cursor[t]] = g
                cursor[t] += 1
    return offsets, ids


@njit(cache=True)
def depth_order(depths, visible):  # pragma: no cover - numba
    """Ids of the visible Gaussians sorted by depth, ties in id order (as a stable argsort): an LSD radix sort
    of the float32 depths' bit patterns (4 passes of 8 bits), mapped so that integer order is float order."""
    n_vis = 0
    for i in range(visible.shape[0]):
        if visible[i]:
            n_vis += 1
    keys = np.empty(n_vis, np.uint32)
    ids = np.empty(n_vis, np.int64)
    bits = depths.view(np.uint32)
    k = 0
    for i in range(visible.shape[0]):
        if visible[i]:
            b = bits[i]
            keys[k] = b ^ np.uint32(0xFFFFFFFF) if b >> np.uint32(31) else b | np.uint32(0x80000000)
            ids[k] = i
            k += 1
    keys_tmp = np.empty_like(keys)
    ids_tmp = np.empty_like(ids)
    counts = np.empty(257, np.int64)
    for shift in range(0, 32, 8):
        counts[:] = 0
        for k in range(n_vis):
            counts[((keys[k] >> np.uint32(shift)) & np.uint32(0xFF)) + 1] += 1
        if counts[1:].max() == n_vis:  # every key has the same digit: this pass would not move anything
            continue
        for d in range(256):
            counts[d + 1] += counts[d]
        for k in range(n_vis):
            d = (keys[k] >> np.uint32(shift)) & np.uint32(0xFF)
            pos = counts[d]
            keys_tmp[pos] = keys[k]
            ids_tmp[pos] = ids[k]
            counts[d] = pos + 1
        keys, keys_tmp = keys_tmp, keys
        ids, ids_tmp = ids_tmp, ids
    return ids


@njit(parallel=True, cache=True)
def gaussian_records(means2d, conics, opacities, features, visible):  # pragma: no cover - numba
    """Per-Gaussian records [N, RECORD_FIELDS] (the layout of the module docstring) of the visible ones, reach
    boxes as ``reach_boxes`` computes them (rows of culled Gaussians are left unset)."""
    n = means2d.shape[0]
    out = np.empty((n, RECORD_FIELDS), np.float32)
    for i in prange(n):
        if not visible[i]:
            continue
        out[i, 0], out[i, 1] = means2d[i, 0], means2d[i, 1]
        out[i, 2], out[i, 3], out[i, 4] = conics[i, 0], conics[i, 1], conics[i, 2]
        out[i, 5] = opacities[i]
        for f in range(FEATURES):
            out[i, 6 + f] = features[i, f]
        a, b, c = np.float64(conics[i, 0]), np.float64(conics[i, 1]), np.float64(conics[i, 2])
        det = a * c - b * b
        k = 2.0 * math.log(max(255.0 * np.float64(opacities[i]), 1e-30))
        if k < 0:
            out[i, 10], out[i, 11] = -1.0, -1.0
            continue
        for axis in range(2):
            sigma = (c if axis == 0 else a) / det if det > 0 else np.inf
            r = math.sqrt(k * sigma) * 1.01 + 0.05
            if r != r:
                r = np.inf
            out[i, 10 + axis] = min(r, 3e38)
    return out


@njit(parallel=True, cache=True)
def gather_records(ids, per_gaussian):  # pragma: no cover - numba
    """Copy each list entry's Gaussian record into a contiguous [P, RECORD_FIELDS] array."""
    out = np.empty((ids.shape[0], per_gaussian.shape[1]), np.float32)
    for j in prange(ids.shape[0]):
        g = ids[j]
        for f in range(per_gaussian.shape[1]):
            out[j, f] = per_gaussian[g, f]
    return out


@njit(cache=True, inline="always")
def _pair_alpha(rec, j, px, py):  # pragma: no cover - numba
    """(alpha, gaussian value, dx, dy) of entry j at a pixel centre; alpha = 0 when the pair is skipped.

    Callers visit only the pixels of ``_column_span``, inside the reach box (alpha < 1/255 outside, for sure).
    """
    dx = px - rec[j, 0]
    dy = py - rec[j, 1]
    power = -_HALF * (rec[j, 2] * dx * dx + rec[j, 4] * dy * dy) - rec[j, 3] * dx * dy
    if not (power <= _ZERO and power >= _POWER_REJECT32):  # also rejects NaN
        return _ZERO, _ZERO, dx, dy
    gval = math.exp(power)
    alpha = min(_ALPHA_MAX32, rec[j, 5] * gval)
    if alpha < _ALPHA_MIN32:
        return _ZERO, gval, dx, dy
    return alpha, gval, dx, dy


@njit(cache=True)
def _tile_candidates(rec, start, end, row0, col0, rows, cols, out):  # pragma: no cover - numba
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
def _span_coefficients(rec, cand, n_cand, row0, rows, out):  # pragma: no cover - numba
    """Per tile candidate, the row-independent numbers of ``_column_span`` (see there): out[ci] =
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
def _column_span(rec, j, coef, ci, py, col0, cols):  # pragma: no cover - numba
    """Tile-local columns [first, end) where entry j (tile candidate ci) can reach alpha >= 1/255 on the pixel
    row at py.

    Conservative: outside the span the exact float32 test in ``_pair_alpha`` rejects the pair for sure, so
    skipping those pixels changes no result (inside, that test still decides). alpha >= 1/255 needs
    power >= thr := max(POWER_REJECT, ln(1 / (255 opacity))): on a row, 0.5 a dx^2 + b dy dx + 0.5 c dy^2 + thr
    <= 0, whose roots dx = -(b/a) dy +- sqrt((b^2 - a c) dy^2 - 2 a thr) / a bound the span (float64, with thr
    lowered by a bound on the float32 rounding of power, exp and the product with opacity;
    ``_span_coefficients``). The reach box bounds it too.
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
def _tile_setup(offsets, rec, t, width, height, tile_size, tiles_x):  # pragma: no cover - numba
    """Tile ``t``'s pixel rectangle and the entries of its list that can reach it (depth order), with their column
    span coefficients: (row0, col0, rows, cols, cand, n_cand, coef), as the forward, count and fill passes walk it."""
    start, end = offsets[t], offsets[t + 1]
    row0, col0 = (t // tiles_x) * tile_size, (t % tiles_x) * tile_size
    rows, cols = min(tile_size, height - row0), min(tile_size, width - col0)
    cand = np.empty(end - start, np.int64)
    n_cand = _tile_candidates(rec, start, end, row0, col0, rows, cols, cand)
    coef = np.empty((n_cand, 4), np.float64)
    _span_coefficients(rec, cand, n_cand, row0, rows, coef)
    return row0, col0, rows, cols, cand, n_cand, coef


@njit(cache=True, inline="always")
def _row_range(rec, j, row0, rows):  # pragma: no cover - numba
    """Tile-local rows [first, end), a superset of those whose pixel centres lie in entry j's reach (the loops
    test each row exactly)."""
    my, ry = np.float64(rec[j, 1]), np.float64(rec[j, 11])
    lo, hi = my - ry - 0.5 - row0, my + ry - 0.5 - row0
    if not (lo <= hi):  # NaN: every row
        return 0, rows
    lo = min(max(lo, -1.0), np.float64(rows))  # clamped first: numba's floor/ceil give int64
    hi = min(max(hi, -1.0), np.float64(rows))
    return max(0, math.floor(lo)), min(rows, math.ceil(hi) + 1)


@njit(parallel=True, cache=True)
def blend_forward(offsets, rec, tile_order, width, height, tile_size, tiles_x, spans):  # pragma: no cover
    """Front-to-back blending: features [H, W, 4] (no background), final transmittance, last entry + 1.

    Per pixel the same arithmetic, in the same order, as the per-pixel loop of the torch twin
    (``reference._blend_tile``); the loops run entry-major over a tile (the tile's pixel state in small arrays) so
    that each entry visits only the rows of its reach and, in each, the pixels of its ``_column_span``.
    ``spans`` [P, tile_size, 2] (a small integer type) receives each visited entry's column span per tile row,
    (0, 0) where the row misses its reach, for ``blend_backward`` to reuse; rows an entry does not visit (outside
    ``_row_range``, or every pixel of the row stopped before the entry) are left unset: the backward never reads
    them (it skips entries past the row's last contributor).
    """
    feats = np.zeros((height, width, FEATURES), np.float32)
    t_final = np.ones((height, width), np.float32)
    last = np.zeros((height, width), np.int64)
    for k in prange(tile_order.shape[0]):
        row0, col0, rows, cols, cand, n_cand, coef = _tile_setup(offsets, rec, tile_order[k], width, height,
                                                                 tile_size, tiles_x)
        n_pix = rows * cols
        trans = np.ones(n_pix, np.float32)
        acc = np.zeros((n_pix, FEATURES), np.float32)
        stop = np.full(n_pix, offsets[tile_order[k]], np.int64)  # no contributor: the list's start
        done = np.zeros(n_pix, np.bool_)
        row_active = np.full(rows, cols, np.int64)
        active = n_pix
        for ci in range(n_cand):
            j = cand[ci]
            r_first, r_end = _row_range(rec, j, row0, rows)
            for lr in range(r_first, r_end):
                if row_active[lr] == 0:
                    continue
                py = np.float32(row0 + lr + 0.5)
                if abs(py - rec[j, 1]) > rec[j, 11]:
                    spans[j, lr, 0] = 0
                    spans[j, lr, 1] = 0
                    continue
                first, span_end = _column_span(rec, j, coef, ci, py, col0, cols)
                spans[j, lr, 0] = first
                spans[j, lr, 1] = span_end
                base = lr * cols
                for lc in range(first, span_end):
                    p = base + lc
                    if done[p]:
                        continue
                    alpha, _, _, _ = _pair_alpha(rec, j, np.float32(col0 + lc + 0.5), py)
                    if alpha == 0.0:
                        continue
                    tr = trans[p]
                    next_trans = tr * (_ONE - alpha)
                    if next_trans < TRANSMITTANCE_MIN:
                        done[p] = True
                        row_active[lr] -= 1
                        active -= 1
                        continue
                    w = alpha * tr
                    acc[p, 0] += rec[j, 6] * w
                    acc[p, 1] += rec[j, 7] * w
                    acc[p, 2] += rec[j, 8] * w
                    acc[p, 3] += rec[j, 9] * w
                    trans[p] = next_trans
                    stop[p] = j + 1
            if active == 0:
                break
        for lr in range(rows):
            for lc in range(cols):
                p = lr * cols + lc
                row, col = row0 + lr, col0 + lc
                for f in range(FEATURES):
                    feats[row, col, f] = acc[p, f]
                t_final[row, col] = trans[p]
                last[row, col] = stop[p]
    return feats, t_final, last


@njit(parallel=True, cache=True)
def blend_backward(
    offsets, rec, tile_order, width, height, tile_size, tiles_x, t_final, last, spans, grad_feats, grad_t_final
):  # pragma: no cover - numba
    """Back-to-front gradient of blend_forward; returns per-entry gradients [P, GRAD_FIELDS].

    Entry-major over each tile like ``blend_forward``, with its rows and column ``spans``: an entry's gradient is
    summed over the tile's pixels in registers, then written to its row of the result once.
    """
    grads = np.zeros((rec.shape[0], GRAD_FIELDS), np.float32)
    for k in prange(tile_order.shape[0]):
        t = tile_order[k]
        start, end = offsets[t], offsets[t + 1]
        row0, col0 = (t // tiles_x) * tile_size, (t % tiles_x) * tile_size
        rows, cols = min(tile_size, height - row0), min(tile_size, width - col0)
        cand = np.empty(end - start, np.int64)
        n_cand = _tile_candidates(rec, start, end, row0, col0, rows, cols, cand)
        n_pix = rows * cols
        trans = np.empty(n_pix, np.float32)
        behind = np.zeros((n_pix, FEATURES), np.float32)  # colour blended behind the current entry
        g = np.empty((n_pix, FEATURES), np.float32)
        g_bg = np.empty(n_pix, np.float32)
        stop = np.empty(n_pix, np.int64)
        row_stop = np.full(rows, start, np.int64)  # the last contributor + 1 over each row
        tile_stop = start
        for lr in range(rows):
            for lc in range(cols):
                p, row, col = lr * cols + lc, row0 + lr, col0 + lc
                tf = t_final[row, col]
                trans[p] = tf
                for f in range(FEATURES):
                    g[p, f] = grad_feats[row, col, f]
                g_bg[p] = grad_t_final[row, col] * tf
                stop[p] = last[row, col]
                row_stop[lr] = max(row_stop[lr], stop[p])
            tile_stop = max(tile_stop, row_stop[lr])
        for ci in range(n_cand - 1, -1, -1):
            j = cand[ci]
            if j >= tile_stop:
                continue
            c0, c1, c2, c3 = rec[j, 6], rec[j, 7], rec[j, 8], rec[j, 9]
            a, b, c = rec[j, 2], rec[j, 3], rec[j, 4]
            d_c0 = d_c1 = d_c2 = d_c3 = _ZERO
            d_op = d_mx = d_my = d_a = d_b = d_c = _ZERO
            r_first, r_end = _row_range(rec, j, row0, rows)
            for lr in range(r_first, r_end):
                if j >= row_stop[lr]:
                    continue
                first, span_end = np.int64(spans[j, lr, 0]), np.int64(spans[j, lr, 1])
                py = np.float32(row0 + lr + 0.5)
                base = lr * cols
                for lc in range(first, span_end):
                    p = base + lc
                    if j >= stop[p]:
                        continue
                    alpha, gval, dx, dy = _pair_alpha(rec, j, np.float32(col0 + lc + 0.5), py)
                    if alpha == 0.0:
                        continue
                    one_minus = 1.0 - alpha
                    inv_one_minus = _ONE / one_minus
                    tr = trans[p] * inv_one_minus
                    trans[p] = tr
                    w = alpha * tr
                    g0, g1, g2, g3 = g[p, 0], g[p, 1], g[p, 2], g[p, 3]
                    d_c0 += g0 * w
                    d_c1 += g1 * w
                    d_c2 += g2 * w
                    d_c3 += g3 * w
                    s0, s1, s2, s3 = behind[p, 0], behind[p, 1], behind[p, 2], behind[p, 3]
                    d_alpha = tr * (g0 * (c0 - s0) + g1 * (c1 - s1) + g2 * (c2 - s2) + g3 * (c3 - s3))
                    d_alpha -= g_bg[p] * inv_one_minus
                    behind[p, 0] = alpha * c0 + one_minus * s0
                    behind[p, 1] = alpha * c1 + one_minus * s1
                    behind[p, 2] = alpha * c2 + one_minus * s2
                    behind[p, 3] = alpha * c3 + one_minus * s3
                    if rec[j, 5] * gval <= ALPHA_MAX:  # alpha not clamped: it depends on opacity and power
                        d_op += gval * d_alpha
                        d_power = alpha * d_alpha
                        d_mx += d_power * (a * dx + b * dy)
                        d_my += d_power * (b * dx + c * dy)
                        d_a += -0.5 * d_power * dx * dx
                        d_b += -d_power * dx * dy
                        d_c += -0.5 * d_power * dy * dy
            grads[j, 0] = d_mx
            grads[j, 1] = d_my
            grads[j, 2] = d_a
            grads[j, 3] = d_b
            grads[j, 4] = d_c
            grads[j, 5] = d_op
            grads[j, 6] = d_c0
            grads[j, 7] = d_c1
            grads[j, 8] = d_c2
            grads[j, 9] = d_c3
    return grads


@njit(parallel=True, cache=True)
def scatter_entry_grads(ids, entry_grads, n_gaussians):  # pragma: no cover - numba
    """Sum per-entry gradient rows into per-Gaussian rows [N, GRAD_FIELDS] (float64 accumulation, entries in
    order); parallel over the fields, so threads never write the same cell."""
    out = np.zeros((n_gaussians, entry_grads.shape[1]), np.float64)
    for f in prange(entry_grads.shape[1]):
        for j in range(ids.shape[0]):
            out[ids[j], f] += entry_grads[j, f]
    return out


@njit(parallel=True, cache=True)
def _walk_blend_weights(offsets, ids, rec, tile_order, width, height, tile_size, tiles_x, row_ptr,
                        fill):  # pragma: no cover - numba
    """The loops of ``blend_forward`` recording the blend weights alpha_i * T_i of every pixel x Gaussian pair.
    ``fill`` False: count them per pixel ([H * W] int64) and keep the final transmittance [H, W]; True: write the
    Gaussian ids and weights into the CSR rows that ``row_ptr`` (from the counts) lays out. Returns (counts,
    t_final, ids, weights); the arrays of the other pass are empty."""
    counts = np.zeros(0 if fill else height * width, np.int64)
    t_final = np.ones((0, 0) if fill else (height, width), np.float32)
    gaussian_ids = np.empty(row_ptr[-1] if fill else 0, np.int64)
    vals = np.empty(row_ptr[-1] if fill else 0, np.float32)
    for k in prange(tile_order.shape[0]):
        row0, col0, rows, cols, cand, n_cand, coef = _tile_setup(offsets, rec, tile_order[k], width, height,
                                                                 tile_size, tiles_x)
        n_pix = rows * cols
        trans = np.ones(n_pix, np.float32)
        done = np.zeros(n_pix, np.bool_)
        pos = np.zeros(n_pix, np.int64)  # fill: the next free slot of each pixel's CSR row
        if fill:
            for lr in range(rows):
                for lc in range(cols):
                    pos[lr * cols + lc] = row_ptr[(row0 + lr) * width + col0 + lc]
        row_active = np.full(rows, cols, np.int64)
        active = n_pix
        for ci in range(n_cand):
            j = cand[ci]
            r_first, r_end = _row_range(rec, j, row0, rows)
            for lr in range(r_first, r_end):
                py = np.float32(row0 + lr + 0.5)
                if row_active[lr] == 0 or abs(py - rec[j, 1]) > rec[j, 11]:
                    continue
                first, span_end = _column_span(rec, j, coef, ci, py, col0, cols)
                for lc in range(first, span_end):
                    p = lr * cols + lc
                    if done[p]:
                        continue
                    alpha, _, _, _ = _pair_alpha(rec, j, np.float32(col0 + lc + 0.5), py)
                    if alpha == 0.0:
                        continue
                    tr = trans[p]
                    next_trans = tr * (_ONE - alpha)
                    if next_trans < TRANSMITTANCE_MIN:
                        done[p] = True
                        row_active[lr] -= 1
                        active -= 1
                        continue
                    if fill:
                        gaussian_ids[pos[p]] = ids[j]
                        vals[pos[p]] = alpha * tr
                        pos[p] += 1
                    else:
                        counts[(row0 + lr) * width + col0 + lc] += 1
                    trans[p] = next_trans
            if active == 0:
                break
        if not fill:
            for lr in range(rows):
                for lc in range(cols):
                    t_final[row0 + lr, col0 + lc] = trans[lr * cols + lc]
    return counts, t_final, gaussian_ids, vals


def count_blend_weights(offsets, ids, rec, tile_order, width, height, tile_size, tiles_x):
    """Number of Gaussians that contribute to each pixel, [H * W] int64, and the final transmittance [H, W]."""
    counts, t_final, _, _ = _walk_blend_weights(offsets, ids, rec, tile_order, width, height, tile_size, tiles_x,
                                                np.zeros(1, np.int64), False)
    return counts, t_final


def fill_blend_weights(offsets, ids, rec, tile_order, width, height, tile_size, tiles_x, row_ptr):
    """CSR columns (Gaussian ids) and values (alpha_i * T_i) of the pixel x Gaussian blend matrix whose rows
    ``row_ptr`` lays out (the prefix sums of ``count_blend_weights``)."""
    _, _, gaussian_ids, vals = _walk_blend_weights(offsets, ids, rec, tile_order, width, height, tile_size, tiles_x,
                                                   row_ptr, True)
    return gaussian_ids, vals


@njit(cache=True)
def csr_transpose(row_ptr, cols, vals, n_cols):  # pragma: no cover - numba
    """The transpose of a CSR matrix [R, n_cols] as CSR [n_cols, R] (column indices sorted in each row)."""
    t_ptr = np.zeros(n_cols + 1, np.int64)
    for k in range(cols.shape[0]):
        t_ptr[cols[k] + 1] += 1
    for c in range(n_cols):
        t_ptr[c + 1] += t_ptr[c]
    cursor = t_ptr[:n_cols].copy()
    t_cols = np.empty(cols.shape[0], np.int64)
    t_vals = np.empty(cols.shape[0], vals.dtype)
    for r in range(row_ptr.shape[0] - 1):
        for k in range(row_ptr[r], row_ptr[r + 1]):
            c = cols[k]
            t_cols[cursor[c]] = r
            t_vals[cursor[c]] = vals[k]
            cursor[c] += 1
    return t_ptr, t_cols, t_vals


def balanced_tile_order(offsets: np.ndarray, n_threads: int) -> np.ndarray:
    """Tile visiting order that spreads costly tiles over numba's static per-thread chunks."""
    n_tiles = offsets.shape[0] - 1
    cost = np.diff(offsets)
    by_cost = np.argsort(-cost, kind="stable")
    n_threads = max(1, min(n_threads, n_tiles))
    # Deal tiles round-robin into n_threads contiguous blocks (block i = chunk of thread i).
    blocks = [by_cost[i::n_threads] for i in range(n_threads)]
    return np.concatenate(blocks).astype(np.int64) if n_tiles else np.zeros(0, np.int64)


def reach_boxes(conics: np.ndarray, opacities: np.ndarray) -> np.ndarray:
    """Half-sizes [N, 2] of the boxes outside which opacity * exp(power) < 1/255 (negative: never visible).

    alpha >= 1/255 needs d^T conic d <= 2 ln(255 opacity) =: k, which bounds |dx| by sqrt(k * Sigma_xx) and
    |dy| by sqrt(k * Sigma_yy), Sigma = conic^-1. A small margin keeps the bound conservative in float32.
    """
    a, b, c = (conics[:, i].astype(np.float64) for i in range(3))
    det = a * c - b * b
    with np.errstate(divide="ignore", invalid="ignore"):
        k = 2.0 * np.log(np.maximum(255.0 * opacities.astype(np.float64), 1e-30))
        sigma_xx = np.where(det > 0, c / det, np.inf)
        sigma_yy = np.where(det > 0, a / det, np.inf)
        reach = np.stack([np.sqrt(np.maximum(k, 0) * sigma_xx), np.sqrt(np.maximum(k, 0) * sigma_yy)], 1)
    reach = np.nan_to_num(reach * 1.01 + 0.05, nan=np.inf, posinf=np.float32(3e38))
    reach[k < 0] = -1.0
    return reach.astype(np.float32)
