"""Numba kernels of the alpha blending, front to back, and of its gradient, back to front.

The loops run entry-major over each tile and keep each pixel's state in small arrays (the torch twin:
``reference._blend_tile``). Each list entry belongs to exactly one tile and each tile to one thread, so per-entry
gradient rows are written without collisions and summed into Gaussians afterwards (``scatter_entry_grads``).

numba's cache checks each kernel against its own file only: after editing a helper of ``pixel_kernels``, delete
the numba cache (``gstyle cache`` shows where it is), or these kernels keep the old one inlined.
"""

from __future__ import annotations

import numpy as np
from numba import get_num_threads, njit, prange

from .pixel_kernels import (
    ALPHA_MAX,
    FEATURES,
    GRAD_FIELDS,
    ONE32,
    TRANSMITTANCE_MIN,
    ZERO32,
    column_span,
    pair_alpha,
    row_range,
    tile_candidates,
    tile_setup,
)


@njit(cache=True, inline="always")
def _blend_row_span(rec, j, py, col0, base, first, span_end, trans, acc, stop, done):  # pragma: no cover - numba
    """Entry ``j`` blended into the pixels ``base + first .. base + span_end`` of a tile row, front to back (the
    pixel state ``trans``, ``acc``, ``stop`` and ``done`` updated in place); returns how many pixels it stopped."""
    stopped = 0
    for lc in range(first, span_end):
        p = base + lc
        if done[p]:
            continue
        alpha, _, _, _ = pair_alpha(rec, j, np.float32(col0 + lc + 0.5), py)
        if alpha == 0.0:
            continue
        tr = trans[p]
        next_trans = tr * (ONE32 - alpha)
        if next_trans < TRANSMITTANCE_MIN:
            done[p] = True
            stopped += 1
            continue
        w = alpha * tr
        acc[p, 0] += rec[j, 6] * w
        acc[p, 1] += rec[j, 7] * w
        acc[p, 2] += rec[j, 8] * w
        acc[p, 3] += rec[j, 9] * w
        trans[p] = next_trans
        stop[p] = j + 1
    return stopped


@njit(cache=True)
def _store_tile(feats, t_final, last, acc, trans, stop, row0, col0, rows, cols):  # pragma: no cover - numba
    """A tile's pixel state written into the image-sized results."""
    for lr in range(rows):
        for lc in range(cols):
            p = lr * cols + lc
            row, col = row0 + lr, col0 + lc
            for f in range(FEATURES):
                feats[row, col, f] = acc[p, f]
            t_final[row, col] = trans[p]
            last[row, col] = stop[p]


@njit(cache=True)
def _load_tile(t_final, last, grad_feats, grad_t_final, row0, col0, rows, cols, start, trans, g, g_bg,
               stop):  # pragma: no cover - numba
    """A tile's backward state from the image-sized inputs (``trans``, ``g``, ``g_bg``, ``stop`` filled in place);
    returns each row's last contributor + 1 and the tile's."""
    row_stop = np.full(rows, start, np.int64)
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
    return row_stop, tile_stop


