"""The 3D half of the rasterizer: project Gaussians to screen-space ellipses (vectorised torch, autograd).

This is the readable torch twin of ``projection_kernels.py``: for float32 inputs both backends run those numba
kernels (forward and backward), for float64 this code; either way the two backends share one projection, so they
agree on means2d, conics, radii and culling bit for bit (``tests/test_raster_projection.py``: kernels vs twin).
Maths follows Kerbl et al. 2023 (EWA splatting with the 3DGS clamp and a 0.3 px low-pass dilation);
see ``gstyle_core/raster/__init__.py`` for the pixel convention.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch
from torch import Tensor

LOW_PASS_DILATION = 0.3
FOV_CLAMP_MARGIN = 0.3  # the 3DGS clamp: |x/z| <= 1.3 * tan(half fov) for a centred principal point
MAX_RADIUS = 2.0**30  # radii are clamped here so they fit an int32 (such a Gaussian covers any screen)
MAX_SCALE = 1e20  # larger scales are clamped here: the 2D covariance would overflow (and such a Gaussian
# covers any screen at any depth up to ``far`` anyway)
QUAT_MIN = 1e-10  # a quaternion whose largest |component| is at most this is the identity (zero gradient)


@dataclass
class Projected:
    """Per-Gaussian screen-space quantities (culled Gaussians carry harmless placeholder values)."""

    means2d: Tensor  # [N, 2] pixel coordinates (0 for culled Gaussians)
    conics: Tensor  # [N, 3] upper triangle (a, b, c) of the inverse 2D covariance
    depths: Tensor  # [N] camera z
    radii: Tensor  # [N] int32 pixel radius, 0 = culled
    visible: Tensor  # [N] bool
    tile_min: Tensor  # [N, 2] int64 first tile (x, y) touched, inclusive
    tile_max: Tensor  # [N, 2] int64 last tile (x, y) touched, exclusive
    tiles_x: int
    tiles_y: int


def _rotation_entries(quats: Tensor) -> list[Tensor]:
    """Row-major entries of the rotation matrices of wxyz quaternions [N, 4] (any length; 0 -> identity)."""
    q = quats.t().contiguous()  # [4, N]: contiguous rows make the per-component ops fast
    # Divide by the largest component before squaring: |q|^2 is then in [1, 4], so huge quaternions do not
    # overflow nor tiny ones underflow, and float32 and float64 agree on which ones are degenerate.
    big = q.abs().amax(0, keepdim=True)
    degenerate = big <= QUAT_MIN
    q = q / torch.where(degenerate, torch.ones_like(big), big)
    norm_sq = (q * q).sum(0, keepdim=True)
    q = q / torch.sqrt(torch.where(degenerate, torch.ones_like(norm_sq), norm_sq))
    identity = torch.zeros_like(q)
    identity[0] = 1.0
    q = torch.where(degenerate, identity, q)
    w, x, y, z = q.unbind(0)
    return [
        1 - 2 * (y * y + z * z),
        2 * (x * y - w * z),
        2 * (x * z + w * y),
        2 * (x * y + w * z),
        1 - 2 * (x * x + z * z),
        2 * (y * z - w * x),
        2 * (x * z - w * y),
        2 * (y * z + w * x),
        1 - 2 * (x * x + y * y),
    ]


def quat_to_rotmat(quats: Tensor) -> Tensor:
    """Rotation matrices [N, 3, 3] from wxyz quaternions [N, 4] of any length (zero gives identity)."""
    return torch.stack(_rotation_entries(quats), -1).reshape(-1, 3, 3)


def covariance_3d(quats: Tensor, scales: Tensor) -> Tensor:
    """World-space covariances R S S^T R^T, [N, 3, 3]."""
    m = quat_to_rotmat(quats) * scales[:, None, :]
    return m @ m.transpose(1, 2)


def project_gaussians(
    means: Tensor,
    quats: Tensor,
    scales: Tensor,
    viewmat: Tensor,
    K: Tensor,
    width: int,
    height: int,
    near: float = 0.01,
    far: float = 1e10,
    tile_size: int = 16,
) -> Projected:
    """Project Gaussians to pixel space: means2d, conics, depths, radii, culling and tile rectangles.

    The stages, in the order their autograd nodes are built (that order fixes how gradients are summed, so it is
    kept): camera space and depth culling, the EWA Jacobian's rows, the 2D covariance, its inverse (the conic),
    the screen radius, the projected centre, the tile rectangles and visibility.
    """
    dtype = means.dtype
    viewmat = viewmat.to(dtype=dtype, device=means.device).detach()
    K = K.to(dtype=dtype, device=means.device).detach()
    fx, fy, cx, cy = (float(K[0, 0]), float(K[1, 1]), float(K[0, 2]), float(K[1, 2]))
    cam = _to_camera(means, viewmat, fx, fy, cx, cy, near, far)
    t_x, t_y, inv_z = _jacobian_rows(cam, viewmat[:3, :3], fx, fy, cx, cy, width, height)
    a, b, c, det = _covariance_2d(t_x, t_y, quats, scales)
    det_ok = (det > 0) & torch.isfinite(det) & torch.isfinite(a + c)
    det_safe = torch.where(det_ok, det, torch.ones_like(det))
    inv_det = 1.0 / det_safe
    conics = torch.stack([c * inv_det, -b * inv_det, a * inv_det], -1).to(dtype)
    radius = _screen_radius(a, c, det_safe)
    means2d = torch.stack([fx * cam.x * inv_z + cx, fy * cam.y * inv_z + cy], -1)
    tiles = _tile_rectangles(means2d, radius, cam.in_depth & det_ok, width, height, tile_size)
    means2d = torch.where(tiles.visible[:, None], means2d, torch.zeros_like(means2d))
    return Projected(means2d, conics, cam.z, tiles.radii, tiles.visible, tiles.tile_min, tiles.tile_max,
                     tiles.tiles_x, tiles.tiles_y)


@dataclass
class _CameraSpace:
    """Camera-space centres: ``z`` as computed (the depths), and x, y, z with the culled entries made harmless."""

    x: Tensor
    y: Tensor
    z: Tensor
    z_safe: Tensor
    in_depth: Tensor  # [N] bool: between near and far, finite, and projecting inside the float range


def _to_camera(means: Tensor, viewmat: Tensor, fx: float, fy: float, cx: float, cy: float, near: float,
               far: float) -> _CameraSpace:
    """World to camera; culls by depth and the centres that project beyond the float range."""
    p_cam = torch.addmm(viewmat[:3, 3:4], viewmat[:3, :3], means.t())  # [3, N]
    x, y, z = p_cam.unbind(0)
    in_depth = (z > near) & (z <= far) & torch.isfinite(p_cam).all(0)
    with torch.no_grad():  # centres that project beyond the float range are culled before they enter the graph
        in_depth &= torch.isfinite(fx * x * (1.0 / z) + cx) & torch.isfinite(fy * y * (1.0 / z) + cy)
    z_safe = torch.where(in_depth, z, torch.ones_like(z))
    x_safe = torch.where(in_depth, x, torch.zeros_like(x))
    y_safe = torch.where(in_depth, y, torch.zeros_like(y))
    return _CameraSpace(x_safe, y_safe, z, z_safe, in_depth)


def _jacobian_rows(cam: _CameraSpace, rot_view: Tensor, fx: float, fy: float, cx: float, cy: float, width: int,
                   height: int) -> tuple[list[Tensor], list[Tensor], Tensor]:
    """The two rows of J W (J: EWA Jacobian at the mean, W: the view rotation) per component, and 1 / z.

    J takes the 3DGS field-of-view clamp (gsplat's form for an off-centre principal point; it equals 3DGS's
    1.3 * tan(fov/2) when cx = width/2, cy = height/2).
    """
    z_safe = cam.z_safe
    tan_fov_x, tan_fov_y = 0.5 * width / fx, 0.5 * height / fy
    lim_x_pos = (width - cx) / fx + FOV_CLAMP_MARGIN * tan_fov_x
    lim_x_neg = cx / fx + FOV_CLAMP_MARGIN * tan_fov_x
    lim_y_pos = (height - cy) / fy + FOV_CLAMP_MARGIN * tan_fov_y
    lim_y_neg = cy / fy + FOV_CLAMP_MARGIN * tan_fov_y
    tx = z_safe * torch.clamp(cam.x / z_safe, -lim_x_neg, lim_x_pos)
    ty = z_safe * torch.clamp(cam.y / z_safe, -lim_y_neg, lim_y_pos)
    inv_z = 1.0 / z_safe
    w = [[float(v) for v in row] for row in rot_view]
    jx, jxz = fx * inv_z, -fx * tx * inv_z * inv_z
    jy, jyz = fy * inv_z, -fy * ty * inv_z * inv_z
    t_x = [jx * w[0][k] + jxz * w[2][k] for k in range(3)]  # first row of J W
    t_y = [jy * w[1][k] + jyz * w[2][k] for k in range(3)]
    return t_x, t_y, inv_z


def _covariance_2d(t_x: list[Tensor], t_y: list[Tensor], quats: Tensor, scales: Tensor
                   ) -> tuple[Tensor, Tensor, Tensor, Tensor]:
    """Sigma_2D = G G^T + dilation with G = J W R S [N, 2, 3]: its entries (a, b, c) and determinant, float64.

    Written per component on [N] tensors (much faster in torch than batched 3x3 products); float64 because huge
    scales close to the camera would overflow float32. The determinant is |g_x x g_y|^2 (Cauchy-Binet) plus the
    dilation terms: positive, and free of cancellation.
    """
    r = _rotation_entries(quats)
    sx, sy, sz = scales.clamp(max=MAX_SCALE).t().contiguous().unbind(0)
    rs = [r[3 * i + k] * s_k for i in range(3) for k, s_k in enumerate((sx, sy, sz))]  # R S, row-major
    g_x = [(t_x[0] * rs[k] + t_x[1] * rs[3 + k] + t_x[2] * rs[6 + k]).to(torch.float64) for k in range(3)]
    g_y = [(t_y[0] * rs[k] + t_y[1] * rs[3 + k] + t_y[2] * rs[6 + k]).to(torch.float64) for k in range(3)]
    a = g_x[0] * g_x[0] + g_x[1] * g_x[1] + g_x[2] * g_x[2] + LOW_PASS_DILATION
    b = g_x[0] * g_y[0] + g_x[1] * g_y[1] + g_x[2] * g_y[2]
    c = g_y[0] * g_y[0] + g_y[1] * g_y[1] + g_y[2] * g_y[2] + LOW_PASS_DILATION
    cross = [
        g_x[1] * g_y[2] - g_x[2] * g_y[1],
        g_x[2] * g_y[0] - g_x[0] * g_y[2],
        g_x[0] * g_y[1] - g_x[1] * g_y[0],
    ]
    det = cross[0] * cross[0] + cross[1] * cross[1] + cross[2] * cross[2]
    return a, b, c, det + LOW_PASS_DILATION * (a + c) - LOW_PASS_DILATION**2


@torch.no_grad()
def _screen_radius(a: Tensor, c: Tensor, det_safe: Tensor) -> Tensor:
    """Pixel radius ceil(3 sqrt(largest eigenvalue)) of the 2D covariances (float64, at most ``MAX_RADIUS``)."""
    mid = 0.5 * (a + c)
    lambda_max = mid + torch.sqrt(torch.clamp(mid * mid - det_safe, min=0.1))
    radius_f = torch.ceil(3.0 * torch.sqrt(lambda_max)).clamp(max=MAX_RADIUS)
    return torch.nan_to_num(radius_f, nan=0.0, posinf=MAX_RADIUS)


@dataclass
class _Tiles:
    """The tile rectangles [tile_min, tile_max) of each Gaussian, its radius and whether it is visible."""

    tile_min: Tensor
    tile_max: Tensor
    radii: Tensor
    visible: Tensor
    tiles_x: int
    tiles_y: int


@torch.no_grad()
def _tile_rectangles(means2d: Tensor, radius_f: Tensor, kept: Tensor, width: int, height: int,
                     tile_size: int) -> _Tiles:
    """Tiles touched by each square of half-side ``radius_f`` around its centre; visible = ``kept`` (depth and
    covariance tests passed) and touching a tile with a finite centre. Culled ones get radius 0, no tiles."""
    tiles_x = math.ceil(width / tile_size)
    tiles_y = math.ceil(height / tile_size)
    m64 = means2d.detach().to(torch.float64)
    lo = torch.floor((m64 - radius_f[:, None]) / tile_size)
    hi = torch.ceil((m64 + radius_f[:, None]) / tile_size)
    limits = torch.tensor([tiles_x, tiles_y], dtype=torch.float64, device=m64.device)
    tile_min = torch.minimum(lo.clamp(min=0), limits).nan_to_num(0).to(torch.int64)
    tile_max = torch.minimum(hi.clamp(min=0), limits).nan_to_num(0).to(torch.int64)
    touches = ((tile_max - tile_min).prod(-1) > 0) & (radius_f > 0)
    visible = kept & touches & torch.isfinite(means2d.detach()).all(-1)
    radii = torch.where(visible, radius_f, torch.zeros_like(radius_f)).to(torch.int32)
    tile_max = torch.where(visible[:, None], tile_max, tile_min)
    return _Tiles(tile_min, tile_max, radii, visible, tiles_x, tiles_y)
