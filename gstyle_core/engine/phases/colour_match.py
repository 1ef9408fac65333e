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


def detail_base(run, colours: torch.Tensor, px: float | None = None) -> torch.Tensor:
    """``colours`` [N, 3] of every Gaussian smoothed over ``px`` (default ``settings.match_detail_px``) working-width
    pixels at the scene's median distance: the opacity-weighted mean on a trilinear lattice of that cell over the
    active Gaussians (seen, and selected in a region run), read back at each of them
    (``colour_field.TrilinearLattice.average``); the others keep their own colour as their base."""
    from ..colour_field import TrilinearLattice, pixel_footprint

    active = run.active
    means = active.gather(run.params["means"].detach())
    if means.shape[0] == 0:
        return colours.clone()
    cell = (run.settings.match_detail_px if px is None else px) * pixel_footprint(means.numpy(), run.cameras)
    opacity = torch.sigmoid(active.gather(run.params["opacity_logits"].detach()))
    base = colours.clone()
    active.scatter(base, TrilinearLattice(means, cell).average(active.gather(colours), opacity))
    return base


def matched_colours(run, source: torch.Tensor, A: np.ndarray, b: np.ndarray) -> torch.Tensor:
    """``source`` [N, 3] under the colour match c -> A c + b. With ``settings.match_detail_px`` > 0 only the broad
    colours are mapped (``detail_base``) and each Gaussian keeps its own difference from them at its own size:
    c' = A·base + b + (c − base). A plain match of a scene far less colourful than the painting multiplies the
    per-Gaussian colour differences of the fit (invisible in the scene) by the map's gain (4–17× measured on the
    bundled captures), which shows as single-splat confetti at the display's size (docs/notes/tradeoffs-history.md).
    With keep colours the luminance map is applied to the whole colour, unclipped (c_gt's chroma is restored after)."""
    keep = run.settings.keep_colours
    if run.settings.match_detail_px > 0 and not keep:
        base = detail_base(run, source)
        mapped = torch.as_tensor(apply_colour_transform(base.numpy(), A, b, clip=False), dtype=torch.float32)
        return (mapped + (source - base)).clamp(0.0, 1.0)
    return torch.as_tensor(apply_colour_transform(source.numpy(), A, b, clip=not keep), dtype=torch.float32)


def detail_sigma(run, scale: float = 1.0) -> float:
    """The image-space counterpart of ``detail_base``'s smoothing: σ (px) of a Gaussian blur as wide as a lattice
    average of ``match_detail_px`` cells (splat then read: two trilinear hats, variance cell²/3), in pixels of an
    image ``scale`` × the working width; 0 when the match maps whole colours."""
    s = run.settings
    return 0.0 if s.match_detail_px <= 0 or s.keep_colours else float(s.match_detail_px) / 3 ** 0.5 * scale


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
    run.content_images = [content_target(run, g, a, run.region_coverage[i] if run.region_coverage else None)
                          for i, (g, a) in enumerate(zip(run.gt_images, run.coverage, strict=True))]
    return A, b


def content_target(run, gt: torch.Tensor, alpha: torch.Tensor, region: torch.Tensor | None = None,
                   scale: float = 1.0) -> torch.Tensor:
    """The content target of a ground-truth image ``gt`` [H, W, 3] with coverage ``alpha`` [H, W] under the run's
    colour transform (``region``: the selected Gaussians' weight per pixel in a region run, else None; ``scale``: the
    image's pixels per working-width pixel).

    The content targets are what the colour-matched Gaussians render: a render is Σ w_i c_i with Σ w_i = alpha over a
    black background, so c -> A c + b turns a pixel p into A p + alpha b. The background stays black (transforming it
    too would ask c_s for a change no Gaussian can make, and pull at every silhouette). With ``match_detail_px`` the
    Gaussians' broad colours alone are mapped (``matched_colours``), so the pixel becomes
    p + alpha·((A − I)·base + b), base the surface colour blurred as widely (``detail_sigma``)."""
    A, b = run.colour_transform
    g = gt.reshape(-1, 3)
    sigma = detail_sigma(run, scale)
    if sigma > 0:
        base = surface_blur(gt, alpha, sigma).reshape(-1, 3)
        change = apply_colour_transform(base.numpy(), A - np.eye(3), b, clip=False)
        p = g + alpha.reshape(-1, 1) * torch.as_tensor(change, dtype=torch.float32)
    else:
        p = apply_colour_transform(g.numpy(), A, np.zeros(3), clip=False)
        p = torch.as_tensor(p + alpha.reshape(-1, 1).numpy() * b, dtype=torch.float32)
    if run.settings.keep_colours:  # the view's own hues at the new luminance (as c_s gets them)
        from ...style.keep_colours import with_chroma_of

        p = with_chroma_of(p, g)
    if region is not None:  # region: the selected share of each pixel matched, the rest as it was
        share = (region / alpha.clamp_min(1e-6)).clamp(0.0, 1.0).reshape(-1, 1)
        p = g + share * (p - g)
    return p.clamp(0.0, 1.0).reshape(gt.shape)


