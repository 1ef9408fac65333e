"""The part of a view the scene covers: the networks need not look at the empty background around an object.

Since NNFM, content and the coarse substitute weight each feature position by the scene's coverage, positions the
scene does not reach count for nothing; VGG still paid for them. ``scene_box`` is the box of pixels the scene
covers (alpha above the blending cut-off 1/255), grown by ``SCENE_BOX_MARGIN_PX`` so that the covered positions
keep their image context (relu3's effective receptive field is a few pixels wide: on the winter fountain's views
NNFM and content agreed with the whole frame's to 1e-4 relative; test_scene_box.py checks 2e-3 on a synthetic
object with random VGG weights) and aligned to ``SCENE_BOX_ALIGN_PX``, so that VGG's two poolings see the same
pixel grid as in the whole frame. The CLIP term (or its substitute, whose context is most of the frame) still gets
the whole frame.
"""

from __future__ import annotations

import torch

from ..raster.kernels import ALPHA_MIN

SCENE_BOX_MARGIN_PX = 8
SCENE_BOX_ALIGN_PX = 16


def scene_box(coverage: torch.Tensor, margin: int = SCENE_BOX_MARGIN_PX,
              align: int = SCENE_BOX_ALIGN_PX) -> tuple[slice, slice] | None:
    """(rows, columns) slices of the box the scene covers in ``coverage`` [H, W]; None when it is the whole frame
    (nothing to save) or when nothing is covered (nothing to crop to: the caller keeps the frame)."""
    cov = torch.as_tensor(coverage)
    if cov.ndim != 2:
        raise ValueError(f"coverage must be [H, W], got {tuple(cov.shape)}")
    rows = torch.nonzero((cov > ALPHA_MIN).any(dim=1)).flatten()
    cols = torch.nonzero((cov > ALPHA_MIN).any(dim=0)).flatten()
    if len(rows) == 0:
        return None
    height, width = cov.shape
    y0, y1 = _aligned(int(rows[0]) - margin, int(rows[-1]) + 1 + margin, height, align)
    x0, x1 = _aligned(int(cols[0]) - margin, int(cols[-1]) + 1 + margin, width, align)
    if (y0, y1, x0, x1) == (0, height, 0, width):
        return None
    return slice(y0, y1), slice(x0, x1)


def box_fraction(box: tuple[slice, slice] | None, height: int, width: int) -> float:
    """Fraction of the frame's pixels inside ``box`` (1 for None: the whole frame)."""
    if box is None:
        return 1.0
    rows, cols = box
    return (rows.stop - rows.start) * (cols.stop - cols.start) / float(height * width)


def _aligned(start: int, stop: int, size: int, align: int) -> tuple[int, int]:
    """[start, stop) widened to multiples of ``align`` and clipped to [0, size) (the end may stop at ``size``)."""
    start = max(0, start // align * align)
    stop = min(size, -(-stop // align) * align)
    return start, stop
