"""Build the real stylization engine inside the worker process (module-level, so spawn can pickle it)."""

from __future__ import annotations

import argparse
from typing import Any

from gstyle_core.pipeline.controls import cli_control_names

# ``gstyle stylize`` options the studio may set (engine_config keys); None keeps the preset's value.
ENGINE_OPTIONS = ("defaults", *cli_control_names(), "working_width", "clip_weights", "vgg_weights", "max_gaussians",
                  "style_weights",
                  "region", "selection")  # region: a box; selection: a bool mask (the studio's rectangle)


def make_stylizer(scene: str | None = None, style: str | list[str] | None = None, cameras: str | None = None,
                  preset: str = "preview", scene_kind: str = "auto", **overrides: Any):
    """``gstyle_core.pipeline.Stylizer`` for a scene/style/cameras, as ``gstyle stylize`` builds it (``style``: one
    image path, or a list of paintings to mix with ``style_weights``)."""
    from gstyle_core.pipeline.cli import build_stylizer

    unknown = set(overrides) - set(ENGINE_OPTIONS)
    if unknown:
        raise ValueError(f"unknown engine options: {', '.join(sorted(unknown))}")
    args = argparse.Namespace(scene=scene, style=style, cameras=cameras, preset=preset, scene_kind=scene_kind,
                              threads=1, **{k: overrides.get(k) for k in ENGINE_OPTIONS})
    engine, *_ = build_stylizer(args)
    return engine
