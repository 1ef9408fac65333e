"""Real spherical harmonics colour evaluation with the 3DGS conventions (degree 0-3, +0.5, clamp at 0)."""

from __future__ import annotations

import torch
from torch import Tensor

SH_C0 = 0.28209479177387814
SH_C1 = 0.4886025119029199
SH_C2 = (
    1.0925484305920792,
    -1.0925484305920792,
    0.31539156525252005,
    -1.0925484305920792,
    0.5462742152960396,
)
SH_C3 = (
    -0.5900435899266435,
    2.890611442640554,
    -0.4570457994644658,
    0.3731763325901154,
    -0.4570457994644658,
    1.445305721320277,
    -0.5900435899266435,
)


def sh_basis(dirs: Tensor, degree: int) -> Tensor:
    """SH basis values [N, (degree+1)^2] for unit directions [N, 3], in the 3DGS coefficient order."""
    if not 0 <= degree <= 3:
        raise ValueError(f"SH degree must be 0-3, got {degree}")
    x, y, z = dirs.unbind(-1)
    out = [torch.full_like(x, SH_C0)]
    if degree >= 1:
        out += [-SH_C1 * y, SH_C1 * z, -SH_C1 * x]
    if degree >= 2:
        xx, yy, zz, xy, yz, xz = x * x, y * y, z * z, x * y, y * z, x * z
        out += [
            SH_C2[0] * xy,
            SH_C2[1] * yz,
            SH_C2[2] * (2 * zz - xx - yy),
            SH_C2[3] * xz,
            SH_C2[4] * (xx - yy),
        ]
    if degree >= 3:
        out += [
            SH_C3[0] * y * (3 * xx - yy),
            SH_C3[1] * xy * z,
            SH_C3[2] * y * (4 * zz - xx - yy),
            SH_C3[3] * z * (2 * zz - 3 * xx - 3 * yy),
            SH_C3[4] * x * (4 * zz - xx - yy),
            SH_C3[5] * z * (xx - yy),
            SH_C3[6] * x * (xx - 3 * yy),
        ]
    return torch.stack(out, -1)


def eval_sh_colors(coeffs: Tensor, means: Tensor, camera_position: Tensor, degree: int) -> Tensor:
    """RGB [N, 3] = max(0, sum_k basis_k(dir) * coeffs[:, k] + 0.5), dir = normalised (mean - camera)."""
    needed = (degree + 1) ** 2
    if coeffs.ndim != 3 or coeffs.shape[-1] != 3 or coeffs.shape[1] < needed:
        raise ValueError(
            f"SH degree {degree} needs colors of shape [N, >={needed}, 3], got {tuple(coeffs.shape)}"
        )
    offset = means - camera_position
    dirs = offset / torch.sqrt((offset * offset).sum(-1, keepdim=True).clamp_min(1e-24))
    basis = sh_basis(dirs, degree)
    rgb = (basis[:, :, None] * coeffs[:, :needed]).sum(1) + 0.5
    return rgb.clamp_min(0.0)
