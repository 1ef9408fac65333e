"""A feathered region's colours (``settings.region_feather``): each selected Gaussian shows c_gt + w (c_s − c_gt),
w from its centre's distance outside the box (``region.feather_weights``), so the style fades out across the
feather's band instead of stopping at the box's faces. Applied to what the viewer is sent and what is exported; the
optimisation itself works on c_s as before. ``merge_unselected``: the rest of a region run's export, the
Gaussians outside the selection as they came in."""

from __future__ import annotations

import numpy as np
import torch

from ..scene import GaussianScene
from .region import feather_weights


def feathered_colours(run, colours: torch.Tensor) -> torch.Tensor:
    """``colours`` (c_s, [N, 3]) as a feathered region shows them; unchanged without a region box or a feather."""
    s = run.settings
    if s.region is None or float(getattr(s, "region_feather", 0.0)) <= 0 or run.active.selected is None:
        return colours
    w = feather_weights(run.params["means"].detach().numpy(), s.region, float(s.region_feather))
    w = torch.from_numpy(w).to(colours.dtype)[:, None]
    gt = run.gt_rgb().to(colours.dtype)
    return gt + w * (colours - gt)


def merge_unselected(scene: GaussianScene, input_scene: GaussianScene, active) -> GaussianScene:
    """``scene`` (the stylized one) with the Gaussians outside a region's selection taken back from the input
    exactly (every attribute, SH bands included; the stylized ones get zero bands); ``scene`` outside region runs."""
    if active.selected is None:
        return scene
    keep = (~active.selected).numpy()
    rows = active.origin.numpy()[keep]
    fields = {}
    for name in ("means", "log_scales", "quats", "opacity_logits", "sh_dc"):
        src = np.asarray(getattr(input_scene, name))
        arr = np.asarray(getattr(scene, name)).astype(src.dtype, copy=True)
        arr[keep] = src[rows]
        fields[name] = arr
    rest = np.asarray(input_scene.sh_rest)
    sh_rest = np.zeros((scene.count,) + rest.shape[1:], rest.dtype)
    sh_rest[keep] = rest[rows]
    return GaussianScene(**fields, sh_rest=sh_rest)
