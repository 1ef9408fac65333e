"""Test doubles for the app: a tiny engine that follows the Stylizer protocol (picklable factory for spawn)."""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from gstyle_core.engine.controls import control_names


@dataclass
class FakeReport:
    """Step report with the protocol's fields."""

    phase: str
    step: int
    total_steps: int
    losses: dict = field(default_factory=dict)
    seconds: float = 0.0
    gaussians: int = 0
    colours_changed: bool = True
    geometry_changed: bool = False
    done: bool = False
    width: int | None = None  # the width the step rendered at (None: the engine does not say)


class FakeEngine:
    """Deterministic engine: colours move with the step count, geometry grows every ``grow_every`` steps.

    ``fail_at``: step() raises RuntimeError at that step (1-based). ``set_params`` values are echoed in the
    snapshot under ``"params"`` so tests can see that they arrived. ``ignore_sigterm``: the process ignores SIGTERM
    (with a long ``step_seconds``, a worker that hangs and must be killed). ``min_level``: the darkest colour of the
    cycle (0: black every 100 steps; above 0 every snapshot shows the scene).
    """

    def __init__(self, n: int = 64, total_steps: int = 1_000_000, fail_at: int | None = None,
                 step_seconds: float = 0.002, grow_every: int = 0, ignore_sigterm: bool = False,
                 min_level: float = 0.0) -> None:
        if ignore_sigterm:
            import signal

            signal.signal(signal.SIGTERM, signal.SIG_IGN)
        self.n, self.total, self.fail_at = n, total_steps, fail_at
        self.step_seconds, self.grow_every, self.min_level = step_seconds, grow_every, min_level
        self.steps = 0
        self.params: dict[str, float] = {"lambda_clip": 10.0, "lambda_nnfm": 100.0}
        self.geometry_version = 0
        rng = np.random.default_rng(0)
        self.means = rng.normal(0, 0.5, (n, 3)).astype(np.float32)

    def step(self) -> FakeReport:
        self.steps += 1
        if self.fail_at is not None and self.steps == self.fail_at:
            raise RuntimeError("fake engine failure\nsecond line")
        time.sleep(self.step_seconds)
        grew = bool(self.grow_every) and self.steps % self.grow_every == 0
        if grew:
            self.means = np.concatenate([self.means, self.means[:1] + 0.01])
            self.geometry_version += 1
        loss = 1.0 / self.steps * self.params["lambda_clip"]
        return FakeReport("stylize", self.steps, self.total, {"total": loss}, self.step_seconds, len(self.means),
                          True, grew, self.steps >= self.total)

    def set_params(self, **kw: float) -> None:
        unknown = set(kw) - set(control_names())
        if unknown:
            raise ValueError(f"unknown parameters: {sorted(unknown)}")
        self.params.update({k: float(v) for k, v in kw.items()})

    def snapshot(self) -> dict:
        n = len(self.means)
        level = self.min_level + (1.0 - self.min_level) * (self.steps % 100) / 100.0
        return {
            "means": self.means.copy(),
            "log_scales": np.full((n, 3), np.log(0.05), np.float32),
            "quats": np.tile(np.array([1, 0, 0, 0], np.float32), (n, 1)),
            "opacity_logits": np.full(n, 2.0, np.float32),
            "colors": np.full((n, 3), level, np.float32),
            "colors_gt": np.full((n, 3), 0.5, np.float32),
            "geometry_version": self.geometry_version,
            "colour_version": self.steps,
            "params": dict(self.params),
        }

    def state_dict(self) -> dict:
        return {"steps": self.steps, "means": self.means.copy(), "params": dict(self.params),
                "resumed_at": getattr(self, "resumed_at", None)}

    def load_state_dict(self, state: dict) -> None:
        self.steps = state["steps"]
        self.resumed_at = int(state["steps"])  # the step this engine continued from (tests check resumes)
        self.means = state["means"].copy()
        self.params = dict(state["params"])


def make_fake_engine(scene=None, style=None, cameras=None, preset=None, **config) -> FakeEngine:
    """Module-level factory (picklable for the spawn start method); ignores the app's scene/style keys."""
    return FakeEngine(**config)


