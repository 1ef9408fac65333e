"""Nearest neighbours by centre (scipy's k-d tree, queried in bounded chunks): what a capture larger than a run holds
takes its colours from (``engine/capacity.py``) and where a level-of-detail child finds the descendant that carries
its parent's change (``lod/carry.py``)."""

from __future__ import annotations

import numpy as np

NEIGHBOUR_CHUNK = 1 << 20  # queries of the nearest-neighbour search at a time (bounded memory)


def nearest_rows(points: np.ndarray, queries: np.ndarray, workers: int = -1) -> np.ndarray:
    """For each of ``queries`` [Q, 3] the row of the nearest of ``points`` [P, 3] (Euclidean; non-finite
    coordinates count as the origin), int64 [Q]."""
    from scipy.spatial import cKDTree

    if len(points) == 0:
        raise ValueError("nearest_rows: no points to search")
    tree = cKDTree(_finite(points))
    rows = np.empty(len(queries), np.int64)
    for start in range(0, len(queries), NEIGHBOUR_CHUNK):
        part = _finite(queries[start:start + NEIGHBOUR_CHUNK])
        rows[start:start + len(part)] = tree.query(part, k=1, workers=workers)[1]
    return rows


def _finite(points: np.ndarray) -> np.ndarray:
    """``points`` as float64 with every non-finite coordinate at 0."""
    return np.nan_to_num(np.asarray(points, np.float64), nan=0.0, posinf=0.0, neginf=0.0)