def surface_blur(image: torch.Tensor, alpha: torch.Tensor, sigma: float) -> torch.Tensor:
    """The surface colour of ``image`` [H, W, 3] (a render over black with coverage ``alpha`` [H, W]) blurred by a
    Gaussian of ``sigma`` px: blur(image) / blur(alpha), so the empty background does not darken the scene's rim."""
    from ...style.texture_scale import gaussian_blur

    planes = torch.cat([image.permute(2, 0, 1), alpha[None]]).to(torch.float32)
    blurred = gaussian_blur(planes, sigma)
    return (blurred[:3] / blurred[3:].clamp_min(1e-6)).permute(1, 2, 0)


def blend_colours(before: torch.Tensor, matched: torch.Tensor, strength: float) -> torch.Tensor:
    """(1 − t)·``before`` + t·``matched`` for t = ``strength`` in [0, 1]; t = 0 gives ``before`` and t = 1 ``matched``
    bit for bit (copies)."""
    if strength <= 0.0:
        return before.clone()
    if strength >= 1.0:
        return matched.clone()
    return torch.lerp(before, matched, float(strength))


class ColourMatch(Phase):
    """One colour match of the (selected) Gaussians' colours: c_gt -> c_s before stylization, c_s -> c_s after.

    The final match (``final``) is applied at ``settings.palette_match`` = t: c_s = (1 − t)·before + t·matched,
    ``before`` the colours the stylization (and its levels) left, ``matched`` what the full match gives (with keep
    colours: the luminance match, chroma restored). Both are kept, so a finished run takes a new strength at once
    (``reapply``) without fitting the match again; checkpoints keep them too."""

    def __init__(self, run, final: bool = False) -> None:
        super().__init__(run)
        self.final = final
        self.name = "finish" if final else "colour_match"
        self.done = False
        self.before: torch.Tensor | None = None  # the final match's input and full output (kept once it ran)
        self.matched: torch.Tensor | None = None
        self.applied = 1.0  # the strength c_s holds now

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
            A, b = transfer(run, *self.renders())
            source = run.c_s.detach().clone()
        else:
            if run.active.region:
                run.region_coverage = [run.selected_weight(v) for v in range(len(run.cameras))]
            A, b = match_content_targets(run)
            source = run.gt_rgb().to(torch.float32)
        matched = matched_colours(run, source, A, b)
        run.c_s = run.active.keep_unselected(matched, source)  # outside a region the colours stay
        if keep:
            run.restore_chroma()
        self.done = True
        if not self.final:
            return self.report(colours_changed=True, message="colours matched to the style")
        self.before, self.matched = source, run.c_s.detach().clone()
        self.applied = float(run.settings.palette_match)
        run.c_s = blend_colours(self.before, self.matched, self.applied)
        what = "luminance (colours kept)" if keep else "style"
        strength = "" if self.applied == 1.0 else f" at strength {self.applied:g}"
        return self.report(colours_changed=True, message=f"final colour match to the {what}{strength}")

    def reapply(self, strength: float) -> bool:
        """A finished final match blended again at ``strength``: c_s takes the new blend and True, when c_s is still
        the blend this phase left (no refine, keep colours switch or resumed step changed it since); else False and
        nothing changes (the strength applies when the final match runs next)."""
        if not (self.final and self.done) or self.before is None or self.matched is None:
            return False
        run = self.run
        if self.before.shape != run.c_s.shape or not torch.equal(
                run.c_s, blend_colours(self.before, self.matched, self.applied)):
            return False
        self.applied = float(strength)
        run.c_s = blend_colours(self.before, self.matched, self.applied)
        return True

    def reopen(self) -> None:
        """The final match is due again (a finer level was added after it): it runs anew at its end."""
        self.done = False
        self.before = self.matched = None

    def renders(self) -> tuple[list[torch.Tensor], list[torch.Tensor]]:
        """The stylized renders of the training views and what of each the scene (or the region) covers."""
        run = self.run
        images = [run.render(v) for v in range(len(run.cameras))]
        if run.active.region:
            return images, [run.selected_weight(v) for v in range(len(run.cameras))]
        return images, [1.0 - run.cache(v).t_final for v in range(len(run.cameras))]

    def state_dict(self) -> dict:
        kept = {} if self.before is None else {"before": self.before.clone(), "matched": self.matched.clone(),
                                               "applied": self.applied}
        return {**super().state_dict(), "done": self.done, **kept}

    def load_state_dict(self, state: dict) -> None:
        """Restore ``state_dict()``; a checkpoint written before the palette match kept none of its colours: the
        run resumes, and a finished one takes a new strength only after its final match runs again."""
        super().load_state_dict(state)
        self.done = bool(state["done"])
        before, matched = state.get("before"), state.get("matched")
        if before is None or matched is None:
            self.before = self.matched = None
            return
        self.before, self.matched = torch.as_tensor(before).clone(), torch.as_tensor(matched).clone()
        self.applied = float(state.get("applied", 1.0))