class StylizingEngine(FakeEngine):
    """A ``FakeEngine`` that says it is stylizing and has settings (a calibrated 360° preview, 256 px), so its exports
    are results (``app/result_files.py``); ``width``: the width its reports say it works at (None: none)."""

    decisions: dict = {}

    def __init__(self, width: int | None = None, **config) -> None:
        from gstyle_core.engine.settings import resolve_settings

        super().__init__(**config)
        self.settings, self.width = resolve_settings("preview", "360", 4), width

    def step(self) -> FakeReport:
        report = super().step()
        if self.width is not None:
            report.width = self.width
        return report

    def snapshot(self) -> dict:
        return {**super().snapshot(), "phase": "stylize"}


def make_stylizing_engine(scene=None, style=None, cameras=None, preset=None, **config) -> StylizingEngine:
    """``StylizingEngine`` for the studio's factory (ignores the app's scene/style keys)."""
    return StylizingEngine(**config)


class MarkingEngine(FakeEngine):
    """A ``FakeEngine`` that creates the file ``marker`` (if given) after its ``mark_after``-th step: another process
    can then see that the engine has stepped."""

    def __init__(self, marker: str | None = None, mark_after: int = 5, **config) -> None:
        super().__init__(**config)
        self.marker, self.mark_after = marker, mark_after

    def step(self) -> FakeReport:
        report = super().step()
        if self.marker and self.steps == self.mark_after:
            open(self.marker, "w").close()
        return report


def make_slow_engine(**_app_config) -> FakeEngine:
    """A ``FakeEngine`` that steps for ever at 20 steps a second with the scene always lit (the studio's factory in
    tests that kill its worker mid-run)."""
    return FakeEngine(n=64, step_seconds=0.05, min_level=0.3)


def make_command_line_engine(**_app_config) -> MarkingEngine:
    """Stands in for ``app.engine_factory.make_stylizer`` in a studio run from its command line (ignores the engine
    config); the file named by ``$GSTYLE_TEST_STEPPED`` appears after five steps."""
    import os

    return MarkingEngine(os.environ.get("GSTYLE_TEST_STEPPED"), n=64, step_seconds=0.01)


class MeanColourPull:
    """Cheap stand-in style objective: pulls the render's mean colour to the style's (no networks)."""

    def __init__(self, style, settings) -> None:
        import torch

        self.target = torch.as_tensor(np.asarray(style).reshape(-1, 3).mean(0))
        self.weights = settings.weights

    def set_weights(self, weights) -> None:
        self.weights = weights

    def __call__(self, image, content, view, coverage=None):
        loss = self.weights.nnfm * ((image.reshape(-1, 3).mean(0) - self.target.to(image.device)) ** 2).sum()
        return loss, {"nnfm": float(loss.detach())}


class OutOfMemoryPull(MeanColourPull):
    """``MeanColourPull`` standing in for a GPU that runs out of memory: on any device setting but "cpu" (the run
    computes on the CPU all the same) its ``FAIL_ON``-th call raises torch's out-of-memory error."""

    FAIL_ON = 4

    def __init__(self, style, settings) -> None:
        super().__init__(style, settings)
        self.on_gpu, self.calls = settings.device != "cpu", 0

    def __call__(self, image, content, view, coverage=None):
        import torch

        self.calls += 1
        if self.on_gpu and self.calls == self.FAIL_ON:
            raise torch.OutOfMemoryError("CUDA out of memory. Tried to allocate 2.00 GiB (a stand-in)")
        return super().__call__(image, content, view, coverage)


def make_small_stylizer(n: int = 150, device: str | None = None, objective=MeanColourPull, kind: str = "forward",
                        **_ignored):
    """The real ``Stylizer`` on a tiny synthetic scene with ``MeanColourPull`` (for bridge integration tests);
    ``kind`` "360": a calibrated 360° preview (its first Refine level takes the weights of runs with levels)."""
    from synthetic import blob_scene, ring_cameras

    from gstyle_core.engine.settings import resolve_settings
    from gstyle_core.engine.stylizer import Stylizer

    style = np.zeros((8, 8, 3), np.float32)
    style[..., 0] = 1.0
    settings = resolve_settings("preview", kind, 3, max_views=3, epochs=3, min_steps=0, refit_iterations=2,
                                split_at=(1 / 3,), working_width=32, preprocess_rounds=1, device=device)
    return Stylizer(blob_scene(n, seed=5), ring_cameras(3), style, settings, objective_factory=objective)


