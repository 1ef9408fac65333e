"""Differentiable rasterizer for 3D Gaussians (standard 3DGS maths, Kerbl et al. 2023): numba kernels on the CPU;
on CUDA tensors the same projection in torch and gsplat's blend kernels (``gsplat_backend.py``, alpha clamped at
0.999 instead of 0.99; ``tests/test_raster_gsplat.py`` is the twin test).

Conventions (the OpenGL viewer matches them):
- Camera: ``viewmat`` is world-to-camera with OpenCV axes (x right, y down, z forward); ``K`` in pixels.
- Pixel convention (as gsplat): a Gaussian's centre projects to ``means2d = (fx*X/Z + cx, fy*Y/Z + cy)``
  and pixel (col, row) is evaluated at the continuous point ``(col + 0.5, row + 0.5)``.
- Extreme inputs: scales above 1e20 count as 1e20 (the 2D covariance would overflow; such a Gaussian covers
  the screen anyway); a quaternion is normalised after division by its largest component, and one whose
  largest |component| is <= 1e-10 is the identity (both the same in float32 and float64).
- Culling: camera z <= near or z > far; a centre projecting beyond the float range; 2D covariance determinant
  <= 0; no 16x16 tile on screen touched by the square of half-side radius = ceil(3 * sqrt(largest eigenvalue
  of the 2D covariance)).
- 2D covariance: EWA Jacobian at the mean with x/z, y/z clamped to the field of view widened by 30 %
  (3DGS's 1.3 * tan(fov/2)), plus 0.3 px^2 on the diagonal (low-pass dilation).
- Blending, front to back in depth order per pixel: power = -0.5 d^T conic d (skipped if > 0),
  alpha = min(0.99, opacity * exp(power)) (skipped if < 1/255); a pixel stops before the Gaussian that
  would take its transmittance below 1e-4. image = sum c_i alpha_i T_i + T_final * background.
  Where alpha is clamped to 0.99 its gradient w.r.t. opacity and geometry is zero (the exact derivative).
- ``alpha`` output = 1 - T_final. ``depth`` output = sum z_i alpha_i T_i divided by alpha where alpha > 0
  (an expected depth of the visible surface), 0 elsewhere.
- SH colours (``sh_degree``): 3DGS order and constants, direction = normalised (mean - camera centre),
  colour = max(0, SH + 0.5).
"""

from .colour_cache import ColourCache, ColourCacheStore
from .projection import project_gaussians
from .render import RenderOutput, rasterize

__all__ = ["rasterize", "RenderOutput", "ColourCache", "ColourCacheStore", "project_gaussians"]
