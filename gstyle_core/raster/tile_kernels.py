"""Numba kernels that prepare a blend: depth order, per-tile lists of Gaussians, their records, the tile order.

The records' layout is ``pixel_kernels``'s; ``reach_boxes`` is the numpy statement of the reach boxes that
``gaussian_records`` computes per Gaussian.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .pixel_kernels import FEATURES, RECORD_FIELDS


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
    """Per-Gaussian records [N, RECORD_FIELDS] (the layout of ``pixel_kernels``) of the visible ones, reach
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