@njit(parallel=True, cache=True)
def blend_forward(offsets, rec, tile_order, width, height, tile_size, tiles_x, spans):  # pragma: no cover
    """Front-to-back blending: features [H, W, 4] (no background), final transmittance, last entry + 1.

    Per pixel the same arithmetic, in the same order, as the per-pixel loop of the torch twin
    (``reference._blend_tile``); the loops run entry-major over a tile (the tile's pixel state in small arrays) so
    that each entry visits only the rows of its reach and, in each, the pixels of its ``column_span``.
    ``spans`` [P, tile_size, 2] (a small integer type) receives each visited entry's column span per tile row,
    (0, 0) where the row misses its reach, for ``blend_backward`` to reuse; rows an entry does not visit (outside
    ``row_range``, or every pixel of the row stopped before the entry) are left unset: the backward never reads
    them (it skips entries past the row's last contributor).
    """
    feats = np.zeros((height, width, FEATURES), np.float32)
    t_final = np.ones((height, width), np.float32)
    last = np.zeros((height, width), np.int64)
    for k in prange(tile_order.shape[0]):
        row0, col0, rows, cols, cand, n_cand, coef = tile_setup(offsets, rec, tile_order[k], width, height,
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
            r_first, r_end = row_range(rec, j, row0, rows)
            for lr in range(r_first, r_end):
                if row_active[lr] == 0:
                    continue
                py = np.float32(row0 + lr + 0.5)
                if abs(py - rec[j, 1]) > rec[j, 11]:
                    spans[j, lr, 0] = 0
                    spans[j, lr, 1] = 0
                    continue
                first, span_end = column_span(rec, j, coef, ci, py, col0, cols)
                spans[j, lr, 0] = first
                spans[j, lr, 1] = span_end
                stopped = _blend_row_span(rec, j, py, col0, lr * cols, first, span_end, trans, acc, stop, done)
                row_active[lr] -= stopped
                active -= stopped
            if active == 0:
                break
        _store_tile(feats, t_final, last, acc, trans, stop, row0, col0, rows, cols)
    return feats, t_final, last


@njit(cache=True, inline="always")
def _unblend_row_span(rec, j, py, col0, base, first, span_end, stop, trans, g, g_bg, behind, d_c0, d_c1, d_c2, d_c3,
                      d_op, d_mx, d_my, d_a, d_b, d_c):  # pragma: no cover - numba
    """Entry ``j`` taken back out of the pixels ``base + first .. base + span_end`` of a tile row, back to front
    (``trans`` and ``behind`` updated in place), its gradient sums carried on: returns them (colours, opacity, 2D
    mean, conic) after these pixels, summed in the order the whole tile's loop sums them."""
    c0, c1, c2, c3 = rec[j, 6], rec[j, 7], rec[j, 8], rec[j, 9]
    a, b, c = rec[j, 2], rec[j, 3], rec[j, 4]
    for lc in range(first, span_end):
        p = base + lc
        if j >= stop[p]:
            continue
        alpha, gval, dx, dy = pair_alpha(rec, j, np.float32(col0 + lc + 0.5), py)
        if alpha == 0.0:
            continue
        one_minus = 1.0 - alpha
        inv_one_minus = ONE32 / one_minus
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
    return d_c0, d_c1, d_c2, d_c3, d_op, d_mx, d_my, d_a, d_b, d_c


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
        n_cand = tile_candidates(rec, start, end, row0, col0, rows, cols, cand)
        n_pix = rows * cols
        trans = np.empty(n_pix, np.float32)
        behind = np.zeros((n_pix, FEATURES), np.float32)  # colour blended behind the current entry
        g = np.empty((n_pix, FEATURES), np.float32)
        g_bg = np.empty(n_pix, np.float32)
        stop = np.empty(n_pix, np.int64)
        row_stop, tile_stop = _load_tile(t_final, last, grad_feats, grad_t_final, row0, col0, rows, cols, start,
                                         trans, g, g_bg, stop)
        for ci in range(n_cand - 1, -1, -1):
            j = cand[ci]
            if j >= tile_stop:
                continue
            d_c0 = d_c1 = d_c2 = d_c3 = ZERO32
            d_op = d_mx = d_my = d_a = d_b = d_c = ZERO32
            r_first, r_end = row_range(rec, j, row0, rows)
            for lr in range(r_first, r_end):
                if j >= row_stop[lr]:
                    continue
                first, span_end = np.int64(spans[j, lr, 0]), np.int64(spans[j, lr, 1])
                d_c0, d_c1, d_c2, d_c3, d_op, d_mx, d_my, d_a, d_b, d_c = _unblend_row_span(
                    rec, j, np.float32(row0 + lr + 0.5), col0, lr * cols, first, span_end, stop, trans, g, g_bg,
                    behind, d_c0, d_c1, d_c2, d_c3, d_op, d_mx, d_my, d_a, d_b, d_c)
            grads[j, 0], grads[j, 1], grads[j, 2], grads[j, 3], grads[j, 4] = d_mx, d_my, d_a, d_b, d_c
            grads[j, 5], grads[j, 6], grads[j, 7], grads[j, 8], grads[j, 9] = d_op, d_c0, d_c1, d_c2, d_c3
    return grads


def scatter_entry_grads(ids, entry_grads, n_gaussians):
    """Sum per-entry gradient rows into per-Gaussian rows [N, GRAD_FIELDS] (float64 accumulation, each Gaussian's
    entries in list order, so the sums do not depend on the thread count). Each thread owns a contiguous block of
    Gaussians and writes whole rows of it: with millions of Gaussians the writes land in few cache lines (a pass
    per field over the whole output, as before, took 196 ms of a refit step at 1.37 M Gaussians, this 64 ms:
    ``docs/notes/captures.md``)."""
    return _scatter_rows(ids, entry_grads, n_gaussians, max(1, min(get_num_threads(), n_gaussians)))


@njit(parallel=True, cache=True)
def _scatter_rows(ids, entry_grads, n_gaussians, n_parts):  # pragma: no cover - numba
    """``scatter_entry_grads``'s loops: ``n_parts`` contiguous blocks of Gaussians, one per thread."""
    n_fields = entry_grads.shape[1]
    out = np.zeros((n_gaussians, n_fields), np.float64)
    for part in prange(n_parts):
        lo = part * n_gaussians // n_parts
        hi = (part + 1) * n_gaussians // n_parts
        for j in range(ids.shape[0]):
            g = ids[j]
            if g < lo or g >= hi:
                continue
            for f in range(n_fields):
                out[g, f] += entry_grads[j, f]
    return out
