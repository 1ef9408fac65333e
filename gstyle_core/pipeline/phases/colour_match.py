"""The colour match, before stylization (``colour_match``) and after it (``finish``): one class, one step each.

The affine colour transform maps the RGB mean/covariance of the scene's covered pixels onto the painting's palette
(with keep colours: the luminance mean/std only). Because a render is linear in colours (and the transform affine),
transforming every Gaussian's colour transforms every opaque pixel the same way, which is what the reference
achieves by refitting colours to transformed images.
- Before: the pixels are the ground truth's; the transform maps c_gt to start c_s and gives the content targets
  (``match_content_targets``; a region run first measures the region's coverage of each view).
- After: the pixels are the stylized renders'; the transform maps c_s once more.
Where the scene covers fewer than 2 pixels, whole frames are measured instead.
"""

from __future__ import annotations

import numpy as np
import torch

from ...style.colour_match import Palette, apply_colour_transform
from .base import Phase, StepReport


def surface_pixels(image: torch.Tensor, alpha: torch.Tensor, keep_colours: bool) -> torch.Tensor:
    """The pixels [M, 3] the scene covers (alpha > 0.5) whose statistics the colour match maps. With keep colours
    they are divided by alpha (the surface's colour, not its blend with the black background): the luminance map
    Y -> aY + β of the Gaussians turns a pixel into aY + alpha·β, so matched on these the render's covered pixels
    get the painting's luminance mean and std, not a darker scene's."""
    covered = alpha > 0.5
    if not keep_colours:
        return image[covered]
    return image[covered] / alpha[covered].unsqueeze(-1)


def transfer(run, images: list[torch.Tensor], alphas: list[torch.Tensor]) -> tuple[np.ndarray, np.ndarray]:
    """The affine map (A, b) of the covered pixels of ``images`` onto the painting(s): full colour, or luminance
    only with keep colours; whole frames when the scene covers fewer than 2 pixels."""
    from ...style.colour_match import colour_transfer_matrix
    from ...style.keep_colours import luminance_transfer_matrix

    s = run.settings
    pixels = torch.cat([surface_pixels(i, a, s.keep_colours) for i, a in zip(images, alphas, strict=True)]).numpy()
    if len(pixels) < 2:
        pixels = torch.cat([i.reshape(-1, 3) for i in images]).numpy()
    match = luminance_transfer_matrix if s.keep_colours else colour_transfer_matrix
    return match(pixels, Palette.mixture(run.palettes, s.style_weights))


def match_content_targets(run) -> tuple[np.ndarray, np.ndarray]:
    """Colour-match the ground truth to the style: sets ``run.colour_transform`` and the content targets."""
    A, b = transfer(run, run.gt_images, run.match_coverage())
    run.colour_transform = (A, b)
    # The content targets are what the colour-matched Gaussians render: a render is Σ w_i c_i with Σ w_i = alpha
    # over a black background, so c -> A c + b turns a pixel p into A p + alpha b. The background stays black
    # (transforming it too would ask c_s for a change no Gaussian can make, and pull at every silhouette).
    run.content_images = []
    for i, (g, a) in enumerate(zip(run.gt_images, run.coverage, strict=True)):
        p = apply_colour_transform(g.reshape(-1, 3).numpy(), A, np.zeros(3), clip=False)
        p = torch.as_tensor(p + a.reshape(-1, 1).numpy() * b, dtype=torch.float32)
        if run.settings.keep_colours:  # the view's own hues at the new luminance (as c_s gets them)
            from ...style.keep_colours import with_chroma_of

            p = with_chroma_of(p, g.reshape(-1, 3))
        if run.region_coverage:  # region: the selected share of each pixel matched, the rest as it was
            share = (run.region_coverage[i] / a.clamp_min(1e-6)).clamp(0.0, 1.0).reshape(-1, 1)
            p = g.reshape(-1, 3) + share * (p - g.reshape(-1, 3))
        run.content_images.append(p.clamp(0.0, 1.0).reshape(g.shape))
    return A, b


class ColourMatch(Phase):
    """One colour match of the (selected) Gaussians' colours: c_gt -> c_s before stylization, c_s -> c_s after."""

    def __init__(self, run, final: bool = False) -> None:
        super().__init__(run)
        self.final = final
        self.name = "finish" if final else "colour_match"
        self.done = False

    @property
    def finished(self) -> bool:
        return self.done

    def remaining_steps(self) -> int:
        return 0 if self.done else 1

    @torch.no_grad()
    def step(self) -> StepReport:
        run = self.run
        keep = run.settings.keep_colours
        if self.final:
            A, b = transfer(run, *self._renders())
            source = run.c_s
        else:
            if run.active.region:
                run.region_coverage = [run.selected_weight(v) for v in range(len(run.cameras))]
            A, b = match_content_targets(run)
            source = run.gt_rgb().to(torch.float32)
        # with keep colours the luminance map is unclipped, then c_gt's chroma is restored as far as it fits
        matched = torch.as_tensor(apply_colour_transform(source.numpy(), A, b, clip=not keep), dtype=torch.float32)
        run.c_s = run.active.keep_unselected(matched, source)  # outside a region the colours stay
        if keep:
            run.restore_chroma()
        self.done = True
        if self.final:
            what = "luminance (colours kept)" if keep else "style"
            return self.report(colours_changed=True, message=f"final colour match to the {what}")
        return self.report(colours_changed=True, message="colours matched to the style")

    def _renders(self) -> tuple[list[torch.Tensor], list[torch.Tensor]]:
        """The stylized renders of the training views and what of each the scene (or the region) covers."""
        run = self.run
        images = [run.render(v) for v in range(len(run.cameras))]
        if run.active.region:
            return images, [run.selected_weight(v) for v in range(len(run.cameras))]
        return images, [1.0 - run.cache(v).t_final for v in range(len(run.cameras))]

    def state_dict(self) -> dict:
        return {**super().state_dict(), "done": self.done}

    def load_state_dict(self, state: dict) -> None:
        super().load_state_dict(state)
        self.done = bool(state["done"])
