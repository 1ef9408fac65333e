"""Moment matching: groups of Gaussians merged into one parent each that keeps their weight, mean and covariance.

Each child i weighs wᵢ = αᵢ·(s₀s₁ + s₀s₂ + s₁s₂) (opacity × surface area, as hierarchical 3D Gaussians and
splat-transform's decimation weigh them); with ŵᵢ = wᵢ / Σw the parent has mean μ = Σŵᵢμᵢ, covariance
Σ = Σŵᵢ(Σᵢ + δᵢδᵢᵀ) with δᵢ = μᵢ − μ, colour (every SH coefficient) Σŵᵢcᵢ, scales and rotation from Σ's
eigen-decomposition and opacity min(1, Σw / its own area). A group whose weights are all 0 is weighed evenly.
Everything is computed in float64 and written as float32.
"""

from __future__ import annotations

import numpy as np

from ..scene import GaussianScene, logit, sigmoid

MIN_VARIANCE = 1e-24  # an eigenvalue floor (σ 1e-12 scene units): a degenerate group stays a valid Gaussian
OPACITY_EPS = 1e-6


def rotation_matrices(quats: np.ndarray) -> np.ndarray:
    """Rotation matrices [N, 3, 3] of wxyz quaternions (normalised here; a zero or non-finite one is the identity)."""
    q = np.nan_to_num(np.asarray(quats, np.float64), nan=0.0, posinf=0.0, neginf=0.0)
    norm = np.linalg.norm(q, axis=1, keepdims=True)
    bad = norm[:, 0] < 1e-12
    q = np.where(bad[:, None], np.array([1.0, 0.0, 0.0, 0.0]), q / np.where(bad[:, None], 1.0, norm))
    w, x, y, z = q.T
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], axis=-1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], axis=-1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=-1),
    ], axis=1)


def covariances(log_scales: np.ndarray, quats: np.ndarray) -> np.ndarray:
    """Covariance matrices R·diag(s²)·Rᵀ, float64 [N, 3, 3]."""
    rot = rotation_matrices(quats)
    var = np.exp(2.0 * np.clip(np.asarray(log_scales, np.float64), -60.0, 60.0))
    return np.einsum("nij,nj,nkj->nik", rot, var, rot)


def surface_areas(scales: np.ndarray) -> np.ndarray:
    """s₀s₁ + s₀s₂ + s₁s₂ of each row of per-axis standard deviations [N, 3] (float64 [N])."""
    s = np.asarray(scales, np.float64)
    return s[:, 0] * s[:, 1] + s[:, 0] * s[:, 2] + s[:, 1] * s[:, 2]


def gaussian_weights(log_scales: np.ndarray, opacity_logits: np.ndarray) -> np.ndarray:
    """Each Gaussian's merge weight: opacity × surface area (float64 [N], finite, ≥ 0)."""
    area = surface_areas(np.exp(np.clip(np.asarray(log_scales, np.float64), -60.0, 60.0)))
    w = sigmoid(np.asarray(opacity_logits, np.float64)).astype(np.float64) * area
    return np.nan_to_num(w, nan=0.0, posinf=0.0, neginf=0.0)


def matrices_to_quats(rot: np.ndarray) -> np.ndarray:
    """wxyz unit quaternions of rotation matrices [N, 3, 3] (the largest of the four candidates, for stability)."""
    m = np.asarray(rot, np.float64)
    tr = m[:, 0, 0] + m[:, 1, 1] + m[:, 2, 2]
    cand = np.stack([
        np.stack([1 + tr, m[:, 2, 1] - m[:, 1, 2], m[:, 0, 2] - m[:, 2, 0], m[:, 1, 0] - m[:, 0, 1]], -1),
        np.stack([m[:, 2, 1] - m[:, 1, 2], 1 + m[:, 0, 0] - m[:, 1, 1] - m[:, 2, 2], m[:, 0, 1] + m[:, 1, 0],
                  m[:, 0, 2] + m[:, 2, 0]], -1),
        np.stack([m[:, 0, 2] - m[:, 2, 0], m[:, 0, 1] + m[:, 1, 0], 1 - m[:, 0, 0] + m[:, 1, 1] - m[:, 2, 2],
                  m[:, 1, 2] + m[:, 2, 1]], -1),
        np.stack([m[:, 1, 0] - m[:, 0, 1], m[:, 0, 2] + m[:, 2, 0], m[:, 1, 2] + m[:, 2, 1],
                  1 - m[:, 0, 0] - m[:, 1, 1] + m[:, 2, 2]], -1),
    ], axis=1)  # [N, 4 candidates, 4]: each is 4·q·(its largest component)
    best = np.argmax(cand[:, np.arange(4), np.arange(4)], axis=1)  # 4·q_k², the largest component's candidate
    q = cand[np.arange(len(m)), best]
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return q * np.where(q[:, :1] < 0, -1.0, 1.0)


