"""The coarse colour field: neighbouring Gaussians' colours moved together, so strokes come at the painting's size.

Each stylized colour takes its own Adam step, and Adam moves every colour by about the learning rate whatever its
gradient, so the texture that accumulates sits at the scale of single Gaussians (about 1 px at the working width;
docs/texture-scale.md). Beside the per-Gaussian colours this module keeps a **colour field**: a dense 3-D grid over
the optimised Gaussians' centres, read at each centre by trilinear interpolation and added to its colour. A cell's
gradient is the sum of the colour gradients of the Gaussians around it, so a field step is one coherent move of a
whole neighbourhood; the colours keep their own steps for the fine marks.

* **Cell size**: ``FIELD_CELL_PX`` (8) working-width pixels at the scene's median distance from the training
  cameras, times the stroke size (so the stroke size sets the width of the coherent moves), enlarged where the grid
  would exceed ``MAX_FIELD_CELLS`` cells. The grid spans the 0.5-99.5th percentile box of the centres; centres
  outside it read the border cells.
* **Step**: the colours and the field each step at ``FIELD_STEP_SHARE`` (half) of the learning rate, so the step
  budget of the run is split between the two scales rather than doubled (docs/texture-scale.md measures full and
  half steps). The field uses the same optimiser kind as the colours (``VisibleAdam``: cells no view's Gaussian
  reaches keep their moments).
* **Folding**: after every optimiser step the field's values are added into the colours and set back to zero, so
  the colours (c_s) always hold the whole stylized colour (exports, the studio's buffers, splits and refits see
  nothing else) while Adam's moments of the field go on. The gradient does not depend on the field's value, so this
  is the same optimisation as keeping the field apart.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import torch
import torch.nn.functional as F

FIELD_CELL_PX = 8.0  # cell edge in working-width pixels at the scene's median distance (times the stroke size). A
# cell's trilinear hat has σ = edge / √6 ≈ 3.3 px, at the lower edge of the texture-scale figure's coarse band (σ 4-10
# px). Measured over nine captures × paintings (docs/texture-scale.md): against 4 px the coarse ratio and the structure
# were higher on all nine; 16 px kept more structure still but cost up to 2.9 points of NNFM drop.
FIELD_STEP_SHARE = 0.5  # the colours and the field each step at this share of the learning rate (read when a field
# is built: benches may set it, and COLOUR_STEP_SHARE for the colours alone)
COLOUR_STEP_SHARE: float | None = None  # None: FIELD_STEP_SHARE
MAX_FIELD_CELLS = 2_000_000  # cells enlarged beyond this (memory: 3 floats and 2 Adam moments per cell)
BOX_PERCENTILES = (0.5, 99.5)  # the grid spans this box of the centres (outliers read the border cells)


def pixel_footprint(points: np.ndarray, cameras: Sequence[Any]) -> float:
    """Scene units per pixel of ``cameras`` (their ``fx``) at the median distance from their positions to the
    median of ``points`` [N, 3]."""
    if len(points) == 0 or not cameras:
        raise ValueError("the colour field needs Gaussians and cameras")
    centre = np.median(np.asarray(points, np.float64), axis=0)
    return float(np.median([np.linalg.norm(np.asarray(c.position, np.float64) - centre) / float(c.fx)
                            for c in cameras]))


def grid_shape(extent: np.ndarray, cell: float, max_cells: int = MAX_FIELD_CELLS) -> tuple[tuple[int, int, int], float]:
    """Cells per axis (x, y, z) covering ``extent`` [3] with cells of ``cell`` scene units, and the cell size used
    (enlarged until the grid has at most ``max_cells`` cells)."""
    extent = np.maximum(np.asarray(extent, np.float64), 0.0)
    if not (np.isfinite(cell) and cell > 0):
        raise ValueError(f"the colour field's cell size must be a finite number above 0, got {cell}")
    while True:
        dims = tuple(int(np.ceil(e / cell)) + 1 for e in extent)
        if int(np.prod(dims)) <= max_cells:
            return dims, float(cell)
        cell *= 1.25


class ColourField:
    """A trilinear colour field over ``points`` [N, 3] (the optimised Gaussians' centres), cells of ``cell`` scene
    units, with its own optimiser (``visible``: ``VisibleAdam``, else Adam) at ``lr``.

    ``sample()`` [N, 3] is each point's field colour (differentiable); ``step()`` takes the optimiser step;
    ``fold_into(colours)`` adds the field into ``colours`` [N, 3] and zeroes it."""

    def __init__(self, points: torch.Tensor, cell: float, lr: float, visible: bool = True) -> None:
        self.field_share = float(FIELD_STEP_SHARE)  # of the learning rate, for the field's steps
        self.colour_share = float(FIELD_STEP_SHARE if COLOUR_STEP_SHARE is None else COLOUR_STEP_SHARE)  # colours'
        pts = np.asarray(points.detach().to(torch.float64).numpy())
        if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) == 0:
            raise ValueError(f"the colour field needs centres [N, 3] with N > 0, got {tuple(pts.shape)}")
        lo, hi = np.percentile(pts, BOX_PERCENTILES, axis=0)
        self.dims, self.cell = grid_shape(hi - lo, cell)
        span = (np.array(self.dims) - 1) * self.cell
        u = np.where(span > 0, (pts - lo) / np.where(span > 0, span, 1.0) * 2.0 - 1.0, 0.0)
        self.coords = torch.as_tensor(np.clip(u, -1.0, 1.0), dtype=torch.float32).view(1, -1, 1, 1, 3)
        nx, ny, nz = self.dims
        self.values = torch.zeros(nx * ny * nz, 3, requires_grad=True)  # rows: z-major, then y, then x
        if visible:
            from .visible_adam import VisibleAdam

            self.optimiser: Any = VisibleAdam(self.values, lr=lr)
        else:
            self.optimiser = torch.optim.Adam([self.values], lr=lr)

    @property
    def cells(self) -> int:
        """Number of cells."""
        return int(self.values.shape[0])

    def sample(self) -> torch.Tensor:
        """The field at every point, [N, 3] (trilinear; differentiable with respect to the cells)."""
        nx, ny, nz = self.dims
        volume = self.values.t().reshape(1, 3, nz, ny, nx)
        out = F.grid_sample(volume, self.coords, mode="bilinear", padding_mode="border", align_corners=True)
        return out.reshape(3, -1).t()

    def set_lr(self, lr: float) -> None:
        """The learning rate of the next step."""
        for group in self.optimiser.param_groups:
            group["lr"] = lr

    def zero_grad(self) -> None:
        """Forget the last step's gradient."""
        self.optimiser.zero_grad(set_to_none=True)

    def step(self) -> None:
        """One optimiser step of the cells (after the loss's backward pass)."""
        self.optimiser.step()

    @torch.no_grad()
    def fold_into(self, colours: torch.Tensor) -> None:
        """Add the field into ``colours`` [N, 3] (in place) and set the field back to zero."""
        colours.add_(self.sample())
        self.values.zero_()

    def state_dict(self) -> dict[str, Any]:
        """The optimiser's moments and the grid's shape (the values are zero between steps: they are folded)."""
        return {"dims": list(self.dims), "cell": self.cell, "optimiser": self.optimiser.state_dict()}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore the moments saved by ``state_dict`` (the grid must have the same shape)."""
        if tuple(state["dims"]) != tuple(self.dims):
            raise ValueError(f"colour field state for a {tuple(state['dims'])} grid, this one is {self.dims}")
        self.optimiser.load_state_dict(state["optimiser"])

    def describe(self, stroke_size: float) -> str:
        """One line for the run's decisions."""
        nx, ny, nz = self.dims
        steps = (f"the colours and the field each step at {self.field_share:g} × the learning rate"
                 if self.colour_share == self.field_share else
                 f"the colours step at {self.colour_share:g} and the field at {self.field_share:g} × the learning rate")
        return (f"on: {nx}×{ny}×{nz} cells of {self.cell:.3g} scene units ({FIELD_CELL_PX:g} px × stroke size "
                f"{stroke_size:g} at the scene's median distance, or larger to stay within {MAX_FIELD_CELLS:,} "
                f"cells); {steps}")


def build_colour_field(points: torch.Tensor, cameras: Sequence[Any], stroke_size: float, lr: float,
                       visible: bool) -> ColourField:
    """The colour field for the centres ``points`` seen by ``cameras`` (at the working width) at ``stroke_size``."""
    cell = FIELD_CELL_PX * float(stroke_size) * pixel_footprint(points.detach().numpy(), cameras)
    return ColourField(points, cell, lr, visible)
