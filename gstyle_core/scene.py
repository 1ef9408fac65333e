"""The in-memory Gaussian scene shared by IO, the rasterizer, the stylizer and the viewer.

Conventions (those of the reference 3DGS code and its ``.ply``):
- ``means``: [N, 3] world positions.
- ``log_scales``: [N, 3] natural log of the per-axis standard deviations.
- ``quats``: [N, 4] rotation quaternions, (w, x, y, z), unit length after validation.
- ``opacity_logits``: [N] inverse-sigmoid of opacity.
- ``sh_dc``: [N, 3] degree-0 SH coefficients; colour = 0.5 + SH_C0 * sh_dc.
- ``sh_rest``: [N, K, 3] higher SH coefficients, K = (degree + 1)^2 - 1 (K = 0 for degree 0).
All arrays are float32 numpy arrays.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

SH_C0 = 0.28209479177387814


def sh_degree_from_rest_count(k: int) -> int:
    """Return the SH degree for K higher coefficients per channel (0, 3, 8, 15)."""
    for degree in range(4):
        if (degree + 1) ** 2 - 1 == k:
            return degree
    raise ValueError(f"{k} higher SH coefficients per channel match no SH degree (0, 3, 8 or 15 expected)")


def used_sh_degree(sh_rest) -> int:
    """The lowest SH degree that keeps every non-zero coefficient of ``sh_rest`` [N, K, 3] (numpy or torch).

    Higher bands that are all zero add exactly nothing to a colour, so evaluating them can be skipped.
    """
    rest = np.asarray(sh_rest)
    degree = 0
    for d in range(1, 4):
        lo, hi = d * d - 1, (d + 1) ** 2 - 1
        if rest.ndim == 3 and rest.shape[1] >= hi and np.any(rest[:, lo:hi] != 0):
            degree = d
    return degree


def rgb_to_sh_dc(rgb: np.ndarray) -> np.ndarray:
    """Convert linear colour in [0, 1] to degree-0 SH coefficients."""
    return ((np.asarray(rgb, np.float32) - 0.5) / SH_C0).astype(np.float32)


def sh_dc_to_rgb(sh_dc: np.ndarray) -> np.ndarray:
    """Convert degree-0 SH coefficients to colour (not clipped)."""
    return (0.5 + SH_C0 * np.asarray(sh_dc, np.float32)).astype(np.float32)


def sigmoid(x: np.ndarray) -> np.ndarray:
    """Numerically stable logistic function."""
    x = np.asarray(x, np.float64)
    out = np.empty_like(x)
    pos = x >= 0
    out[pos] = 1.0 / (1.0 + np.exp(-x[pos]))
    ex = np.exp(x[~pos])
    out[~pos] = ex / (1.0 + ex)
    return out.astype(np.float32)


def logit(p: np.ndarray, eps: float = 1e-6) -> np.ndarray:
    """Inverse sigmoid with clamping away from 0 and 1."""
    p = np.clip(np.asarray(p, np.float64), eps, 1.0 - eps)
    return np.log(p / (1.0 - p)).astype(np.float32)


@dataclass
class GaussianScene:
    """A set of 3D Gaussians (see module docstring for conventions)."""

    means: np.ndarray
    log_scales: np.ndarray
    quats: np.ndarray
    opacity_logits: np.ndarray
    sh_dc: np.ndarray
    sh_rest: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 3), np.float32))

    def __post_init__(self) -> None:
        n = len(self.means)
        if self.sh_rest.size == 0 and self.sh_rest.shape[0] != n:
            self.sh_rest = np.zeros((n, 0, 3), np.float32)

    @property
    def count(self) -> int:
        """Number of Gaussians."""
        return int(self.means.shape[0])

    def __len__(self) -> int:
        return self.count

    @property
    def sh_degree(self) -> int:
        """SH degree (0-3) implied by ``sh_rest``."""
        return sh_degree_from_rest_count(self.sh_rest.shape[1])

    @property
    def rgb(self) -> np.ndarray:
        """Diffuse (view-independent) colour, [N, 3], not clipped."""
        return sh_dc_to_rgb(self.sh_dc)

    @property
    def opacities(self) -> np.ndarray:
        """Opacity in [0, 1], [N]."""
        return sigmoid(self.opacity_logits)

    @property
    def scales(self) -> np.ndarray:
        """Per-axis standard deviations, [N, 3]."""
        return np.exp(self.log_scales).astype(np.float32)

    def subset(self, index: np.ndarray) -> GaussianScene:
        """Return the Gaussians selected by a boolean mask or index array."""
        return GaussianScene(
            means=self.means[index].copy(),
            log_scales=self.log_scales[index].copy(),
            quats=self.quats[index].copy(),
            opacity_logits=self.opacity_logits[index].copy(),
            sh_dc=self.sh_dc[index].copy(),
            sh_rest=self.sh_rest[index].copy(),
        )

    def with_sh_degree(self, degree: int) -> GaussianScene:
        """Return a copy truncated (or zero-padded) to the given SH degree."""
        k = (degree + 1) ** 2 - 1
        rest = np.zeros((self.count, k, 3), np.float32)
        keep = min(k, self.sh_rest.shape[1])
        rest[:, :keep] = self.sh_rest[:, :keep]
        return GaussianScene(
            self.means.copy(),
            self.log_scales.copy(),
            self.quats.copy(),
            self.opacity_logits.copy(),
            self.sh_dc.copy(),
            rest,
        )

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Axis-aligned bounding box (min, max) of the means."""
        if self.count == 0:
            z = np.zeros(3, np.float32)
            return z, z
        return self.means.min(axis=0), self.means.max(axis=0)

    @staticmethod
    def empty(sh_degree: int = 0) -> GaussianScene:
        """A scene with no Gaussians."""
        k = (sh_degree + 1) ** 2 - 1
        return GaussianScene(
            np.zeros((0, 3), np.float32),
            np.zeros((0, 3), np.float32),
            np.zeros((0, 4), np.float32),
            np.zeros((0,), np.float32),
            np.zeros((0, 3), np.float32),
            np.zeros((0, k, 3), np.float32),
        )

    @staticmethod
    def concatenate(scenes: list[GaussianScene]) -> GaussianScene:
        """Concatenate scenes of the same SH degree."""
        return GaussianScene(
            *(np.concatenate([getattr(s, f) for s in scenes]) for f in
              ("means", "log_scales", "quats", "opacity_logits", "sh_dc", "sh_rest"))
        )


def importance_order(log_scales: np.ndarray, opacity_logits: np.ndarray) -> np.ndarray:
    """int32 Gaussian indices by opacity × area of their two largest axes, most important first.

    The view-independent order in which the viewer's reduced-detail frames keep Gaussians and a run larger than it
    can hold picks the Gaussians it stylizes (``engine/capacity.py``): small faint ones go first; the ``keep``
    most important are its first ``keep`` entries."""
    s = np.sort(np.nan_to_num(np.asarray(log_scales, np.float64), nan=-30.0, posinf=30.0, neginf=-30.0), axis=1)
    score = (s[:, 1] + s[:, 2]) + np.log(sigmoid(np.asarray(opacity_logits, np.float64)) + 1e-12)
    return np.argsort(-score, kind="stable").astype(np.int32)
