"""Multi-view consistency of a stylized scene: how much two nearby views disagree about the same surface points.

Pixels of view A that the scene covers (alpha > ``min_alpha``) are lifted to 3D with A's rendered depth,
projected into view B, and compared with B's render there (bilinear). Points that B sees behind something else
(B's own depth is nearer by more than ``occlusion_tolerance`` relative) or that fall outside B are left out.
The error is the mean absolute RGB difference of the points kept. A Gaussian scene rendered with diffuse colours
is consistent by construction up to blending and resampling; running the same measure on the input scene's renders
gives that floor, so ``stylized − input`` is what stylization added.
"""

from __future__ import annotations

import numpy as np
import torch

from gstyle_core.cameras.camera import Camera
from gstyle_core.scene import GaussianScene


def render_with_depth(scene: GaussianScene, camera: Camera) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Diffuse (SH0) render of ``scene`` from ``camera``: image [H,W,3], alpha [H,W], depth [H,W]."""
    from gstyle_core.fit.model import params_from_scene, render_params

    params = params_from_scene(scene.with_sh_degree(0), requires_grad=False)
    with torch.no_grad():
        out = render_params(params, camera, sh_degree=0, backend="fast")
    return out.image.numpy(), out.alpha.numpy(), out.depth.numpy()


def _bilinear(img: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Sample img [H, W, C] at pixel-centre coordinates (x, y) (pixel i spans [i, i+1))."""
    h, w = img.shape[:2]
    fx, fy = np.clip(x - 0.5, 0, w - 1), np.clip(y - 0.5, 0, h - 1)
    x0, y0 = np.floor(fx).astype(int), np.floor(fy).astype(int)
    x1, y1 = np.minimum(x0 + 1, w - 1), np.minimum(y0 + 1, h - 1)
    ax, ay = (fx - x0)[:, None], (fy - y0)[:, None]
    top = img[y0, x0] * (1 - ax) + img[y0, x1] * ax
    bottom = img[y1, x0] * (1 - ax) + img[y1, x1] * ax
    return top * (1 - ay) + bottom * ay


def reprojection_error(a: tuple[np.ndarray, np.ndarray, np.ndarray], cam_a: Camera,
                       b: tuple[np.ndarray, np.ndarray, np.ndarray], cam_b: Camera, *, min_alpha: float = 0.95,
                       occlusion_tolerance: float = 0.05) -> tuple[float, int]:
    """Mean |A − warp(B)| over A's covered, unoccluded pixels that land inside B; returns (error, pixels used)."""
    img_a, alpha_a, depth_a = a
    img_b, alpha_b, depth_b = b
    rows, cols = np.nonzero((alpha_a > min_alpha) & (depth_a > 0))
    if rows.size == 0:
        return float("nan"), 0
    z = depth_a[rows, cols].astype(np.float64)
    u, v = cols + 0.5, rows + 0.5
    pts_cam = np.stack([(u - cam_a.cx) / cam_a.fx * z, (v - cam_a.cy) / cam_a.fy * z, z, np.ones_like(z)])
    pts_b = (np.asarray(cam_b.world_to_cam) @ np.asarray(cam_a.cam_to_world) @ pts_cam)[:3]
    zb = pts_b[2]
    in_front = zb > 1e-6
    ub = np.where(in_front, cam_b.fx * pts_b[0] / np.maximum(zb, 1e-6) + cam_b.cx, -1.0)
    vb = np.where(in_front, cam_b.fy * pts_b[1] / np.maximum(zb, 1e-6) + cam_b.cy, -1.0)
    inside = in_front & (ub >= 0.5) & (ub <= cam_b.width - 0.5) & (vb >= 0.5) & (vb <= cam_b.height - 0.5)
    if not inside.any():
        return float("nan"), 0
    ub, vb, zb = ub[inside], vb[inside], zb[inside]
    seen_depth = _bilinear(depth_b[..., None], ub, vb)[:, 0]
    seen_alpha = _bilinear(alpha_b[..., None], ub, vb)[:, 0]
    visible = (seen_alpha > min_alpha) & (np.abs(seen_depth - zb) <= occlusion_tolerance * zb)
    if not visible.any():
        return float("nan"), 0
    colour_a = img_a[rows[inside][visible], cols[inside][visible]]
    colour_b = _bilinear(img_b, ub[visible], vb[visible])
    return float(np.abs(colour_a - colour_b).mean()), int(visible.sum())


def nearby_camera(camera: Camera, shift: float) -> Camera:
    """``camera`` moved sideways (along its image x axis) by ``shift`` world units, same orientation."""
    c2w = np.asarray(camera.cam_to_world, np.float64).copy()
    c2w[:3, 3] += c2w[:3, 0] * shift
    return Camera(camera.width, camera.height, camera.fx, camera.fy, camera.cx, camera.cy, np.linalg.inv(c2w),
                  f"{camera.name}+shift")


def view_consistency(scene: GaussianScene, pairs: list[tuple[Camera, Camera]]) -> float:
    """Mean reprojection error of ``scene`` over camera pairs (NaN when no pair shares visible points)."""
    errors = []
    for cam_a, cam_b in pairs:
        err, used = reprojection_error(render_with_depth(scene, cam_a), cam_a, render_with_depth(scene, cam_b), cam_b)
        if used:
            errors.append(err)
    return float(np.mean(errors)) if errors else float("nan")