def _group_sum(groups: np.ndarray, values: np.ndarray, n_groups: int) -> np.ndarray:
    """Σ over each group of ``values`` [N, ...] (float64 [G, ...])."""
    flat = values.reshape(len(values), int(np.prod(values.shape[1:])))
    out = np.stack([np.bincount(groups, weights=flat[:, k], minlength=n_groups).astype(np.float64)
                    for k in range(flat.shape[1])], -1) if flat.shape[1] else np.zeros((n_groups, 0))
    return out.reshape((n_groups,) + values.shape[1:])


def merge_groups(scene: GaussianScene, groups: np.ndarray, n_groups: int) -> tuple[GaussianScene, np.ndarray]:
    """One parent per group of ``scene``'s Gaussians (``groups``: int [N] in [0, n_groups), every group non-empty):
    the parents as a scene (its SH degree) and each parent's total weight Σw (float64 [G])."""
    groups = np.asarray(groups, np.int64)
    w = gaussian_weights(scene.log_scales, scene.opacity_logits)
    total = np.bincount(groups, weights=w, minlength=n_groups).astype(np.float64)
    empty = total <= 0  # every child transparent or flat: weigh them evenly
    if empty.any():
        w = np.where(empty[groups], 1.0, w)
        total = np.bincount(groups, weights=w, minlength=n_groups).astype(np.float64)
    share = w / total[groups]  # ŵᵢ
    means = np.nan_to_num(np.asarray(scene.means, np.float64))
    mean = _group_sum(groups, means * share[:, None], n_groups)
    delta = means - mean[groups]
    cov_i = covariances(scene.log_scales, scene.quats) + delta[:, :, None] * delta[:, None, :]
    cov = _group_sum(groups, cov_i * share[:, None, None], n_groups)
    cov = 0.5 * (cov + np.transpose(cov, (0, 2, 1)))
    var, vec = np.linalg.eigh(cov)
    vec[:, :, 2] *= np.sign(np.linalg.det(vec))[:, None]  # a proper rotation (det +1)
    scales = np.sqrt(np.maximum(var, MIN_VARIANCE))
    alpha = np.clip(total_weight_alpha(total, scales, empty), OPACITY_EPS, 1.0 - OPACITY_EPS)
    sh_dc = _group_sum(groups, np.asarray(scene.sh_dc, np.float64) * share[:, None], n_groups)
    rest = np.asarray(scene.sh_rest, np.float64)
    sh_rest = (_group_sum(groups, rest * share[:, None, None], n_groups) if rest.shape[1]
               else np.zeros((n_groups, 0, 3)))
    parents = GaussianScene(mean.astype(np.float32), np.log(scales).astype(np.float32),
                            matrices_to_quats(vec).astype(np.float32), logit(alpha),
                            sh_dc.astype(np.float32), sh_rest.astype(np.float32))
    return parents, total


def total_weight_alpha(total: np.ndarray, scales: np.ndarray, evenly: np.ndarray | None = None) -> np.ndarray:
    """A parent's opacity: its children's total weight over its own surface area, at most 1 (``evenly``: groups
    weighed evenly because every weight was 0 keep a faint opacity)."""
    area = surface_areas(scales)
    alpha = np.minimum(1.0, np.divide(total, area, out=np.zeros_like(total), where=area > 0))
    return alpha if evenly is None else np.where(evenly, OPACITY_EPS, alpha)
