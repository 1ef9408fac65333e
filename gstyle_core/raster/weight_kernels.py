"""Numba kernels of the blend weights alpha_i * T_i of every pixel x Gaussian pair, as a CSR matrix, and its
transpose: the colour cache's linear map (``colour_cache.py``). The walk is ``blend_kernels.blend_forward``'s.

numba's cache checks each kernel against its own file only: after editing a helper of ``pixel_kernels``, delete
the numba cache (``gstyle cache`` shows where it is), or these kernels keep the old one inlined.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from .pixel_kernels import ONE32, TRANSMITTANCE_MIN, column_span, pair_alpha, row_range, tile_setup


@njit(parallel=True, cache=True)
def _walk_blend_weights(offsets, ids, rec, tile_order, width, height, tile_size, tiles_x, row_ptr,
                        fill, gaussian_ids, vals):  # pragma: no cover - numba
    """The loops of ``blend_forward`` recording the blend weights alpha_i * T_i of every pixel x Gaussian pair.
    ``fill`` False: count them per pixel ([H * W] int64) and keep the final transmittance [H, W]; True: write the
    Gaussian ids and weights into ``gaussian_ids`` and ``vals`` (allocated by the caller, of the index type it
    chose) at the CSR rows that ``row_ptr`` (from the counts) lays out. Returns (counts, t_final); the arrays of
    the other pass are empty."""
    counts = np.zeros(0 if fill else height * width, np.int64)
    t_final = np.ones((0, 0) if fill else (height, width), np.float32)
    for k in prange(tile_order.shape[0]):
        row0, col0, rows, cols, cand, n_cand, coef = tile_setup(offsets, rec, tile_order[k], width, height,
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
            r_first, r_end = row_range(rec, j, row0, rows)
            for lr in range(r_first, r_end):
                py = np.float32(row0 + lr + 0.5)
                if row_active[lr] == 0 or abs(py - rec[j, 1]) > rec[j, 11]:
                    continue
                first, span_end = column_span(rec, j, coef, ci, py, col0, cols)
                for lc in range(first, span_end):
                    p = lr * cols + lc
                    if done[p]:
                        continue
                    alpha, _, _, _ = pair_alpha(rec, j, np.float32(col0 + lc + 0.5), py)
                    if alpha == 0.0:
                        continue
                    tr = trans[p]
                    next_trans = tr * (ONE32 - alpha)
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
    return counts, t_final


def count_blend_weights(offsets, ids, rec, tile_order, width, height, tile_size, tiles_x):
    """Number of Gaussians that contribute to each pixel, [H * W] int64, and the final transmittance [H, W]."""
    return _walk_blend_weights(offsets, ids, rec, tile_order, width, height, tile_size, tiles_x,
                               np.zeros(1, np.int64), False, np.empty(0, np.int64), np.empty(0, np.float32))


def fill_blend_weights(offsets, ids, rec, tile_order, width, height, tile_size, tiles_x, row_ptr,
                       index_dtype=np.int64):
    """CSR columns (Gaussian ids, ``index_dtype``) and values (alpha_i * T_i) of the pixel x Gaussian blend matrix
    whose rows ``row_ptr`` lays out (the prefix sums of ``count_blend_weights``)."""
    gaussian_ids = np.empty(int(row_ptr[-1]), index_dtype)
    vals = np.empty(int(row_ptr[-1]), np.float32)
    _walk_blend_weights(offsets, ids, rec, tile_order, width, height, tile_size, tiles_x, row_ptr, True,
                        gaussian_ids, vals)
    return gaussian_ids, vals


def csr_transpose(row_ptr, cols, vals, n_cols):
    """The transpose of a CSR matrix [R, n_cols] as CSR [n_cols, R] (column indices sorted in each row), its
    indices of ``cols``' type."""
    t_ptr = np.zeros(n_cols + 1, cols.dtype)
    t_cols = np.empty(cols.shape[0], cols.dtype)
    t_vals = np.empty(cols.shape[0], vals.dtype)
    _fill_transpose(row_ptr, cols, vals, n_cols, t_ptr, t_cols, t_vals)
    return t_ptr, t_cols, t_vals


@njit(cache=True)
def _fill_transpose(row_ptr, cols, vals, n_cols, t_ptr, t_cols, t_vals):  # pragma: no cover - numba
    """``csr_transpose``'s loops, into the arrays it allocated."""
    for k in range(cols.shape[0]):
        t_ptr[cols[k] + 1] += 1
    for c in range(n_cols):
        t_ptr[c + 1] += t_ptr[c]
    cursor = t_ptr[:n_cols].copy()
    for r in range(row_ptr.shape[0] - 1):
        for k in range(row_ptr[r], row_ptr[r + 1]):
            c = cols[k]
            t_cols[cursor[c]] = r
            t_vals[cursor[c]] = vals[k]
            cursor[c] += 1
