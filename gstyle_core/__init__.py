"""G-Style core: scene IO, cameras, differentiable rasterizer, losses and the stylization engine.

This package never imports GL or UI code; the studio app (``app/``) builds on it.
"""

__version__ = "0.1.0"
