"""Shared pytest configuration.

Hypothesis profiles for the fuzz tests (``tests/test_fuzz_readers.py``), chosen with ``GSTYLE_FUZZ_PROFILE``:
"ci" (the default: few examples, derandomized so CI runs are repeatable) and "soak" (many random examples,
failures kept in the ``.hypothesis`` database). The fuzz tests apply the profile themselves, so other tests
keep hypothesis' defaults. Shared GL fixtures: ``ctx`` (standalone EGL context) and ``window`` (headless studio
window of the module's W x H).
"""

from __future__ import annotations

import os
from datetime import timedelta

import pytest
from hypothesis import HealthCheck, settings

FUZZ_PROFILE = os.environ.get("GSTYLE_FUZZ_PROFILE", "ci")
_SLOW_CHECKS = [HealthCheck.too_slow, HealthCheck.data_too_large]

settings.register_profile("ci", max_examples=30, deadline=timedelta(seconds=5), derandomize=True, database=None,
                          suppress_health_check=_SLOW_CHECKS, print_blob=True)
settings.register_profile("soak", max_examples=1000, deadline=timedelta(seconds=10),
                          suppress_health_check=_SLOW_CHECKS, print_blob=True)


@pytest.fixture(scope="module")
def ctx():
    """A standalone EGL OpenGL 3.3 context for the module (skips with the reason when there is none)."""
    moderngl = pytest.importorskip("moderngl")
    try:
        context = moderngl.create_standalone_context(backend="egl", require=330)
    except Exception as exc:  # noqa: BLE001
        pytest.skip(f"no EGL OpenGL 3.3 context: {exc}")
    yield context
    context.release()


@pytest.fixture
def window(request):
    """A headless studio window (glfw NULL platform + EGL) of the test module's ``W`` x ``H``."""
    pytest.importorskip("imgui_bundle")
    from app.window import DisplayUnavailableError, open_window

    try:
        win = open_window(request.module.W, request.module.H, headless=True)
    except DisplayUnavailableError as exc:
        pytest.skip(f"no headless GL window (glfw NULL + EGL): {exc}")
    yield win
    win.close()


@pytest.fixture
def no_clip_weights(monkeypatch):
    """No CLIP weights anywhere: runs get the coarse substitute (or no CLIP term), as on a machine without them."""
    from gstyle_core.style import clip as clip_module

    monkeypatch.setattr(clip_module, "clip_search_paths", lambda: [])
    monkeypatch.delenv(clip_module.CLIP_ENV, raising=False)


@pytest.fixture(scope="module")
def vgg():
    """VGG-16 block 1-3 with random weights (seed 0), in eval mode: the loss definitions do not depend on them."""
    import torch

    from gstyle_core.style.vgg import VGGFeatures

    torch.manual_seed(0)
    return VGGFeatures().eval()
