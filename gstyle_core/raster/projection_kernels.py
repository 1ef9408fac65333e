"""Numba twin of ``projection.py`` for float32 inputs (the fast backend): the projection and its backward.

Per Gaussian, in float64 inside, the same rules as the torch code (its readable twin, which the reference backend
runs): the view transform, the EWA Jacobian with the 3DGS field-of-view clamp, Sigma_2D = G G^T + 0.3 I with
G = J W R S, the conic, the 3-sigma radius, culling and tile rectangles. float32 overflow of a projected centre
culls the Gaussian as it does in torch's float32 arithmetic. The backward is the chain rule written out (the
torch twin gets it from autograd); culled Gaussians get zero gradients.
"""

from __future__ import annotations

import math

import numpy as np
import torch
from numba import njit, prange

from .projection import FOV_CLAMP_MARGIN, LOW_PASS_DILATION, MAX_RADIUS, MAX_SCALE, QUAT_MIN, Projected

FLOAT32_MAX = float(np.finfo(np.float32).max)
DIL = LOW_PASS_DILATION


@njit(cache=True, inline="always")
def _unit_quat(quats, i):  # pragma: no cover - numba
    """(w, x, y, z, |q|, degenerate) of quaternion i: normalised after division by its largest component."""
    q0, q1, q2, q3 = (np.float64(quats[i, 0]), np.float64(quats[i, 1]), np.float64(quats[i, 2]),
                      np.float64(quats[i, 3]))
    big = max(max(abs(q0), abs(q1)), max(abs(q2), abs(q3)))
    if not (big > QUAT_MIN):
        return 1.0, 0.0, 0.0, 0.0, 1.0, True
    q0, q1, q2, q3 = q0 / big, q1 / big, q2 / big, q3 / big
    n = math.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
    return q0 / n, q1 / n, q2 / n, q3 / n, n * big, False


@njit(cache=True, inline="always")
def _rotation(w, x, y, z):  # pragma: no cover - numba
    """Row-major rotation matrix entries of a unit wxyz quaternion (as ``projection._rotation_entries``)."""
    return (
        1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
        2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
        2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y),
    )


@njit(cache=True, inline="always")
def _camera_point(means, i, view):  # pragma: no cover - numba
    """Gaussian i's centre in camera coordinates (float64)."""
    mx, my, mz = np.float64(means[i, 0]), np.float64(means[i, 1]), np.float64(means[i, 2])
    x = view[0, 0] * mx + view[0, 1] * my + view[0, 2] * mz + view[0, 3]
    y = view[1, 0] * mx + view[1, 1] * my + view[1, 2] * mz + view[1, 3]
    z = view[2, 0] * mx + view[2, 1] * my + view[2, 2] * mz + view[2, 3]
    return x, y, z


@njit(cache=True)
def _jacobian_rows(view, x, y, z, fx, fy, lims):  # pragma: no cover - numba
    """The EWA Jacobian at (x, y, z) with the field-of-view clamp, times the view's rotation: T's rows t_x, t_y, and
    the clamped tx, ty they were taken at."""
    inv_z = 1.0 / z
    tx = z * min(max(x * inv_z, -lims[0]), lims[1])
    ty = z * min(max(y * inv_z, -lims[2]), lims[3])
    jx, jxz = fx * inv_z, -fx * tx * inv_z * inv_z
    jy, jyz = fy * inv_z, -fy * ty * inv_z * inv_z
    t_x = (jx * view[0, 0] + jxz * view[2, 0], jx * view[0, 1] + jxz * view[2, 1], jx * view[0, 2] + jxz * view[2, 2])
    t_y = (jy * view[1, 0] + jyz * view[2, 0], jy * view[1, 1] + jyz * view[2, 1], jy * view[1, 2] + jyz * view[2, 2])
    return t_x, t_y, tx, ty


