"""Which cameras a run trains on: at most a given number, evenly spread over the scene's cameras."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


def choose_views(cameras: Sequence, max_views: int) -> list[int]:
    """Indices of at most ``max_views`` cameras, evenly spread over the list."""
    n = len(cameras)
    if n <= max_views:
        return list(range(n))
    return sorted({int(round(i)) for i in np.linspace(0, n - 1, max_views)})
