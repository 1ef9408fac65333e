"""Which Gaussians the training cameras can see, by the rasterizer's own culling rules.

A Gaussian contributes to some pixel of a camera only if the projection keeps it (in front of the near plane,
a valid 2D covariance, its 3-sigma footprint touching the image's tiles) and its opacity reaches the blending
cut-off of 1/255 (alpha = opacity * exp(power) <= opacity). Gaussians that fail for every camera add exactly
nothing to any training render, so the stylizer leaves them out of renders, gradients and splits.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch
from torch import Tensor

from ..cameras.camera import Camera
from ..fit.model import camera_tensors
from ..raster.kernels import ALPHA_MIN
from ..raster.projection import project_gaussians


@torch.no_grad()
def seen_mask(means: Tensor, quats: Tensor, scales: Tensor, opacities: Tensor, cameras: Sequence[Camera],
              near: float = 0.01, far: float = 1e10) -> Tensor:
    """Bool [N]: True where a Gaussian can add to at least one pixel of at least one of ``cameras``.

    ``scales`` and ``opacities`` are activated (not logs or logits). Each camera projects only the Gaussians no
    earlier camera saw, so the cost falls as the views accumulate.
    """
    f32 = torch.float32
    means, quats, scales = means.detach().to(f32), quats.detach().to(f32), scales.detach().to(f32)
    seen = torch.zeros(means.shape[0], dtype=torch.bool)
    todo = torch.nonzero(opacities.detach().to(f32) >= np.float32(ALPHA_MIN)).flatten()
    for cam in cameras:
        if todo.numel() == 0:
            break
        viewmat, K = camera_tensors(cam)
        proj = project_gaussians(means[todo], quats[todo], scales[todo], viewmat, K, cam.width, cam.height,
                                 near, far)
        seen[todo[proj.visible]] = True
        todo = todo[~proj.visible]
    return seen


def culling_note(unseen: int, total: int, views: int) -> str:
    """The run summary's line for the culling decision."""
    return (f"{unseen} of {total} Gaussians seen by no training camera ({views} views): not rendered, not "
            f"optimised, not split")