@njit(cache=True, inline="always")
def _covariance_2d(gx0, gx1, gx2, gy0, gy1, gy2):  # pragma: no cover - numba
    """Sigma_2D = G G^T + 0.3 I from G's rows: its entries a, b, c, the cross product k of the rows and its det."""
    a = gx0 * gx0 + gx1 * gx1 + gx2 * gx2 + DIL
    b = gx0 * gy0 + gx1 * gy1 + gx2 * gy2
    c = gy0 * gy0 + gy1 * gy1 + gy2 * gy2 + DIL
    k0, k1, k2 = gx1 * gy2 - gx2 * gy1, gx2 * gy0 - gx0 * gy2, gx0 * gy1 - gx1 * gy0
    det = k0 * k0 + k1 * k1 + k2 * k2 + DIL * (a + c) - DIL * DIL
    return a, b, c, k0, k1, k2, det


@njit(cache=True, inline="always")
def _tile_rect(u32, v32, radius, tile_size, tiles_x, tiles_y):  # pragma: no cover - numba
    """The tiles a square of ``radius`` around (u, v) touches, clamped to the image: lo_x, lo_y, hi_x, hi_y
    (clamped before floor/ceil: numba's give int64, which huge values overflow)."""
    lo_x = math.floor(min(max((np.float64(u32) - radius) / tile_size, -1.0), tiles_x + 1.0))
    lo_y = math.floor(min(max((np.float64(v32) - radius) / tile_size, -1.0), tiles_y + 1.0))
    hi_x = math.ceil(min(max((np.float64(u32) + radius) / tile_size, -1.0), tiles_x + 1.0))
    hi_y = math.ceil(min(max((np.float64(v32) + radius) / tile_size, -1.0), tiles_y + 1.0))
    lo_x, lo_y = min(max(lo_x, 0), tiles_x), min(max(lo_y, 0), tiles_y)
    hi_x, hi_y = min(max(hi_x, 0), tiles_x), min(max(hi_y, 0), tiles_y)
    return lo_x, lo_y, hi_x, hi_y


@njit(parallel=True, cache=True)
def project_forward(means, quats, scales, view, intr, lims, width, height, near, far, tile_size, tiles_x,
                    tiles_y):  # pragma: no cover - numba
    """Per Gaussian: means2d [N, 2] f32, conics [N, 3] f32, depths [N] f32, radii [N] i32, visible [N] bool,
    tile_min / tile_max [N, 2] i64. ``view`` [4, 4] and ``intr`` (fx, fy, cx, cy), ``lims`` (x_neg, x_pos,
    y_neg, y_pos) float64."""
    n = means.shape[0]
    means2d = np.zeros((n, 2), np.float32)
    conics = np.zeros((n, 3), np.float32)
    depths = np.empty(n, np.float32)
    radii = np.zeros(n, np.int32)
    visible = np.zeros(n, np.bool_)
    tile_min = np.zeros((n, 2), np.int64)
    tile_max = np.zeros((n, 2), np.int64)
    fx, fy, cx, cy = intr[0], intr[1], intr[2], intr[3]
    for i in prange(n):
        x, y, z = _camera_point(means, i, view)
        depths[i] = np.float32(z)
        if not (z > near and z <= far and math.isfinite(x) and math.isfinite(y)):
            continue
        inv_z = 1.0 / z
        u = fx * x * inv_z + cx
        v = fy * y * inv_z + cy
        if not (abs(u) <= FLOAT32_MAX and abs(v) <= FLOAT32_MAX):  # beyond float32: culled, as in torch
            continue
        (t_x0, t_x1, t_x2), (t_y0, t_y1, t_y2), _, _ = _jacobian_rows(view, x, y, z, fx, fy, lims)
        qw, qx, qy, qz, _, _ = _unit_quat(quats, i)
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = _rotation(qw, qx, qy, qz)
        s0 = min(np.float64(scales[i, 0]), MAX_SCALE)
        s1 = min(np.float64(scales[i, 1]), MAX_SCALE)
        s2 = min(np.float64(scales[i, 2]), MAX_SCALE)
        gx0 = (t_x0 * r00 + t_x1 * r10 + t_x2 * r20) * s0
        gx1 = (t_x0 * r01 + t_x1 * r11 + t_x2 * r21) * s1
        gx2 = (t_x0 * r02 + t_x1 * r12 + t_x2 * r22) * s2
        gy0 = (t_y0 * r00 + t_y1 * r10 + t_y2 * r20) * s0
        gy1 = (t_y0 * r01 + t_y1 * r11 + t_y2 * r21) * s1
        gy2 = (t_y0 * r02 + t_y1 * r12 + t_y2 * r22) * s2
        a, b, c, _, _, _, det = _covariance_2d(gx0, gx1, gx2, gy0, gy1, gy2)
        if not (det > 0 and math.isfinite(det) and math.isfinite(a + c)):
            continue
        inv_det = 1.0 / det
        mid = 0.5 * (a + c)
        spread = mid * mid - det
        lambda_max = mid + math.sqrt(spread if spread > 0.1 else 0.1)
        radius = 3.0 * math.sqrt(lambda_max)
        if not (radius > 0):  # also NaN (torch: nan_to_num to 0)
            continue
        radius = np.float64(math.ceil(min(radius, MAX_RADIUS)))
        u32, v32 = np.float32(u), np.float32(v)
        lo_x, lo_y, hi_x, hi_y = _tile_rect(u32, v32, radius, tile_size, tiles_x, tiles_y)
        if not (hi_x > lo_x and hi_y > lo_y):
            continue
        visible[i] = True
        radii[i] = np.int32(radius)
        means2d[i, 0], means2d[i, 1] = u32, v32
        conics[i, 0], conics[i, 1], conics[i, 2] = c * inv_det, -b * inv_det, a * inv_det
        tile_min[i, 0], tile_min[i, 1] = lo_x, lo_y
        tile_max[i, 0], tile_max[i, 1] = hi_x, hi_y
    return means2d, conics, depths, radii, visible, tile_min, tile_max


