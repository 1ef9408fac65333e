"""Shared set-up for tests that run a bench script's command line on tiny inputs."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
from synthetic import blob_scene, ring_cameras

from gstyle_core.engine.build import SMOKE_SETTINGS

BENCH = Path(__file__).resolve().parents[1] / "bench"


def load_bench(name: str):
    """The bench script ``bench/NAME.py`` (``NAME`` may be ``studies/...``) as a module of its own (``NAME_bench``
    after the last slash), as its command line would run."""
    spec = importlib.util.spec_from_file_location(f"{Path(name).name}_bench", BENCH / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses and pickling look a class's module up by name
    spec.loader.exec_module(module)
    return module


TINY = SMOKE_SETTINGS  # the engine's own tiniest run through every phase (what GSTYLE_SMOKE=1 asks for)


def tiny_bench_inputs(module, vgg, style: np.ndarray, tmp_path: Path, monkeypatch) -> tuple[Path, Path]:
    """Write a 150-Gaussian scene and ``style`` as files, load ``vgg`` wherever VGG is loaded, and make ``module``'s
    ``build_request`` ask for ``TINY`` settings; returns the scene's and the painting's paths."""
    from PIL import Image

    from gstyle_core.io import save_scene
    from gstyle_core.style import vgg as vgg_module

    scene, painting = tmp_path / "tiny.ply", tmp_path / "style.png"
    save_scene(blob_scene(150, seed=2), scene)
    Image.fromarray((style * 255).astype(np.uint8)).save(painting)
    monkeypatch.setattr(vgg_module, "load_vgg", lambda *a, **k: vgg)
    plain = module.build_request

    def tiny_request(args):
        request = plain(args)
        request.overrides.update(TINY)
        return request

    monkeypatch.setattr(module, "build_request", tiny_request)
    return scene, painting


def tiny_engine(vgg, scene, style, **overrides):
    """A real engine on ``vgg`` over 3 ring cameras at a 32-px working width (a forward-facing preview cut to a few
    steps), not yet stepped; ``overrides`` go to ``resolve_settings``."""
    from gstyle_core.engine.objective import StyleObjective
    from gstyle_core.engine.settings import resolve_settings
    from gstyle_core.engine.stylizer import Stylizer

    opts = dict(max_views=3, epochs=1, min_steps=2, preprocess_rounds=1, refit_iterations=2, split_rate=0.0,
                working_width=32)
    opts.update(overrides)
    settings = resolve_settings("preview", "forward", 3, **opts)
    return Stylizer(scene, ring_cameras(3), style, settings,
                    objective_factory=lambda s, st: StyleObjective(s, st, vgg=vgg))
