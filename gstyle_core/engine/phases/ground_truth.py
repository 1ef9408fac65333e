"""Ground truth: one training view per step, the scene's photo or a render of the input scene (with its SH)."""

from __future__ import annotations

import numpy as np
import torch

from ...cameras.images import resize_image
from ...fit.model import params_from_scene, render_params
from .base import Phase, StepReport


def ground_truth_view(run, cam, view: int, input_params) -> tuple[torch.Tensor, torch.Tensor]:
    """The ground truth of training view ``view`` seen by ``cam`` (that view at any size): its photo resized, or a
    render of the input scene (``input_params``, with its SH); and its coverage (the render's alpha; 1 for photos)."""
    if run.photos is not None:
        photo = np.clip(np.asarray(run.photos[view], np.float32), 0, 1)
        gt = torch.as_tensor(resize_image(photo, (cam.width, cam.height)))
        return gt, torch.ones(gt.shape[:2])
    with torch.no_grad():
        out = render_params(input_params, cam, sh_degree=run.gt_sh_degree, backend=run.settings.raster_backend,
                            device=run.raster_device)
    return out.image.clamp(0, 1).cpu(), out.alpha.clamp(0, 1).cpu()


class GroundTruth(Phase):
    """Fills ``run.gt_images`` and ``run.coverage`` (the render's alpha; 1 for photos), one view per step."""

    name = "ground_truth"

    def __init__(self, run) -> None:
        super().__init__(run)
        self._input_params = None  # the input scene with its SH, while views are left to render

    @property
    def finished(self) -> bool:
        return len(self.run.gt_images) >= len(self.run.cameras)

    def remaining_steps(self) -> int:
        return len(self.run.cameras) - len(self.run.gt_images)

    def step(self) -> StepReport:
        run = self.run
        i = len(run.gt_images)
        if run.photos is None and self._input_params is None:
            self._input_params = params_from_scene(run.truth_scene, requires_grad=False)
        gt, covered = ground_truth_view(run, run.cameras[i], i, self._input_params)
        run.gt_images.append(gt)
        run.coverage.append(covered)
        if self.finished:
            self._input_params = None
        source = "photo" if run.photos is not None else "render"
        return self.report(message=f"ground truth {i + 1}/{len(run.cameras)} ({source})")