@njit(cache=True)
def _covariance_backward(gx0, gx1, gx2, gy0, gy1, gy2, d_conic0, d_conic1, d_conic2):  # pragma: no cover - numba
    """The conic (c, -b, a) / det's gradient carried back to G's rows: dgx (3), dgy (3)."""
    a, b, c, k0, k1, k2, det = _covariance_2d(gx0, gx1, gx2, gy0, gy1, gy2)
    inv_det = 1.0 / det
    ga, gb, gc = np.float64(d_conic0), np.float64(d_conic1), np.float64(d_conic2)
    d_det = -(ga * c - gb * b + gc * a) * inv_det * inv_det
    d_a = gc * inv_det + DIL * d_det
    d_b = -gb * inv_det
    d_c = ga * inv_det + DIL * d_det
    dk0, dk1, dk2 = 2 * k0 * d_det, 2 * k1 * d_det, 2 * k2 * d_det  # d/d(g_x x g_y)
    # (u x v).w: d/du = v x w, d/dv = w x u
    dgx = (2 * gx0 * d_a + gy0 * d_b + (gy1 * dk2 - gy2 * dk1), 2 * gx1 * d_a + gy1 * d_b + (gy2 * dk0 - gy0 * dk2),
           2 * gx2 * d_a + gy2 * d_b + (gy0 * dk1 - gy1 * dk0))
    dgy = (2 * gy0 * d_c + gx0 * d_b + (dk1 * gx2 - dk2 * gx1), 2 * gy1 * d_c + gx1 * d_b + (dk2 * gx0 - dk0 * gx2),
           2 * gy2 * d_c + gx2 * d_b + (dk0 * gx1 - dk1 * gx0))
    return dgx, dgy


