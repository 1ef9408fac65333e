"""Build the real stylization engine inside the worker process (module-level, so spawn can pickle it)."""

from __future__ import annotations

from typing import Any

from gstyle_core.engine.build import SETTING_OPTIONS

# What the studio's engine config may set besides scene/style/cameras/preset/scene_kind (None keeps the preset's
# value): the 360° defaults, the settings ``gstyle stylize`` takes, and ``selection``, a bool mask over the scene's
# Gaussians (the studio's rectangle; ``region`` is its box).
ENGINE_OPTIONS = ("defaults", *SETTING_OPTIONS, "selection", "capacity")  # capacity: a resumed run's cap


def make_stylizer(scene: str | None = None, style: str | list[str] | None = None, cameras: str | None = None,
                  preset: str = "preview", scene_kind: str = "auto", **options: Any):
    """``gstyle_core.engine.Stylizer`` for a scene/style/cameras, as ``gstyle stylize`` builds it (``style``: one
    image path, or a list of paintings to mix with ``style_weights``)."""
    from gstyle_core.engine.build import BuildRequest, build_stylizer

    unknown = set(options) - set(ENGINE_OPTIONS)
    if unknown:
        raise ValueError(f"unknown engine options: {', '.join(sorted(unknown))}")
    request = BuildRequest(scene=scene, style=style, cameras=cameras, preset=preset, scene_kind=scene_kind,
                           defaults=options.get("defaults"), selection=options.get("selection"),
                           capacity=options.get("capacity"),
                           overrides={name: options.get(name) for name in SETTING_OPTIONS})
    return build_stylizer(request).engine
