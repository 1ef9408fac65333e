"""Build a stylization engine from settings: the scene and its cameras (and photos), the painting(s) and the
resolved ``StylizeSettings``. ``gstyle stylize`` (``cli.build_request``), the studio's worker, the benches and the
tests all build their engines here."""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from ..errors import GStyleError
from .controls import cli_control_names

# The settings a caller names in ``BuildRequest.overrides`` besides any other ``StylizeSettings`` field (the benches
# set those): the options of ``gstyle stylize`` and of the studio's engine config. None keeps the preset's value.
SETTING_OPTIONS = (*cli_control_names(), "working_width", "clip_weights", "vgg_weights", "max_gaussians",
                   "style_weights", "region", "precision", "refine_widths", "refine_mode", "match_detail_px",
                   "device", "region_feather", "lod", "lod_pixels", "lod_merge_size")

# ``GSTYLE_SMOKE=1``: every engine built here runs the tiniest run that still goes through every phase (one split
# round, a few steps and refit iterations at 32 px, three views), and ``gstyle stylize`` measures its display figures
# and its quality figures at 64 px. For the benches' smoke test (``tests/test_bench_smoke.py``), which drives each
# lasting bench as a whole process; the run says so in ``decisions.smoke``. Never for results.
SMOKE_ENV = "GSTYLE_SMOKE"
SMOKE_SETTINGS = {"epochs": 1.0, "min_steps": 2, "max_views": 3, "refit_iterations": 2, "preprocess_rounds": 1,
                  "split_at": (0.5,), "working_width": 32, "refine_epochs": 0.5}
SMOKE_DISPLAY_WIDTH = 64
FIGURES_WIDTH_ENV = "GSTYLE_FIGURES_WIDTH"
EVALUATION_WIDTH = 256  # the width ``gstyle stylize``'s quality figures are measured at (``run_figures.evaluate_run``)


def smoke_run() -> bool:
    """Whether ``GSTYLE_SMOKE`` asks for the tiniest runs (the benches' smoke test)."""
    return os.environ.get(SMOKE_ENV, "") not in ("", "0")


def evaluation_width() -> int:
    """The width ``gstyle stylize``'s quality figures are measured at: ``$GSTYLE_FIGURES_WIDTH`` where it is a whole
    number of at least 16 px, else ``EVALUATION_WIDTH``, ``SMOKE_DISPLAY_WIDTH`` in a smoke run (a 32 px run measured
    at 256 px spent half its time on the figures). The test suite sets 64: its runs are 32 px wide."""
    raw = os.environ.get(FIGURES_WIDTH_ENV, "").strip()
    if raw.isdigit() and int(raw) >= 16:
        return int(raw)
    return SMOKE_DISPLAY_WIDTH if smoke_run() else EVALUATION_WIDTH


def display_width_of(args: Any) -> int:
    """The width ``gstyle stylize``'s display figures are measured at: ``--display-width`` (0: none), at most
    ``SMOKE_DISPLAY_WIDTH`` in a smoke run."""
    width = getattr(args, "display_width", 0)
    return min(width, SMOKE_DISPLAY_WIDTH) if smoke_run() else width


@dataclass
class BuildRequest:
    """What an engine is built from. ``overrides``: ``StylizeSettings`` fields by name (the λ weights as
    ``lambda_clip`` …), None for the preset's value; ``selection``: a bool mask over the scene's Gaussians (the
    studio's rectangle), None for the whole scene or ``overrides["region"]``'s box."""

    scene: str | None = None  # scene file; None: the bundled demo
    style: str | Sequence[str] | None = None  # one painting, several to mix (style_weights); None: the bundled one
    cameras: str | None = None  # cameras file or folder; None: generated around the scene
    preset: str = "preview"
    scene_kind: str = "auto"  # "forward" | "360" | "auto" (from the cameras)
    defaults: str | None = None  # 360° scenes: "calibrated" (None) or "paper"
    overrides: dict[str, Any] = field(default_factory=dict)
    selection: np.ndarray | None = None
    capacity: tuple[int, str] | None = None  # a resumed run's own cap on Gaussians (None: from the memory now)


class BuiltEngine(NamedTuple):
    """An engine with what it was built from: the input scene, its load report, the cameras (``CameraSet``) and the
    style (the painting, or the list of paintings of a mix)."""

    engine: Any
    scene: Any
    report: Any
    cameras: Any
    style: np.ndarray | list[np.ndarray]


def style_paths(style: str | Sequence[str] | None) -> list[str]:
    """The style image paths of a request (one path, several, or None: the bundled painting)."""
    from ..assets import DEFAULT_STYLE

    if not style:
        return [str(DEFAULT_STYLE)]
    return [str(style)] if isinstance(style, (str, Path)) else [str(s) for s in style]


def request_config(request: BuildRequest) -> dict[str, Any]:
    """The engine config (the studio's engine factory's keywords) that builds ``request``'s engine again from
    anywhere: paths absolute, the preset's values (None overrides) left out."""
    def absolute(path: Any) -> str | None:
        return str(Path(path).expanduser().resolve()) if path else None

    style = request.style
    config: dict[str, Any] = {
        "scene": absolute(request.scene),
        "style": [absolute(s) for s in style] if isinstance(style, (list, tuple)) else absolute(style),
        "cameras": absolute(request.cameras), "preset": request.preset, "scene_kind": request.scene_kind,
        "defaults": request.defaults}
    config.update({k: v for k, v in request.overrides.items() if v is not None})
    if request.selection is not None:
        config["selection"] = request.selection
    return config


def build_stylizer(request: BuildRequest) -> BuiltEngine:
    """Load the scene, cameras, photos and style, resolve the settings and build the engine."""
    from ..cameras import classify_scene_kind
    from ..images import load_style_image
    from ..scene_images import load_scene_and_cameras
    from ..style.mix import normalise_style_weights
    from .settings import resolve_settings
    from .stylizer import Stylizer

    paths = style_paths(request.style)
    overrides = dict(request.overrides)
    if smoke_run():
        overrides.update(SMOKE_SETTINGS)
    try:  # before anything loads: a wrong count of weights is the caller's mistake
        normalise_style_weights(overrides.get("style_weights"), len(paths))
    except ValueError as exc:
        raise GStyleError(f"--style/--style-weights: {exc}") from None
    scene, report, cams = load_scene_and_cameras(request.scene, request.cameras)
    styles = [load_style_image(path) for path in paths]
    kind = request.scene_kind if request.scene_kind != "auto" else classify_scene_kind(cams)
    settings = resolve_settings(request.preset, kind, len(cams.cameras), defaults=request.defaults, **overrides)
    photos = None
    if cams.has_images:
        photos = cams.load_images(max_width=max(settings.working_width * 2, 256))
    engine = Stylizer(scene, cams.cameras, styles[0] if len(styles) == 1 else styles, settings, photos=photos,
                      selection=request.selection, capacity=request.capacity)
    if smoke_run():
        engine.decisions["smoke"] = f"{SMOKE_ENV} set: the tiniest run through every phase, not a result"
    return BuiltEngine(engine, scene, report, cams, engine.style_input())
