"""A feathered region's colours (``settings.region_feather``): each selected Gaussian shows c_gt + w (c_s − c_gt),
w from its centre's distance outside the box (``region.feather_weights``), so the style fades out across the
feather's band instead of stopping at the box's faces. Applied to what the viewer is sent and what is exported; the
optimisation itself works on c_s as before."""

from __future__ import annotations

import torch

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