@njit(cache=True, inline="always")
def _camera_point_backward(view, x, y, z, tx, ty, dtx, dty, du, dv, d_depth, fx, fy, lims):  # pragma: no cover
    """The gradients of T's rows (``dtx``, ``dty``), of the projected centre (``du``, ``dv``) and of the depth,
    carried back through the clamped Jacobian and the projection to the camera point: d_x, d_y, d_z."""
    w = view
    inv_z = 1.0 / z
    ux, uy = x * inv_z, y * inv_z
    d_jx = dtx[0] * w[0, 0] + dtx[1] * w[0, 1] + dtx[2] * w[0, 2]
    d_jxz = dtx[0] * w[2, 0] + dtx[1] * w[2, 1] + dtx[2] * w[2, 2]
    d_jy = dty[0] * w[1, 0] + dty[1] * w[1, 1] + dty[2] * w[1, 2]
    d_jyz = dty[0] * w[2, 0] + dty[1] * w[2, 1] + dty[2] * w[2, 2]
    inv_z2 = inv_z * inv_z
    d_z = -fx * inv_z2 * d_jx - fy * inv_z2 * d_jy
    d_z += 2 * fx * tx * inv_z2 * inv_z * d_jxz + 2 * fy * ty * inv_z2 * inv_z * d_jyz
    d_tx = -fx * inv_z2 * d_jxz
    d_ty = -fy * inv_z2 * d_jyz
    d_x = 0.0
    d_y = 0.0
    if ux < -lims[0] or ux > lims[1]:  # clamped: tx = z * limit
        d_z += (tx * inv_z) * d_tx
    else:  # tx = x
        d_x += d_tx
    if uy < -lims[2] or uy > lims[3]:
        d_z += (ty * inv_z) * d_ty
    else:
        d_y += d_ty
    # means2d = (fx x / z + cx, fy y / z + cy), depth = z
    d_x += fx * inv_z * du
    d_y += fy * inv_z * dv
    d_z += -fx * x * inv_z2 * du - fy * y * inv_z2 * dv + d_depth
    return d_x, d_y, d_z


@njit(cache=True, inline="always")
def _quat_backward(qw, qx, qy, qz, qnorm, dr):  # pragma: no cover - numba
    """The rotation matrix's gradient ``dr`` (row-major) carried back through ``_rotation`` and the normalisation
    q / |q| to the quaternion as given."""
    d_w = 2 * (-qz * dr[1] + qy * dr[2] + qz * dr[3] - qx * dr[5] - qy * dr[6] + qx * dr[7])
    d_qx = 2 * (qy * dr[1] + qz * dr[2] + qy * dr[3] - 2 * qx * dr[4] - qw * dr[5] + qz * dr[6]
                + qw * dr[7] - 2 * qx * dr[8])
    d_qy = 2 * (-2 * qy * dr[0] + qx * dr[1] + qw * dr[2] + qx * dr[3] + qz * dr[5] - qw * dr[6]
                + qz * dr[7] - 2 * qy * dr[8])
    d_qz = 2 * (-2 * qz * dr[0] - qw * dr[1] + qx * dr[2] + qw * dr[3] - 2 * qz * dr[4] + qy * dr[5]
                + qx * dr[6] + qy * dr[7])
    dot = qw * d_w + qx * d_qx + qy * d_qy + qz * d_qz  # through the normalisation q / |q|
    return (d_w - qw * dot) / qnorm, (d_qx - qx * dot) / qnorm, (d_qy - qy * dot) / qnorm, (d_qz - qz * dot) / qnorm


