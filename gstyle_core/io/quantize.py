"""Helpers shared by the quantising writers (.spz, compressed .ply)."""

from __future__ import annotations

import numpy as np


def unit_quats(quats: np.ndarray) -> np.ndarray:
    """(w, x, y, z) quaternions [N, 4] normalised in float64; zero-length ones become the identity."""
    q = np.asarray(quats, np.float64)
    norms = np.linalg.norm(q, axis=1, keepdims=True)
    identity = np.tile([1.0, 0.0, 0.0, 0.0], (len(q), 1))
    return np.divide(q, norms, out=identity, where=norms > 0)


def to_uint(values: np.ndarray, top: int) -> np.ndarray:
    """Round to the nearest integer and clamp to [0, top] (uint32)."""
    return np.clip(np.rint(np.nan_to_num(values, nan=0.0)), 0, top).astype(np.uint32)
