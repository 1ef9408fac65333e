"""Helpers shared by the quantising writers and readers (.spz, compressed .ply, SOG)."""

from __future__ import annotations

import numpy as np


def unit_quats(quats: np.ndarray) -> np.ndarray:
    """(w, x, y, z) quaternions [N, 4] normalised in float64; zero-length ones become the identity."""
    q = np.asarray(quats, np.float64)
    norms = np.linalg.norm(q, axis=1, keepdims=True)
    identity = np.tile([1.0, 0.0, 0.0, 0.0], (len(q), 1))
    return np.divide(q, norms, out=identity, where=norms > 0)


# the three components kept beside the largest (index i of w, x, y, z), in order: row i
OTHERS = np.array([[j for j in range(4) if j != i] for i in range(4)])


def smallest_three(quats: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(index of the largest component of each unit quaternion (w, x, y, z) [N, 4], the other three in order [N, 3]),
    each quaternion's sign chosen so that its largest component is positive (float64)."""
    q = unit_quats(quats)
    largest = np.argmax(np.abs(q), axis=1)
    rows = np.arange(len(q))
    q = np.where(q[rows, largest][:, None] < 0, -q, q)
    return largest, np.stack([q[rows, OTHERS[largest, slot]] for slot in range(3)], axis=1)


def from_smallest_three(largest: np.ndarray, small: np.ndarray) -> np.ndarray:
    """(w, x, y, z) quaternions [N, 4] float64 from the largest component's index and the other three (the inverse of
    ``smallest_three``): the largest is sqrt(1 - a^2 - b^2 - c^2), non-negative."""
    quats = np.zeros((len(small), 4))
    rows = np.arange(len(small))
    quats[rows, largest] = np.sqrt(np.maximum(0.0, 1.0 - np.square(small).sum(axis=1)))
    for slot in range(3):
        quats[rows, OTHERS[largest, slot]] = small[:, slot]
    return quats


def to_uint(values: np.ndarray, top: int) -> np.ndarray:
    """Round to the nearest integer and clamp to [0, top] (uint32)."""
    return np.clip(np.rint(np.nan_to_num(values, nan=0.0)), 0, top).astype(np.uint32)


OPACITY_LIMIT = 40.0  # the logit an alpha of exactly 0 or 1 decodes to (its sign)


def opacity_logits_of(alpha: np.ndarray) -> np.ndarray:
    """Opacity logits of alphas in [0, 1] (float64): logit(a), with a = 0 -> -40 and a = 1 -> +40 (the compressed PLY
    and SOG readers' convention)."""
    a = np.asarray(alpha, np.float64)
    with np.errstate(divide="ignore"):
        return np.where(a <= 0, -OPACITY_LIMIT, np.where(a >= 1, OPACITY_LIMIT, -np.log(1.0 / a - 1.0)))
