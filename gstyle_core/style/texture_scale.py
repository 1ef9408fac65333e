"""Texture scale: how the detail energy of an image splits between fine, middle and coarse bands.

The figure answers "are the strokes that stylization added the painting's size?" by comparing two spectra in the
same pixel units:

* the **added texture**: ``after − before`` of the same views (the stylized render minus the input render), and
* the **painting** resized to the size at which it is matched (``matched_side``).

Definition (the one issue #23 measured with):

1. Per colour channel (R, G, B, each in [0, 1]; no conversion to grey), a difference-of-Gaussians band
   ``B_k = G_{σ_k} * x − G_{σ_{k+1}} * x`` for the edges σ = 0.5, 1.5, 4, 10 px (``BAND_EDGES``): fine
   (0.5–1.5 px), middle (1.5–4 px), coarse (4–10 px). The Gaussians are sampled to ±4σ and the image is extended
   by symmetric reflection at its border (scipy.ndimage's default, which the issue's numbers were taken with).
2. Energy of band k: ``E_k = Σ_pixels w(p) · Σ_channels B_k(p)²``. The weight ``w`` is the scene's coverage
   (rendered alpha in [0, 1]) for the added texture; the filters run over the whole frame first, then the mask
   weights the squared responses (so the silhouette's own step stays in, as the eye sees it). The painting is
   measured unweighted over its whole area.
3. Shares: ``E_k / (E_fine + E_middle + E_coarse)``; they sum to 1 (all 0 for an image without detail).

Measured against the issue's numbers (see ``docs/notes/texture-scale.md``): demo × The Starry Night's added texture
0.468 / 0.278 / 0.255 (issue: 0.46 / 0.28 / 0.26). The Starry Night at 256 px gives 0.346 / 0.262 / 0.392 with the
engine's own resize (antialiased bicubic, what VGG sees); the issue's 0.38 / 0.25 / 0.37 is the same measure on a
Lanczos resize (0.378 / 0.250 / 0.372).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import torch
import torch.nn.functional as F

BAND_EDGES = (0.5, 1.5, 4.0, 10.0)  # σ in pixels: fine = 0.5–1.5, middle = 1.5–4, coarse = 4–10
BAND_NAMES = ("fine", "middle", "coarse")
TRUNCATE = 4.0  # Gaussian kernels are cut at ±4σ (as scipy.ndimage.gaussian_filter)
NO_DETAIL = 1e-20  # total energy below this is round-off (one 8-bit step on one pixel gives ~1e-6): no shares


def _symmetric_indices(n: int, pad: int) -> torch.Tensor:
    """Indices of a length-``n`` axis extended by ``pad`` on each side with symmetric reflection (d c b a | a b c d),
    valid for any ``pad`` (reflections repeat)."""
    idx = torch.arange(-pad, n + pad)
    period = 2 * n
    idx = torch.remainder(idx, period)
    return torch.where(idx >= n, period - 1 - idx, idx)


def _kernel(sigma: float) -> torch.Tensor:
    radius = int(TRUNCATE * sigma + 0.5)
    x = torch.arange(-radius, radius + 1, dtype=torch.float64)
    k = torch.exp(-0.5 * (x / sigma) ** 2)
    return k / k.sum()


def gaussian_blur(planes: torch.Tensor, sigma: float) -> torch.Tensor:
    """Separable Gaussian blur of ``planes`` [C, H, W] (in their dtype), symmetric border, kernel cut at ±4σ."""
    k = _kernel(sigma).to(planes.dtype)
    r = (len(k) - 1) // 2
    c, h, w = planes.shape
    x = planes[:, _symmetric_indices(h, r)][:, :, _symmetric_indices(w, r)]
    x = F.conv2d(x[:, None], k.view(1, 1, -1, 1))  # along H
    x = F.conv2d(x, k.view(1, 1, 1, -1))  # along W
    return x[:, 0]


def _planes(image: np.ndarray | torch.Tensor, dtype: torch.dtype = torch.float64) -> torch.Tensor:
    """[H, W], [H, W, C] → [C, H, W] in ``dtype``."""
    t = torch.as_tensor(np.asarray(image), dtype=dtype)
    if t.ndim == 2:
        return t[None]
    if t.ndim != 3:
        raise ValueError(f"expected an [H, W] or [H, W, C] image, got shape {tuple(t.shape)}")
    return t.permute(2, 0, 1).contiguous()


def band_energies(image: np.ndarray | torch.Tensor, weights: np.ndarray | torch.Tensor | None = None,
                  edges: Sequence[float] = BAND_EDGES, dtype: torch.dtype = torch.float64) -> np.ndarray:
    """Energies of the difference-of-Gaussians bands between consecutive ``edges`` (σ in px; default: fine, middle,
    coarse) of ``image`` ([H, W] or [H, W, C], channels measured separately and summed), each pixel's squared band
    responses weighted by ``weights`` [H, W] (None: 1 everywhere). ``dtype``: of the filtering (float32 is ~100×
    faster on a CPU for wide kernels; the squares are summed in float64 either way)."""
    planes = _planes(image, dtype)
    w = None
    if weights is not None:
        w = torch.as_tensor(np.asarray(weights), dtype=torch.float64).reshape(planes.shape[-2:])
        w = w.clamp(0.0, 1.0)
    blurred = [gaussian_blur(planes, s) for s in edges]
    out = np.zeros(len(edges) - 1)
    for k in range(len(out)):
        sq = ((blurred[k] - blurred[k + 1]).double() ** 2).sum(0)
        out[k] = float(sq.sum() if w is None else (sq * w).sum())
    return out


def shares(energies: np.ndarray) -> np.ndarray:
    """Energies → shares summing to 1 (zeros when there is no detail: total below ``NO_DETAIL``)."""
    e = np.asarray(energies, np.float64)
    total = e.sum()
    return e / total if total > NO_DETAIL else np.zeros_like(e)


def band_shares(image: np.ndarray | torch.Tensor, weights: np.ndarray | torch.Tensor | None = None) -> np.ndarray:
    """Shares (fine, middle, coarse) of ``image``'s detail energy (see the module docstring)."""
    return shares(band_energies(image, weights))