BUILT: list = []  # engines made by keep_small_stylizer (and other test factories), newest last


def keep_small_stylizer(**config):
    """``make_small_stylizer``, kept in ``BUILT`` for the test to look at (thread mode: the same process)."""
    BUILT.append(make_small_stylizer(**config))
    return BUILT[-1]


def keep_small_360_stylizer(**config):
    """``keep_small_stylizer`` as a calibrated 360° preview."""
    BUILT.append(make_small_stylizer(**{**config, "kind": "360"}))
    return BUILT[-1]


def stand_in_gpu_stylizer(**config):
    """``keep_small_stylizer`` whose "GPU" (its device setting not "cpu") runs out of memory at its fourth stylize
    step (``OutOfMemoryPull``); on "cpu" it runs through."""
    BUILT.append(make_small_stylizer(**{**config, "objective": OutOfMemoryPull}))
    return BUILT[-1]


def random_torchvision_vgg_state() -> dict:
    """A torchvision-layout VGG-16 state (``features.N.weight/bias``) with random values."""
    import torch

    from gstyle_core.style.vgg import CONV_LAYERS, VGGFeatures

    shapes = {k: v.shape for k, v in VGGFeatures().state_dict().items()}
    gen = torch.Generator().manual_seed(17)
    return {f"features.{i}.{kind}": torch.randn(shapes[f"features.{i}.{kind}"], generator=gen) * 0.05
            for i, _ in CONV_LAYERS for kind in ("weight", "bias")}


def engine_with_random_vgg(monkeypatch, **overrides):
    """A tiny real engine whose objective loads its VGG (random weights, seeded) as the product does: ``load_vgg``
    patched; preview settings over 3 ring cameras, 32 px, 3 epochs, no pre-processing or splits unless ``overrides``
    say otherwise."""
    import torch
    from synthetic import blob_scene, ring_cameras

    from gstyle_core.engine.settings import resolve_settings
    from gstyle_core.engine.stylizer import Stylizer
    from gstyle_core.style import vgg as vgg_module
    from gstyle_core.style.vgg import VGGFeatures

    def fake_load_vgg(weights=None, cache_dir=None, dtype=torch.float32, channels_last=False):
        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(0)
            return VGGFeatures().set_compute_mode(dtype, channels_last)

    monkeypatch.setattr(vgg_module, "load_vgg", fake_load_vgg)
    style = np.random.default_rng(0).uniform(size=(24, 24, 3)).astype(np.float32)
    opts = dict(max_views=3, epochs=3, min_steps=0, preprocess_rounds=0, split_rate=0.0, working_width=32)
    opts.update(overrides)
    return Stylizer(blob_scene(150, seed=3), ring_cameras(3), style, resolve_settings("preview", "forward", 3, **opts))


def engine_at_stylize(vgg, scene, style, **overrides):
    """A tiny real engine (the real ``StyleObjective`` on ``vgg``) over 3 ring cameras, stepped to its stylize phase:
    preview settings without pre-processing or splits, 32 px wide, 3 epochs, unless ``overrides`` say otherwise."""
    from synthetic import ring_cameras

    from gstyle_core.engine.objective import StyleObjective
    from gstyle_core.engine.settings import resolve_settings
    from gstyle_core.engine.stylizer import Stylizer

    opts = dict(max_views=3, epochs=3, min_steps=0, preprocess_rounds=0, split_rate=0.0, working_width=32)
    opts.update(overrides)
    settings = resolve_settings("preview", "forward", 3, **opts)
    engine = Stylizer(scene, ring_cameras(3), style, settings,
                      objective_factory=lambda s, st: StyleObjective(s, st, vgg=vgg))
    while engine.phase != "stylize":
        engine.step()
    return engine


