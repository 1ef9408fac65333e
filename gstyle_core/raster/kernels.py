"""Numba kernels for the 2D half of the fast backend: binning, alpha blending, its backward, blend weights.

Per-entry record layout (one row per Gaussian-tile pair, float32, contiguous per tile):
``[mean_x, mean_y, conic_a, conic_b, conic_c, opacity, r, g, b, depth, reach_x, reach_y]``; gradients use
the first ten fields. ``reach`` is the half-size of the box outside which the Gaussian's alpha is below
1/255 for sure: each tile first drops the entries whose box misses the tile, then each pixel row those
whose box misses the row. Results are unchanged (the 3DGS tile lists and stats stay as they are); about
half of the pixel-Gaussian evaluations go.
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
    offsets = np.zeros(n_tiles + 1, np.int64)
    for k in range(order.shape[0]):
        g = order[k]
        for ty in range(tile_min[g, 1], tile_max[g, 1]):
            for tx in range(tile_min[g, 0], tile_max[g, 0]):
                offsets[ty * tiles_x + tx + 1] += 1
    for t in range(n_tiles):
        offsets[t + 1] += offsets[t]
    ids = np.empty(offsets[n_tiles], np.int32)
    cursor = offsets[:n_tiles].copy()
    for k in range(order.shape[0]):
        g = order[k]
        for ty in range(tile_min[g, 1], tile_max[g, 1]):
            for tx in range(tile_min[g, 0], tile_max[g, 0]):
                t = ty * tiles_x + tx
                ids[cursor[t]] = g
                cursor[t] += 1
    return offsets, ids


@njit(parallel=True, cache=True)
def gather_records(ids, per_gaussian):  # pragma: no cover - numba
    """Copy each list entry's Gaussian record into a contiguous [P, RECORD_FIELDS] array."""
    out = np.empty((ids.shape[0], per_gaussian.shape[1]), np.float32)
    for j in prange(ids.shape[0]):
        g = ids[j]
        for f in range(per_gaussian.shape[1]):
            out[j, f] = per_gaussian[g, f]
    return out


@njit(cache=True)
def _pair_alpha(rec, j, px, py):  # pragma: no cover - numba
    """(alpha, gaussian value, dx, dy) of entry j at a pixel centre; alpha = 0 when the pair is skipped."""
    dx = px - rec[j, 0]
    dy = py - rec[j, 1]
    if abs(dx) > rec[j, 10]:  # outside the reach box: alpha < 1/255 for sure
        return _ZERO, _ZERO, dx, dy
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
def _row_candidates(rec, cand, n_cand, py, out):  # pragma: no cover - numba
    """Keep the tile candidates whose reach box covers the pixel row at height py; count."""
    n = 0
    for c in range(n_cand):
        j = cand[c]
        if abs(py - rec[j, 1]) <= rec[j, 11]:
            out[n] = j
            n += 1
    return n


