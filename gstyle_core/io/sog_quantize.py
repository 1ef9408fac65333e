"""The vector and scalar quantisers the SOG writer uses: 256-entry codebooks and the SH palette.

* ``codebook_1d``: at most 256 float32 values and each input's nearest one (a uint8 index). Inputs with 256 distinct
  values or fewer are kept exactly; otherwise the codebook starts at quantiles of the data and is refined by Lloyd
  iterations (1D k-means on the distinct values weighted by their counts), so it follows where the values are.
* ``sh_palette``: at most 65,536 SH vectors and each Gaussian's palette index. Scenes with that many distinct
  vectors or fewer keep every one; larger ones are split by median cut (each group halved at the median of its
  widest coordinate, 16 rounds, all groups at once), the palette being each group's mean.
"""

from __future__ import annotations

import numpy as np

CODEBOOK_SIZE = 256
PALETTE_SIZE = 1 << 16  # SOG's labels are 16-bit
LLOYD_ITERATIONS = 12


def _nearest(codebook: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Index of the nearest entry of the ascending ``codebook`` for each of ``values``."""
    cb = codebook.astype(np.float64)
    return np.searchsorted((cb[1:] + cb[:-1]) * 0.5, values.astype(np.float64)).astype(np.int64)


def codebook_1d(values: np.ndarray, size: int = CODEBOOK_SIZE) -> tuple[np.ndarray, np.ndarray]:
    """(codebook float32 [<= size] ascending, index of each value's nearest entry, uint8 shaped like ``values``)."""
    flat = np.asarray(values, np.float32).ravel()
    if flat.size == 0:
        return np.zeros(1, np.float32), np.zeros(np.shape(values), np.uint8)
    distinct, counts = np.unique(flat, return_counts=True)
    if len(distinct) <= size:
        codebook = distinct
    else:
        x, w = distinct.astype(np.float64), counts.astype(np.float64)
        cumulative = np.cumsum(w) - 0.5 * w
        targets = (np.arange(size) + 0.5) / size * w.sum()
        centres = np.unique(x[np.clip(np.searchsorted(cumulative, targets), 0, len(x) - 1)])
        for _ in range(LLOYD_ITERATIONS):
            label = _nearest(centres, x)
            weight = np.bincount(label, weights=w, minlength=len(centres))
            total = np.bincount(label, weights=w * x, minlength=len(centres))
            used = weight > 0
            moved = np.where(used, total / np.where(used, weight, 1.0), centres)
            centres = np.unique(moved)
        codebook = np.unique(centres.astype(np.float32))
    labels = _nearest(codebook, flat).reshape(np.shape(values))
    return codebook.astype(np.float32), labels.astype(np.uint8)


def _median_cut(vectors: np.ndarray, rounds: int) -> np.ndarray:
    """Group labels [N] after ``rounds`` halvings of every group at the median of its widest coordinate."""
    n, dims = vectors.shape
    group = np.zeros(n, np.int64)
    rows = np.arange(n)
    for level in range(rounds):
        groups = 1 << level
        count = np.bincount(group, minlength=groups).astype(np.float64)
        if count.max() <= 1:
            break
        spread = np.empty((groups, dims))
        safe = np.maximum(count, 1.0)
        for d in range(dims):
            mean = np.bincount(group, weights=vectors[:, d], minlength=groups) / safe
            spread[:, d] = np.bincount(group, weights=vectors[:, d] ** 2, minlength=groups) / safe - mean**2
        key = vectors[rows, np.argmax(spread, axis=1)[group]]
        order = np.lexsort((key, group))
        sorted_group = group[order]
        start = np.concatenate([[0], np.cumsum(count.astype(np.int64))[:-1]])
        rank = np.arange(n) - start[sorted_group]
        upper = rank >= (count.astype(np.int64) // 2)[sorted_group]
        group[order] = 2 * sorted_group + upper
    return group


def sh_palette(vectors: np.ndarray, size: int = PALETTE_SIZE) -> tuple[np.ndarray, np.ndarray]:
    """(palette float32 [K <= size, D], label of each row of ``vectors`` [N, D], int64)."""
    v = np.asarray(vectors, np.float32)
    if len(v) == 0:
        return np.zeros((1, v.shape[1]), np.float32), np.zeros(0, np.int64)
    distinct, labels = np.unique(v, axis=0, return_inverse=True)
    if len(distinct) <= size:
        return distinct, labels.reshape(-1).astype(np.int64)
    rounds = int(np.ceil(np.log2(size)))
    groups, labels = np.unique(_median_cut(v.astype(np.float64), rounds), return_inverse=True)
    counts = np.bincount(labels, minlength=len(groups)).astype(np.float64)
    palette = np.stack([np.bincount(labels, weights=v[:, d], minlength=len(groups)) for d in range(v.shape[1])],
                       axis=1) / counts[:, None]
    return palette.astype(np.float32), labels.astype(np.int64)