@njit(parallel=True, cache=True)
def project_backward(means, quats, scales, view, intr, lims, visible, d_means2d, d_conics,
                     d_depths):  # pragma: no cover - numba
    """Gradients (means [N, 3], quats [N, 4], scales [N, 3]) float32 of ``project_forward``'s means2d, conics and
    depths; zero for culled Gaussians (their means2d are constants, their conics and depths get no gradient from
    the blend)."""
    n = means.shape[0]
    g_means = np.zeros((n, 3), np.float32)
    g_quats = np.zeros((n, 4), np.float32)
    g_scales = np.zeros((n, 3), np.float32)
    fx, fy = intr[0], intr[1]
    for i in prange(n):
        if not visible[i]:
            continue
        x, y, z = _camera_point(means, i, view)
        t_x, t_y, tx, ty = _jacobian_rows(view, x, y, z, fx, fy, lims)
        qw, qx, qy, qz, qnorm, degenerate = _unit_quat(quats, i)
        r = _rotation(qw, qx, qy, qz)
        s_raw = (np.float64(scales[i, 0]), np.float64(scales[i, 1]), np.float64(scales[i, 2]))
        s = (min(s_raw[0], MAX_SCALE), min(s_raw[1], MAX_SCALE), min(s_raw[2], MAX_SCALE))
        # M = R S (row-major m0..m8), G = T M (T rows t_x, t_y): g_x, g_y
        m0, m1, m2 = r[0] * s[0], r[1] * s[1], r[2] * s[2]
        m3, m4, m5 = r[3] * s[0], r[4] * s[1], r[5] * s[2]
        m6, m7, m8 = r[6] * s[0], r[7] * s[1], r[8] * s[2]
        (dgx0, dgx1, dgx2), (dgy0, dgy1, dgy2) = _covariance_backward(
            t_x[0] * m0 + t_x[1] * m3 + t_x[2] * m6, t_x[0] * m1 + t_x[1] * m4 + t_x[2] * m7,
            t_x[0] * m2 + t_x[1] * m5 + t_x[2] * m8, t_y[0] * m0 + t_y[1] * m3 + t_y[2] * m6,
            t_y[0] * m1 + t_y[1] * m4 + t_y[2] * m7, t_y[0] * m2 + t_y[1] * m5 + t_y[2] * m8,
            d_conics[i, 0], d_conics[i, 1], d_conics[i, 2])
        # through G = T M
        dtx = (dgx0 * m0 + dgx1 * m1 + dgx2 * m2, dgx0 * m3 + dgx1 * m4 + dgx2 * m5, dgx0 * m6 + dgx1 * m7 + dgx2 * m8)
        dty = (dgy0 * m0 + dgy1 * m1 + dgy2 * m2, dgy0 * m3 + dgy1 * m4 + dgy2 * m5, dgy0 * m6 + dgy1 * m7 + dgy2 * m8)
        dm0, dm1, dm2 = t_x[0] * dgx0 + t_y[0] * dgy0, t_x[0] * dgx1 + t_y[0] * dgy1, t_x[0] * dgx2 + t_y[0] * dgy2
        dm3, dm4, dm5 = t_x[1] * dgx0 + t_y[1] * dgy0, t_x[1] * dgx1 + t_y[1] * dgy1, t_x[1] * dgx2 + t_y[1] * dgy2
        dm6, dm7, dm8 = t_x[2] * dgx0 + t_y[2] * dgy0, t_x[2] * dgx1 + t_y[2] * dgy1, t_x[2] * dgx2 + t_y[2] * dgy2
        # through M = R S; clamped scales get no gradient
        if s_raw[0] <= MAX_SCALE:
            g_scales[i, 0] = np.float32(dm0 * r[0] + dm3 * r[3] + dm6 * r[6])
        if s_raw[1] <= MAX_SCALE:
            g_scales[i, 1] = np.float32(dm1 * r[1] + dm4 * r[4] + dm7 * r[7])
        if s_raw[2] <= MAX_SCALE:
            g_scales[i, 2] = np.float32(dm2 * r[2] + dm5 * r[5] + dm8 * r[8])
        d_x, d_y, d_z = _camera_point_backward(view, x, y, z, tx, ty, dtx, dty, np.float64(d_means2d[i, 0]),
                                               np.float64(d_means2d[i, 1]), np.float64(d_depths[i]), fx, fy, lims)
        for k in range(3):
            g_means[i, k] = np.float32(view[0, k] * d_x + view[1, k] * d_y + view[2, k] * d_z)
        if degenerate:
            continue
        dr = (dm0 * s[0], dm1 * s[1], dm2 * s[2], dm3 * s[0], dm4 * s[1], dm5 * s[2], dm6 * s[0], dm7 * s[1],
              dm8 * s[2])
        g_w, g_x, g_y, g_z = _quat_backward(qw, qx, qy, qz, qnorm, dr)
        g_quats[i, 0], g_quats[i, 1] = np.float32(g_w), np.float32(g_x)
        g_quats[i, 2], g_quats[i, 3] = np.float32(g_y), np.float32(g_z)
    return g_means, g_quats, g_scales