def added_texture_shares(before: np.ndarray, after: np.ndarray, coverage: np.ndarray | None = None) -> np.ndarray:
    """Shares of what stylization added (``after − before``, [H, W, 3] each) inside the scene (``coverage`` [H, W]
    weights; None: the whole frame)."""
    a, b = np.asarray(after, np.float64), np.asarray(before, np.float64)
    if a.shape != b.shape:
        raise ValueError(f"before {b.shape} and after {a.shape} differ in shape")
    return band_shares(a - b, coverage)


def matched_side(working_width: int, scale: float, image_width: int | None = None) -> int:
    """Long side (px) of the painting as it is matched (``style_side``: stroke size × the working width), expressed in
    the pixels of images ``image_width`` wide (default: the working width itself), so that it compares with
    renders measured at that width."""
    from .painting_size import style_side

    side, _ = style_side(working_width, scale)
    if image_width is None:
        return side
    return max(1, int(round(side * image_width / max(64, int(working_width)))))


def painting_shares(painting: np.ndarray, side: int) -> np.ndarray:
    """Shares of ``painting`` [H, W, 3] resized (as the engine resizes it) so its longer side is ``side`` px."""
    from .painting_size import resize_long_side

    return band_shares(resize_long_side(np.asarray(painting, np.float32), int(side)))


@dataclass(frozen=True)
class TextureScale:
    """The figure: band shares of the added texture and of the painting(s) at their matched size."""

    added: tuple[float, float, float]
    painting: tuple[float, float, float]
    painting_side: int

    @property
    def coarse_ratio(self) -> float:
        """Coarse share of the added texture over the painting's (1: the painting's proportion of broad detail)."""
        return self.added[2] / self.painting[2] if self.painting[2] > 0 else float("nan")

    def to_dict(self) -> dict:
        """For OUT.json / bench tables."""
        return {"bands_px": [list(BAND_EDGES[k:k + 2]) for k in range(3)],
                "added": dict(zip(BAND_NAMES, (round(v, 4) for v in self.added), strict=True)),
                "painting": dict(zip(BAND_NAMES, (round(v, 4) for v in self.painting), strict=True)),
                "painting_side": self.painting_side, "coarse_ratio": round(self.coarse_ratio, 4)}

    def line(self) -> str:
        """One line for the end of a run."""
        fmt = " / ".join
        return (f"texture scale (fine / middle / coarse, DoG σ 0.5-1.5 / 1.5-4 / 4-10 px): added "
                f"{fmt(f'{v:.2f}' for v in self.added)}, painting at {self.painting_side} px "
                f"{fmt(f'{v:.2f}' for v in self.painting)} (coarse {self.coarse_ratio:.2f}× the painting's)")


def added_energies(before: Sequence[np.ndarray], after: Sequence[np.ndarray],
                   coverage: Sequence[np.ndarray | None]) -> np.ndarray:
    """Band energies of ``after − before`` summed over views (one coverage weight image, or None, per view)."""
    if not (len(before) == len(after) == len(coverage)) or not before:
        raise ValueError(f"{len(before)} before, {len(after)} after and {len(coverage)} coverage image(s)")
    energy = np.zeros(3)
    for b, a, c in zip(before, after, coverage, strict=True):
        if np.shape(a) != np.shape(b):
            raise ValueError(f"before {np.shape(b)} and after {np.shape(a)} differ in shape")
        energy += band_energies(np.asarray(a, np.float64) - np.asarray(b, np.float64), c)
    return energy


def texture_scale(before: Sequence[np.ndarray] | np.ndarray, after: Sequence[np.ndarray] | np.ndarray,
                  coverage: Sequence[np.ndarray] | np.ndarray | None,
                  paintings: Sequence[np.ndarray] | np.ndarray, painting_side: int,
                  painting_weights: Sequence[float] | None = None) -> TextureScale:
    """The figure for renders of several views (lists, or one image each): the added texture's energies are summed
    over the views before the shares are taken; several paintings give the weighted mean of their shares."""
    before_l = [before] if isinstance(before, np.ndarray) else list(before)
    after_l = [after] if isinstance(after, np.ndarray) else list(after)
    cov_l = [None] * len(before_l) if coverage is None else (
        [coverage] if isinstance(coverage, np.ndarray) else list(coverage))
    energy = added_energies(before_l, after_l, cov_l)
    paint_l = [paintings] if isinstance(paintings, np.ndarray) else list(paintings)
    w = np.ones(len(paint_l)) if painting_weights is None else np.asarray(painting_weights, np.float64)
    if len(w) != len(paint_l) or not w.sum() > 0:
        raise ValueError(f"{len(w)} weight(s) for {len(paint_l)} painting(s)")
    mean = sum(wi * painting_shares(p, painting_side) for wi, p in zip(w / w.sum(), paint_l, strict=True))
    return TextureScale(tuple(float(v) for v in shares(energy)), tuple(float(v) for v in mean), int(painting_side))
