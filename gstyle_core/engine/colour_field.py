"""The coarse colour field: neighbouring Gaussians' colours moved together, so strokes come at the painting's size.

Each stylized colour takes its own Adam step, and Adam moves every colour by about the learning rate whatever its
gradient, so the texture that accumulates sits at the scale of single Gaussians (about 1 px at the working width;
docs/notes/texture-scale.md). Beside the per-Gaussian colours this module keeps a **colour field**: values on a regular
3-D lattice, read at each optimised Gaussian's centre by trilinear interpolation and added to its colour. A lattice
point's gradient is the sum of the colour gradients of the Gaussians around it, so a field step is one coherent move
of a whole neighbourhood; the colours keep their own steps for the fine marks.

* **Cell size**: ``FIELD_CELL_PX`` (8) working-width pixels at the scene's median distance from the training
  cameras, times the stroke size (so the stroke size sets the width of the coherent moves).
* **Sparse**: only the lattice points at the corners of a cell that holds a centre exist (at most 8 per Gaussian),
  so an unbounded capture's far background costs as little as its foreground and every cell keeps its size.
* **Step**: the colours and the field each step at ``FIELD_STEP_SHARE`` (half) of the learning rate, so the step
  budget of the run is split between the two scales rather than doubled (docs/notes/texture-scale.md measures full and
  half steps). The field uses the same optimiser kind as the colours (``VisibleAdam``: lattice points no view's
  Gaussian reaches keep their moments).
* **Folding**: after every optimiser step the field's values are added into the colours and set back to zero, so
  the colours (c_s) always hold the whole stylized colour (exports, the studio's buffers, splits and refits see
  nothing else) while Adam's moments of the field go on. The gradient does not depend on the field's value, so this
  is the same optimisation as keeping the field apart.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from typing import Any

import numpy as np
import torch

from ..raster.colour_cache import SparseProduct

FIELD_CELL_PX = 8.0  # cell edge in working-width pixels at the scene's median distance (times the stroke size). A
# cell's trilinear hat has σ = edge / √6 ≈ 3.3 px, at the lower edge of the texture-scale figure's coarse band (σ 4-10
# px). Measured over nine captures × paintings (docs/notes/texture-scale.md): against 4 px the coarse ratio and the
# structure were higher on all nine; 16 px kept more structure still but cost up to 2.9 points of NNFM drop.
FIELD_STEP_SHARE = 0.5  # the colours and the field each step at this share of the learning rate (read when a field
# is built: benches may set it, and COLOUR_STEP_SHARE for the colours alone)
COLOUR_STEP_SHARE: float | None = None  # None: FIELD_STEP_SHARE
CORNERS = torch.tensor([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)])  # a cell's 8 corners


def pixel_footprint(points: np.ndarray, cameras: Sequence[Any]) -> float:
    """Scene units per pixel of ``cameras`` (their ``fx``) at the median distance from their positions to the
    median of ``points`` [N, 3]."""
    if len(points) == 0 or not cameras:
        raise ValueError("the colour field needs Gaussians and cameras")
    centre = np.median(np.asarray(points, np.float64), axis=0)
    return float(np.median([np.linalg.norm(np.asarray(c.position, np.float64) - centre) / float(c.fx)
                            for c in cameras]))


def unique_points(points: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """The distinct rows of ``points`` [P, 3] (integers >= 0) and each row's index among them (``torch.unique`` of
    rows, through one int64 key per row where the lattice's span allows it: a 1-D sort instead of a row sort)."""
    span = points.max(0).values + 1
    if float(span.double().prod()) >= 2.0 ** 62:  # too wide for one key: sort the rows themselves
        return torch.unique(points, dim=0, return_inverse=True)
    sy, sz = int(span[1]), int(span[2])
    key = (points[:, 0] * sy + points[:, 1]) * sz + points[:, 2]
    keys, inverse = torch.unique(key, return_inverse=True)
    return torch.stack([keys // (sy * sz), (keys // sz) % sy, keys % sz], 1), inverse


class TrilinearLattice:
    """A sparse regular 3-D lattice of ``cell`` scene units over ``points`` [N, 3]: only the 8 corners of the cells
    that hold a point exist. ``sample(values)`` reads lattice values [M, C] at every point (trilinear);
    ``average(values, weights)`` is the lattice's weighted mean of per-point values [N, C] read back at the points
    (a smoothing of the points' values over about one cell)."""

    def __init__(self, points: torch.Tensor, cell: float) -> None:
        pts = points.detach().to(torch.float64)
        if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) == 0:
            raise ValueError(f"the colour field needs centres [N, 3] with N > 0, got {tuple(pts.shape)}")
        if not bool(torch.isfinite(pts).all()):
            raise ValueError("the colour field needs finite centres")
        if not (np.isfinite(cell) and cell > 0):
            raise ValueError(f"the colour field's cell size must be a finite number above 0, got {cell}")
        self.cell = float(cell)
        self.origin = pts.min(0).values  # lattice point (0, 0, 0), scene units
        grid = (pts - self.origin) / self.cell  # lattice units
        base = grid.floor()
        frac = (grid - base).to(torch.float32)  # [N, 3] position inside the cell
        corners = (base.to(torch.int64)[:, None, :] + CORNERS[None]).reshape(-1, 3)  # [N·8, 3], all >= 0
        keys, inverse = unique_points(corners)
        self.lattice = keys  # [M, 3] integer coordinates of the lattice points (position: origin + cell × these)
        self.index = inverse.reshape(-1, 8)  # each point's 8 lattice points (rows of lattice values)
        c = CORNERS.to(torch.float32)[None]  # [1, 8, 3]
        self.weights = (c * frac[:, None, :] + (1 - c) * (1 - frac[:, None, :])).prod(-1)  # [N, 8], sum 1
        self.extent = tuple(int(e) + 1 for e in (keys.max(0).values - keys.min(0).values))  # lattice span (x, y, z)
        self._matrices: tuple[torch.Tensor, torch.Tensor] | None = None

    @property
    def size(self) -> int:
        """Number of lattice points."""
        return int(self.lattice.shape[0])

    @property
    def matrices(self) -> tuple[torch.Tensor, torch.Tensor]:
        """The interpolation as sparse CSR matrices, made on first use: W [N, M] (each point's row holds its 8
        corners' weights) and its transpose [M, N] (each lattice point's row: the points around it)."""
        if self._matrices is None:
            n, m = self.index.shape[0], self.size
            columns, order = self.index.sort(dim=1)
            values = self.weights.gather(1, order).reshape(-1)
            columns, rows = columns.reshape(-1), torch.arange(n).repeat_interleave(8)
            by_column = torch.argsort(columns, stable=True)  # rows stay ascending within each lattice point
            t_rows = torch.zeros(m + 1, dtype=torch.int64)
            t_rows[1:] = torch.bincount(columns, minlength=m).cumsum(0)
            with warnings.catch_warnings():
                warnings.filterwarnings("ignore", message="Sparse CSR tensor support is in beta")
                warnings.filterwarnings("ignore", message="Sparse invariant checks are implicitly disabled")
                self._matrices = (
                    torch.sparse_csr_tensor(torch.arange(0, 8 * n + 1, 8), columns, values, (n, m)),
                    torch.sparse_csr_tensor(t_rows, rows[by_column], values[by_column], (m, n)))
        return self._matrices

    def sample(self, values: torch.Tensor) -> torch.Tensor:
        """Lattice ``values`` [M, C] read at every point, [N, C] (trilinear; differentiable in ``values``): one
        sparse product, and one with the transpose for the gradient."""
        forward, adjoint = self.matrices
        return SparseProduct.apply(values.to(torch.float32).contiguous(), forward, adjoint)

    def adjoint(self, point_values: torch.Tensor) -> torch.Tensor:
        """Per-point ``point_values`` [N, C] summed onto the lattice with the trilinear weights, [M, C]: the
        gradient of the lattice values for a gradient ``point_values`` of ``sample``'s output."""
        return self.matrices[1] @ point_values.to(torch.float32).contiguous()

    @torch.no_grad()
    def average(self, values: torch.Tensor, weights: torch.Tensor | None = None) -> torch.Tensor:
        """Per-point ``values`` [N, C] smoothed over the lattice: each lattice point takes the mean of the points
        around it (trilinear weights times ``weights`` [N], default 1), read back at the points (trilinear)."""
        w = self.weights if weights is None else self.weights * weights.to(torch.float32)[:, None]  # [N, 8]
        flat = self.index.reshape(-1)
        total = torch.zeros(self.size, values.shape[-1]).index_add_(
            0, flat, (w[..., None] * values.to(torch.float32)[:, None, :]).reshape(-1, values.shape[-1]))
        mass = torch.zeros(self.size).index_add_(0, flat, w.reshape(-1))
        return self.sample(total / mass.clamp_min(1e-12)[:, None])


class ColourField:
    """A trilinear colour field at ``points`` [N, 3] (the optimised Gaussians' centres) on a lattice of ``cell`` scene
    units, with its own optimiser (``visible``: ``VisibleAdam``, else Adam) at ``lr``.

    ``sample()`` [N, 3] is each point's field colour (differentiable); ``step()`` takes the optimiser step;
    ``fold_into(colours)`` adds the field into ``colours`` [N, 3] and zeroes it."""

    def __init__(self, points: torch.Tensor, cell: float, lr: float, visible: bool = True) -> None:
        self.field_share = float(FIELD_STEP_SHARE)  # of the learning rate, for the field's steps
        self.colour_share = float(FIELD_STEP_SHARE if COLOUR_STEP_SHARE is None else COLOUR_STEP_SHARE)  # colours'
        self.grid = TrilinearLattice(points, cell)
        self.cell, self.origin, self.lattice, self.extent = self.grid.cell, self.grid.origin, self.grid.lattice, \
            self.grid.extent
        self.index, self.weights = self.grid.index, self.grid.weights
        self.values = torch.zeros(self.grid.size, 3, requires_grad=True)
        self.unfolded = False  # True between a step and the fold that adds the values into the colours
        if visible:
            from .visible_adam import VisibleAdam

            self.optimiser: Any = VisibleAdam(self.values, lr=lr)
        else:
            self.optimiser = torch.optim.Adam([self.values], lr=lr)

    @property
    def cells(self) -> int:
        """Number of lattice points (the field's values)."""
        return int(self.values.shape[0])

    def sample(self) -> torch.Tensor:
        """The field at every point, [N, 3] (trilinear; differentiable with respect to the lattice values)."""
        return self.grid.sample(self.values)

    def set_lr(self, lr: float) -> None:
        """The learning rate of the next step."""
        for group in self.optimiser.param_groups:
            group["lr"] = lr

    def zero_grad(self) -> None:
        """Forget the last step's gradient."""
        self.optimiser.zero_grad(set_to_none=True)

    def take_gradient(self, colour_grad: torch.Tensor) -> None:
        """The lattice values' gradient for a gradient ``colour_grad`` [N, 3] of the points' colours, as a loss of
        ``colours + sample()`` gives it (the interpolation's adjoint). Between folds the values are zero, so a step
        renders the colours alone and takes the field's gradient here, with no interpolation in its forward pass."""
        self.values.grad = self.grid.adjoint(colour_grad)

    def step(self) -> None:
        """One optimiser step of the cells (after the loss's backward pass or ``take_gradient``)."""
        self.optimiser.step()
        self.unfolded = True

    @torch.no_grad()
    def fold_into(self, colours: torch.Tensor) -> None:
        """Add the field into ``colours`` [N, 3] (in place) and set the field back to zero."""
        colours.add_(self.sample())
        self.values.zero_()
        self.unfolded = False

    def state_dict(self) -> dict[str, Any]:
        """The optimiser's moments and the lattice's size (the values are zero between steps: they are folded)."""
        return {"cells": self.cells, "cell": self.cell, "optimiser": self.optimiser.state_dict()}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore the moments saved by ``state_dict`` (the lattice must have as many points)."""
        if int(state["cells"]) != self.cells:
            raise ValueError(f"colour field state for {state['cells']} lattice points, this one has {self.cells}")
        self.optimiser.load_state_dict(state["optimiser"])

    def describe(self, stroke_size: float) -> str:
        """One line for the run's decisions."""
        nx, ny, nz = self.extent
        steps = (f"the colours and the field each step at {self.field_share:g} × the learning rate"
                 if self.colour_share == self.field_share else
                 f"the colours step at {self.colour_share:g} and the field at {self.field_share:g} × the learning rate")
        return (f"on: {self.cells:,} lattice points (cells of {self.cell:.3g} scene units: {FIELD_CELL_PX:g} px × "
                f"stroke size {stroke_size:g} at the scene's median distance; the scene spans {nx}×{ny}×{nz} "
                f"cells); {steps}")


def build_colour_field(points: torch.Tensor, cameras: Sequence[Any], stroke_size: float, lr: float,
                       visible: bool) -> ColourField:
    """The colour field for the centres ``points`` seen by ``cameras`` (at the working width) at ``stroke_size``."""
    cell = FIELD_CELL_PX * float(stroke_size) * pixel_footprint(points.detach().numpy(), cameras)
    return ColourField(points, cell, lr, visible)