def small_studio(window, monkeypatch, tmp_path, factory=keep_small_stylizer):
    """A studio on a 150-Gaussian ring scene and a random painting (``style.png`` in ``tmp_path``) whose engine is
    built by ``factory`` in a worker thread; the cache folder is private to the test and ``BUILT`` starts empty."""
    from PIL import Image
    from synthetic import blob_scene, ring_cameras

    from app.studio import LoadedScene, StudioApp

    monkeypatch.setenv("GSTYLE_CACHE", str(tmp_path / "cache"))
    style = tmp_path / "style.png"
    Image.fromarray(np.random.default_rng(0).integers(0, 255, (16, 16, 3), dtype=np.uint8)).save(style)
    loaded = LoadedScene(str(tmp_path / "ring.ply"), blob_scene(150, seed=5), ring_cameras(3))
    BUILT.clear()
    return StudioApp(window.ctx, loaded=loaded, style_path=str(style), engine_factory=factory,
                     output_dir=tmp_path / "out", worker_mode="thread")


def still_studio(window, tmp_path, size: tuple[int, int]):
    """A studio without an engine on a 50-Gaussian scene seen by one camera of ``size``; outputs in ``tmp_path/out``,
    recent folders in ``tmp_path/recent.json``."""
    from synthetic import blob_scene, look_at_camera

    from app.studio import LoadedScene, StudioApp

    loaded = LoadedScene(str(tmp_path / "first.ply"), blob_scene(50), [look_at_camera((0, 0, -3), (0, 0, 0), *size)])
    app = StudioApp(window.ctx, loaded=loaded, style_path=None, engine_factory=None, engine_config={},
                    output_dir=tmp_path / "out")
    app.files.recent_file = tmp_path / "recent.json"
    return app


def ring_studio(window, tmp_path, factory=make_fake_engine, snapshots: int = 1, **config):
    """A studio on a 150-Gaussian ring scene with 4 ring cameras whose engine (``factory``, ``n=150`` and
    ``config``) runs in a worker thread, started and past its first ``snapshots`` snapshots; outputs go to
    ``tmp_path``."""
    from synthetic import blob_scene, ring_cameras

    from app.studio import LoadedScene, StudioApp

    app = StudioApp(window.ctx, loaded=LoadedScene("ring", blob_scene(150), ring_cameras(4)), output_dir=tmp_path,
                    engine_factory=factory, engine_config={"n": 150, **config}, worker_mode="thread")
    app.engine.start()
    assert app.engine.bridge.wait_until(lambda s: s.snapshots_received >= snapshots or s.error, 60), \
        app.engine.bridge.state.error
    return app


class GatedSort:
    """The viewer's real depth sort (``app.depth_sort.sort_request``) behind a gate: ``started`` is set when a sort
    begins, which ends only once the test sets ``gate``; ``keys`` lists the requests sorted."""

    def __init__(self) -> None:
        import threading

        self.gate, self.started = threading.Event(), threading.Event()
        self.keys: list = []

    def __call__(self, request, scratch):
        from app.depth_sort import sort_request

        self.keys.append(request.key)
        self.started.set()
        assert self.gate.wait(30), "the test never opened the gate"
        return sort_request(request, scratch)


def short_pull_run(scene, cameras, channel: int, capacity=None, **overrides):
    """A short forward-facing ``preview`` engine on ``scene`` whose objective pulls the colours toward a painting of
    one primary ``channel`` (``MeanColourPull``): four views, 40 px, a forced pre-processing round, one split;
    ``capacity``: a saved cap (``Stylizer``'s); ``overrides``: other settings."""
    from gstyle_core.engine.settings import resolve_settings
    from gstyle_core.engine.stylizer import Stylizer

    style = np.zeros((8, 8, 3), np.float32)
    style[..., channel] = 1.0
    opts = dict(max_views=4, epochs=4, min_steps=0, refit_iterations=2, split_at=(0.5,), working_width=40,
                preprocess_rounds=1, force_preprocess=True, cull_unseen=False, preprocess_min_child_px=0.0)
    opts.update(overrides)
    settings = resolve_settings("preview", "forward", 4, **opts)
    return Stylizer(scene, cameras, style, settings, objective_factory=MeanColourPull, capacity=capacity)