def camera_arrays(viewmat, K, width: int, height: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(view [4, 4], intrinsics (fx, fy, cx, cy), FOV clamp limits (x_neg, x_pos, y_neg, y_pos)), float64, as
    ``projection.project_gaussians`` derives them."""
    view = np.ascontiguousarray(viewmat.detach().to(torch.float64).cpu().numpy())
    k = K.detach().to(torch.float64).cpu().numpy()
    fx, fy, cx, cy = float(k[0, 0]), float(k[1, 1]), float(k[0, 2]), float(k[1, 2])
    tan_fov_x, tan_fov_y = 0.5 * width / fx, 0.5 * height / fy
    lims = np.array([cx / fx + FOV_CLAMP_MARGIN * tan_fov_x, (width - cx) / fx + FOV_CLAMP_MARGIN * tan_fov_x,
                     cy / fy + FOV_CLAMP_MARGIN * tan_fov_y, (height - cy) / fy + FOV_CLAMP_MARGIN * tan_fov_y])
    return view, np.array([fx, fy, cx, cy]), lims


def _f32(t):
    return np.ascontiguousarray(t.detach().to(torch.float32).cpu().numpy())


class _ProjectFunction(torch.autograd.Function):
    """(means, quats, scales) -> (means2d, conics, depths); the rest of ``Projected`` is left in ``holder``."""

    @staticmethod
    def forward(ctx, means, quats, scales, cam, size, holder):  # noqa: D401
        view, intr, lims = cam
        width, height, near, far, tile_size = size
        tiles_x, tiles_y = math.ceil(width / tile_size), math.ceil(height / tile_size)
        arrays = (_f32(means), _f32(quats), _f32(scales))
        m2d, conics, depths, radii, visible, tmin, tmax = project_forward(
            *arrays, view, intr, lims, width, height, float(near), float(far), tile_size, tiles_x, tiles_y
        )
        holder.update(radii=radii, visible=visible, tile_min=tmin, tile_max=tmax, tiles=(tiles_x, tiles_y))
        ctx.saved = (arrays, cam, visible)
        return torch.from_numpy(m2d), torch.from_numpy(conics), torch.from_numpy(depths)

    @staticmethod
    def backward(ctx, d_means2d, d_conics, d_depths):
        arrays, (view, intr, lims), visible = ctx.saved
        n = arrays[0].shape[0]
        zero = np.zeros
        grads = project_backward(
            *arrays, view, intr, lims, visible,
            zero((n, 2), np.float32) if d_means2d is None else _f32(d_means2d),
            zero((n, 3), np.float32) if d_conics is None else _f32(d_conics),
            zero(n, np.float32) if d_depths is None else _f32(d_depths),
        )
        return (*(torch.from_numpy(g) for g in grads), None, None, None)


def project_gaussians_fast(means, quats, scales, viewmat, K, width: int, height: int, near: float = 0.01,
                           far: float = 1e10, tile_size: int = 16) -> Projected:
    """``projection.project_gaussians`` for float32 inputs with numba kernels (forward and backward)."""
    holder: dict = {}
    cam = camera_arrays(viewmat, K, width, height)
    means2d, conics, depths = _ProjectFunction.apply(
        means, quats, scales, cam, (width, height, near, far, tile_size), holder
    )
    tiles_x, tiles_y = holder["tiles"]
    return Projected(
        means2d, conics, depths, torch.from_numpy(holder["radii"]), torch.from_numpy(holder["visible"]),
        torch.from_numpy(holder["tile_min"]), torch.from_numpy(holder["tile_max"]), tiles_x, tiles_y,
    )