@njit(parallel=True, cache=True)
def blend_forward(offsets, rec, tile_order, width, height, tile_size, tiles_x):  # pragma: no cover - numba
    """Front-to-back blending: features [H, W, 4] (no background), final transmittance, last entry + 1."""
    feats = np.zeros((height, width, FEATURES), np.float32)
    t_final = np.ones((height, width), np.float32)
    last = np.zeros((height, width), np.int64)
    for k in prange(tile_order.shape[0]):
        t = tile_order[k]
        start, end = offsets[t], offsets[t + 1]
        row0, col0 = (t // tiles_x) * tile_size, (t % tiles_x) * tile_size
        rows, cols = min(tile_size, height - row0), min(tile_size, width - col0)
        cand = np.empty(end - start, np.int64)
        n_cand = _tile_candidates(rec, start, end, row0, col0, rows, cols, cand)
        row_cand = np.empty(n_cand, np.int64)
        for row in range(row0, row0 + rows):
            py = np.float32(row + 0.5)
            n_row = _row_candidates(rec, cand, n_cand, py, row_cand)
            for col in range(col0, col0 + cols):
                px = np.float32(col + 0.5)
                trans = np.float32(1.0)
                f0 = f1 = f2 = f3 = np.float32(0.0)
                stop = start
                for c in range(n_row):
                    j = row_cand[c]
                    alpha, _, _, _ = _pair_alpha(rec, j, px, py)
                    if alpha == 0.0:
                        continue
                    next_trans = trans * (_ONE - alpha)
                    if next_trans < TRANSMITTANCE_MIN:
                        break
                    w = alpha * trans
                    f0 += rec[j, 6] * w
                    f1 += rec[j, 7] * w
                    f2 += rec[j, 8] * w
                    f3 += rec[j, 9] * w
                    trans = next_trans
                    stop = j + 1
                feats[row, col, 0] = f0
                feats[row, col, 1] = f1
                feats[row, col, 2] = f2
                feats[row, col, 3] = f3
                t_final[row, col] = trans
                last[row, col] = stop
    return feats, t_final, last


@njit(parallel=True, cache=True)
def blend_backward(
    offsets, rec, tile_order, width, height, tile_size, tiles_x, t_final, last, grad_feats, grad_t_final
):  # pragma: no cover - numba
    """Back-to-front gradient of blend_forward; returns per-entry gradients [P, GRAD_FIELDS]."""
    grads = np.zeros((rec.shape[0], GRAD_FIELDS), np.float32)
    for k in prange(tile_order.shape[0]):
        t = tile_order[k]
        start, end = offsets[t], offsets[t + 1]
        row0, col0 = (t // tiles_x) * tile_size, (t % tiles_x) * tile_size
        rows, cols = min(tile_size, height - row0), min(tile_size, width - col0)
        cand = np.empty(end - start, np.int64)
        n_cand = _tile_candidates(rec, start, end, row0, col0, rows, cols, cand)
        row_cand = np.empty(n_cand, np.int64)
        for row in range(row0, row0 + rows):
            py = np.float32(row + 0.5)
            n_row = _row_candidates(rec, cand, n_cand, py, row_cand)
            for col in range(col0, col0 + cols):
                px = np.float32(col + 0.5)
                tf = t_final[row, col]
                trans = tf
                g0, g1, g2, g3 = (
                    grad_feats[row, col, 0],
                    grad_feats[row, col, 1],
                    grad_feats[row, col, 2],
                    grad_feats[row, col, 3],
                )
                g_bg = grad_t_final[row, col] * tf
                s0 = s1 = s2 = s3 = np.float32(0.0)  # colour blended behind the current entry
                stop = last[row, col]
                for c in range(n_row - 1, -1, -1):
                    j = row_cand[c]
                    if j >= stop:
                        continue
                    alpha, gval, dx, dy = _pair_alpha(rec, j, px, py)
                    if alpha == 0.0:
                        continue
                    one_minus = 1.0 - alpha
                    trans = trans / one_minus
                    w = alpha * trans
                    c0, c1, c2, c3 = rec[j, 6], rec[j, 7], rec[j, 8], rec[j, 9]
                    grads[j, 6] += g0 * w
                    grads[j, 7] += g1 * w
                    grads[j, 8] += g2 * w
                    grads[j, 9] += g3 * w
                    d_alpha = trans * (g0 * (c0 - s0) + g1 * (c1 - s1) + g2 * (c2 - s2) + g3 * (c3 - s3))
                    d_alpha -= g_bg / one_minus
                    s0 = alpha * c0 + one_minus * s0
                    s1 = alpha * c1 + one_minus * s1
                    s2 = alpha * c2 + one_minus * s2
                    s3 = alpha * c3 + one_minus * s3
                    if rec[j, 5] * gval <= ALPHA_MAX:  # alpha not clamped: it depends on opacity and power
                        grads[j, 5] += gval * d_alpha
                        d_power = alpha * d_alpha
                        a, b, c = rec[j, 2], rec[j, 3], rec[j, 4]
                        grads[j, 0] += d_power * (a * dx + b * dy)
                        grads[j, 1] += d_power * (b * dx + c * dy)
                        grads[j, 2] += -0.5 * d_power * dx * dx
                        grads[j, 3] += -d_power * dx * dy
                        grads[j, 4] += -0.5 * d_power * dy * dy
    return grads


@njit(cache=True)
def scatter_entry_grads(ids, entry_grads, n_gaussians):  # pragma: no cover - numba
    """Sum per-entry gradient rows into per-Gaussian rows [N, GRAD_FIELDS] (float64 accumulation)."""
    out = np.zeros((n_gaussians, entry_grads.shape[1]), np.float64)
    for j in range(ids.shape[0]):
        g = ids[j]
        for f in range(entry_grads.shape[1]):
            out[g, f] += entry_grads[j, f]
    return out


@njit(parallel=True, cache=True)
def count_blend_weights(offsets, rec, tile_order, width, height, tile_size, tiles_x):  # pragma: no cover
    """Number of Gaussians that contribute to each pixel, [H * W] int64."""
    counts = np.zeros(height * width, np.int64)
    for k in prange(tile_order.shape[0]):
        t = tile_order[k]
        start, end = offsets[t], offsets[t + 1]
        row0, col0 = (t // tiles_x) * tile_size, (t % tiles_x) * tile_size
        rows, cols = min(tile_size, height - row0), min(tile_size, width - col0)
        cand = np.empty(end - start, np.int64)
        n_cand = _tile_candidates(rec, start, end, row0, col0, rows, cols, cand)
        row_cand = np.empty(n_cand, np.int64)
        for row in range(row0, row0 + rows):
            n_row = _row_candidates(rec, cand, n_cand, np.float32(row + 0.5), row_cand)
            for col in range(col0, col0 + cols):
                trans = np.float32(1.0)
                n = 0
                for c in range(n_row):
                    j = row_cand[c]
                    alpha, _, _, _ = _pair_alpha(rec, j, np.float32(col + 0.5), np.float32(row + 0.5))
                    if alpha == 0.0:
                        continue
                    next_trans = trans * (_ONE - alpha)
                    if next_trans < TRANSMITTANCE_MIN:
                        break
                    trans = next_trans
                    n += 1
                counts[row * width + col] = n
    return counts


@njit(parallel=True, cache=True)
def fill_blend_weights(
    offsets, ids, rec, tile_order, width, height, tile_size, tiles_x, row_ptr
):  # pragma: no cover - numba
    """CSR columns (Gaussian ids) and values (alpha_i * T_i) of the pixel x Gaussian blend matrix."""
    gaussian_ids = np.empty(row_ptr[-1], np.int64)
    vals = np.empty(row_ptr[-1], np.float32)
    for k in prange(tile_order.shape[0]):
        t = tile_order[k]
        start, end = offsets[t], offsets[t + 1]
        row0, col0 = (t // tiles_x) * tile_size, (t % tiles_x) * tile_size
        rows, cols = min(tile_size, height - row0), min(tile_size, width - col0)
        cand = np.empty(end - start, np.int64)
        n_cand = _tile_candidates(rec, start, end, row0, col0, rows, cols, cand)
        row_cand = np.empty(n_cand, np.int64)
        for row in range(row0, row0 + rows):
            n_row = _row_candidates(rec, cand, n_cand, np.float32(row + 0.5), row_cand)
            for col in range(col0, col0 + cols):
                trans = np.float32(1.0)
                pos = row_ptr[row * width + col]
                for c in range(n_row):
                    j = row_cand[c]
                    alpha, _, _, _ = _pair_alpha(rec, j, np.float32(col + 0.5), np.float32(row + 0.5))
                    if alpha == 0.0:
                        continue
                    next_trans = trans * (_ONE - alpha)
                    if next_trans < TRANSMITTANCE_MIN:
                        break
                    gaussian_ids[pos] = ids[j]
                    vals[pos] = alpha * trans
                    trans = next_trans
                    pos += 1
    return gaussian_ids, vals


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
