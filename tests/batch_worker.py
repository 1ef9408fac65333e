"""``gstyle`` with the stand-in engine of ``test_outputs_stylize`` (nine steps, no networks) behind ``gstyle stylize``:
the batch tests run their jobs through it, in the test's process (``use_tiny_engine(monkeypatch.setattr)``) or as
the pool's worker command (``python tests/batch_worker.py stylize ...``; ``--kill-parent-once MARKER`` first: the
first job kills the process that started it, as a Ray worker lost). The scene and the paintings are loaded as a
real run loads them, so a corrupt painting fails the job the same way."""

from __future__ import annotations

import sys
from collections.abc import Callable
from types import SimpleNamespace

import numpy as np
from test_outputs_stylize import TinyEngine

from gstyle_core.cli import run
from gstyle_core.cli import stylize as cli
from gstyle_core.engine.build import BuiltEngine, style_paths


def tiny_build(request, built: list | None = None) -> BuiltEngine:
    """The stand-in engine after the request's scene and paintings were read (errors as a real build's)."""
    from gstyle_core.images import load_style_image
    from gstyle_core.io import load_scene

    scene = load_scene(request.scene)[0]
    styles = [load_style_image(path) for path in style_paths(request.style)]
    if built is not None:
        built.append(request)
    return BuiltEngine(TinyEngine(), scene, None, SimpleNamespace(source="test"), styles[0])


def tiny_figures(engine, scene, style, **_) -> dict:
    """Fixed quality figures; the after picture's colour follows the painting's mean, 16×48 (3:1, like three views)."""
    after = np.broadcast_to(np.asarray(style, np.float32).mean(axis=(0, 1)), (16, 48, 3)).copy()
    return {"images": (np.zeros((16, 48, 3), np.float32), after), "initial": {"nnfm": 2.0},
            "final": {"nnfm": 1.5}, "nnfm_drop": 0.25, "structure": 0.8,
            "display": {"width": 1024, "speckle_ratio": 1.25, "speckle_ratio_per_view": [1.25], "channels": "colours",
                        "painting_side": 1024}}


def use_tiny_engine(setattr_: Callable, built: list | None = None) -> None:
    """Put the stand-in engine and figures behind ``gstyle stylize`` (``setattr_``: ``monkeypatch.setattr``, or
    ``setattr`` in a worker process); ``built`` collects the build requests."""
    setattr_(cli, "build_stylizer", lambda request: tiny_build(request, built))
    setattr_(cli, "evaluate_run", tiny_figures)


def kill_parent_once(marker: str) -> None:
    """The first time (``marker`` not there yet): kill the process that started this one, as a lost Ray worker."""
    import os
    import signal
    from pathlib import Path

    if not Path(marker).exists():
        Path(marker).write_text(str(os.getppid()))
        os.kill(os.getppid(), signal.SIGKILL)
        sys.exit(1)


if __name__ == "__main__":
    argv = sys.argv[1:]
    if argv[:1] == ["--kill-parent-once"]:  # python batch_worker.py --kill-parent-once MARKER stylize ...
        kill_parent_once(argv[1])
        argv = argv[2:]
    use_tiny_engine(setattr)
    sys.exit(run(argv))
