"""Build the real stylization engine inside the worker process (module-level, so spawn can pickle it)."""

from __future__ import annotations

import argparse
from typing import Any


def make_stylizer(scene: str | None = None, style: str | None = None, cameras: str | None = None,
                  preset: str = "preview", scene_kind: str = "auto", **overrides: Any):
    """``gstyle_core.pipeline.Stylizer`` for a scene/style/cameras, as ``gstyle stylize`` builds it."""
    from gstyle_core.pipeline.cli import build_stylizer

    args = argparse.Namespace(
        scene=scene, style=style, cameras=cameras, preset=preset, scene_kind=scene_kind,
        lambda_clip=overrides.get("lambda_clip"), lambda_nnfm=overrides.get("lambda_nnfm"),
        lambda_content=overrides.get("lambda_content"), lambda_tv=overrides.get("lambda_tv"),
        split_rate=overrides.get("split_rate"), working_width=overrides.get("working_width"),
        clip_weights=overrides.get("clip_weights"), vgg_weights=overrides.get("vgg_weights"), threads=1,
    )
    engine, *_ = build_stylizer(args)
    return engine
