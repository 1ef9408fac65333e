"""The selection's outline in the view: the screen footprint of the selected Gaussians' centres, as line segments.

Drawn over every view mode (stylized, original, compare, take) instead of tinting the splats, so the style arriving
in a selected region stays visible. The centres are projected, binned into square cells of ``cell`` pixels, the
occupied cells grown by one cell (neighbouring centres join into one region), and the boundary between occupied
and free cells is returned as horizontal and vertical segments (runs merged). Pure numpy, no GL."""

from __future__ import annotations

import numpy as np

from gstyle_core.cameras.camera import Camera

Segment = tuple[float, float, float, float]
OUTLINE_CELL = 6.0  # pixels per cell of the footprint grid


def project_points(points: np.ndarray, camera: Camera, near: float = 1e-3) -> np.ndarray:
    """[N, 2] pixel positions (x right, y down) of the points in front of ``camera``."""
    w2c = np.asarray(camera.world_to_cam, np.float64)
    p = np.asarray(points, np.float64) @ w2c[:3, :3].T + w2c[:3, 3]
    p = p[p[:, 2] > near]
    return np.column_stack([camera.fx * p[:, 0] / p[:, 2] + camera.cx, camera.fy * p[:, 1] / p[:, 2] + camera.cy])


def footprint(pixels: np.ndarray, width: float, height: float, cell: float = OUTLINE_CELL) -> np.ndarray:
    """bool [rows, cols] grid of ``cell``-pixel cells over a ``width`` x ``height`` view: cells holding a pixel
    position or next to one."""
    cols, rows = max(int(np.ceil(width / cell)), 1), max(int(np.ceil(height / cell)), 1)
    occ = np.zeros((rows + 2, cols + 2), bool)  # one free cell of margin each side for the growing
    if len(pixels):
        ij = np.floor(np.asarray(pixels, np.float64) / cell).astype(np.int64)
        keep = (ij[:, 0] >= -1) & (ij[:, 0] <= cols) & (ij[:, 1] >= -1) & (ij[:, 1] <= rows)
        occ[ij[keep, 1] + 1, ij[keep, 0] + 1] = True
    grown = occ.copy()
    grown[1:, :] |= occ[:-1, :]
    grown[:-1, :] |= occ[1:, :]
    grown2 = grown.copy()
    grown2[:, 1:] |= grown[:, :-1]
    grown2[:, :-1] |= grown[:, 1:]
    return grown2[1:-1, 1:-1]


def _runs(flags: np.ndarray) -> list[tuple[int, int]]:
    """(start, end) of each run of True in a 1-D bool array (end exclusive)."""
    d = np.diff(np.concatenate([[0], flags.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist(), strict=True))


def outline_segments(grid: np.ndarray, cell: float = OUTLINE_CELL) -> list[Segment]:
    """The boundary of the True cells of ``grid`` as (x0, y0, x1, y1) pixel segments, collinear runs merged."""
    padded = np.pad(grid, 1)
    segments: list[Segment] = []
    horizontal = padded[1:, 1:-1] != padded[:-1, 1:-1]  # [rows + 1, cols]: boundary above row i
    for i in np.flatnonzero(horizontal.any(axis=1)):
        y = float(i * cell)
        segments += [(a * cell, y, b * cell, y) for a, b in _runs(horizontal[i])]
    vertical = padded[1:-1, 1:] != padded[1:-1, :-1]  # [rows, cols + 1]: boundary left of column j
    for j in np.flatnonzero(vertical.any(axis=0)):
        x = float(j * cell)
        segments += [(x, a * cell, x, b * cell) for a, b in _runs(vertical[:, j])]
    return segments


def selection_outline(points: np.ndarray, camera: Camera, scale: tuple[float, float] = (1.0, 1.0),
                      cell: float = OUTLINE_CELL) -> list[Segment]:
    """Outline segments (window coordinates: framebuffer pixels divided by ``scale``) of the footprint of
    ``points`` seen by ``camera`` (its size is the view's, in framebuffer pixels)."""
    pixels = project_points(points, camera) / np.asarray(scale, np.float64)
    grid = footprint(pixels, camera.width / scale[0], camera.height / scale[1], cell)
    return outline_segments(grid, cell)
