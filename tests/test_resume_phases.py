"""A run interrupted inside any phase and resumed ends exactly as an uninterrupted one (issue #22).

The state goes through a checkpoint file (``save_checkpoint`` / ``read_checkpoint``, ``weights_only`` loading) into a
freshly built engine (``load_state_dict``), at: a ground-truth view, between two pre-processing rounds, inside a
pre-processing refit (past its first elongation clamp, before the others), right after a pre-processing split and
right after a colour-gradient split (the refit started, its trainer not built yet: its view order's seed), the
colour match, inside the stylization (Adam moments, accumulated gradients), inside the refit after a
colour-gradient split, and the final colour match. Small synthetic scenes with a few Gaussians no camera sees, a
cheap stand-in objective with its own random generator (as CLIP's crops), fixed seed; both versions run in this
process, so they must agree to the bit.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch
from synthetic import blob_scene, ring_cameras

from gstyle_core.cli import run as cli_run
from gstyle_core.engine.checkpoint import (
    CheckpointError,
    read_checkpoint,
    save_checkpoint,
    stylize_checkpoint_path,
)
from gstyle_core.engine.flat_split import ElongationClampStrategy, clamp_points
from gstyle_core.engine.settings import resolve_settings
from gstyle_core.engine.stylizer import Stylizer
from gstyle_core.io import save_scene
from gstyle_core.scene import GaussianScene

REFIT_ITERATIONS = 6  # clamps after iterations 1, 3, 4 and 6 (clamp_points)


class NoisyPull:
    """Stand-in objective: content term plus a pull of the mean colour towards the painting's, weighted by random
    numbers drawn from its own generator every call (its state must survive a checkpoint, as CLIP's crops)."""

    def __init__(self, style, settings) -> None:
        from types import SimpleNamespace

        self.target = torch.as_tensor(np.asarray(style).reshape(-1, 3).mean(0))
        self.weights = settings.weights
        self.loss = SimpleNamespace(clip_term=SimpleNamespace(generator=torch.Generator().manual_seed(11)))

    def set_weights(self, weights) -> None:
        self.weights = weights

    def __call__(self, image, content, view, coverage=None):
        w = torch.rand(3, generator=self.loss.clip_term.generator)
        weight = torch.ones(image.shape[:2]) if coverage is None else coverage
        pull = (w * (image.reshape(-1, 3).mean(0) - self.target) ** 2).sum()
        content_term = (((image - content) ** 2).sum(-1) * weight).mean()
        loss = self.weights.nnfm * pull + content_term
        return loss, {"nnfm": float(pull.detach()), "content": float(content_term.detach())}


def scene_with_unseen() -> GaussianScene:
    """The blob and 5 Gaussians far below the ring of cameras (seen by none: left out of renders and refits)."""
    far = blob_scene(5, seed=9)
    far.means[:] += np.array([0.0, 80.0, 0.0], np.float32)
    return GaussianScene.concatenate([blob_scene(240, seed=8), far])


VARIANTS = {  # the refits train the parameters themselves / a copy of the seen (and selected) rows
    "whole scene, all seen, forward-facing settings": dict(kind="forward", unseen=False),
    "a region, some unseen, 360° settings (4 views a step, random order, visible-rows Adam)": dict(
        kind="360", unseen=True, region=(-10.0, -10.0, -10.0, 0.2, 10.0, 10.0)),
    "a finer level: the pre-processing refits fit windows of the end width's ground truth": dict(
        kind="360", unseen=False, refine_widths=(64,)),
}


def make_engine(kind: str, unseen: bool, region=None, refine_widths=()) -> Stylizer:
    settings = resolve_settings("preview", kind, 4, max_views=4, epochs=3, min_steps=0, working_width=32,
                                refit_iterations=REFIT_ITERATIONS, preprocess_rounds=2, force_preprocess=True,
                                split_at=(0.4,), split_rate=0.1, max_gaussians=10_000, region=region,
                                refine_widths=refine_widths, refine_epochs=1.0)
    style = np.zeros((8, 8, 3), np.float32)
    style[..., 0] = 1.0
    style[::2, :, 2] = 0.6
    scene = scene_with_unseen() if unseen else blob_scene(240, seed=8)
    return Stylizer(scene, ring_cameras(4), style, settings, objective_factory=NoisyPull)


def interruption(engine: Stylizer) -> str | None:
    """Which of the interruption points the engine is at (before its next step), if any."""
    phase = engine.phase
    pre, sty = engine.preprocess, engine.stylize
    if phase == "preprocess" and pre.refit is not None and pre.refit.steps_done == 2:
        return "inside a pre-processing refit"
    if phase == "preprocess" and pre.refit is not None and pre.refit.steps_done == 0 and pre.round == 1:
        return "after a pre-processing split, before its refit's first step"
    if phase == "preprocess" and pre.refit is None and pre.round == 1:
        return "between pre-processing rounds"
    if phase == "refit" and sty.refit.steps_done == 2:
        return "inside the refit after a split"
    if phase == "refit" and sty.refit.steps_done == 0:
        return "after a colour-gradient split, before its refit's first step"
    if phase == "stylize" and sty.step_index == 2:
        return "inside the stylization"
    if phase == "ground_truth" and engine.global_step == 1:
        return "inside the ground truth"
    return {"colour_match": "at the colour match", "finish": "at the final colour match"}.get(phase)


POINTS = 9


@pytest.mark.parametrize("variant", list(VARIANTS))
def test_a_run_resumed_inside_any_phase_ends_as_an_uninterrupted_one(variant, tmp_path):
    reference = make_engine(**VARIANTS[variant])
    saved: dict[str, tuple[int, dict]] = {}
    reports = []
    while not reference.done:
        where = interruption(reference)
        if where is not None and where not in saved:
            path = save_checkpoint(tmp_path / f"{len(saved)}.ckpt", reference.state_dict(), {"kind": "test"})
            saved[where] = (reference.global_step, read_checkpoint(path)[0])
        rep = reference.step()
        reports.append((rep.phase, rep.step, rep.total_steps, rep.message, rep.losses))
    assert len(saved) == POINTS, sorted(saved)
    assert reference.splits_done == 1
    assert reference.decisions["culled"].startswith("5 of" if VARIANTS[variant]["unseen"] else "0 of")
    for where, (step, state) in saved.items():
        resumed = make_engine(**VARIANTS[variant])
        resumed.load_state_dict(state)
        assert resumed.global_step == step and resumed.total_steps() == reports[-1][2], where
        if where == "inside a pre-processing refit":  # the bug this test is for: the clamps of a fresh refit
            assert resumed.preprocess.refit.strategy.clamp_at == clamp_points(REFIT_ITERATIONS)
        tail = []
        while not resumed.done:
            rep = resumed.step()
            tail.append((rep.phase, rep.step, rep.total_steps, rep.message, rep.losses))
        assert tail == reports[step:], where
        for name, value in reference.params.items():
            assert torch.equal(resumed.params[name], value), (where, name)
        assert torch.equal(resumed.c_s, reference.c_s), where
        assert resumed.history == reference.history and resumed.decisions == reference.decisions, where
        assert np.array_equal(resumed.stylized_scene().sh_dc, reference.stylized_scene().sh_dc), where


def test_a_refit_whose_first_step_runs_out_of_memory_is_built_by_the_next(monkeypatch):
    """The first step of each kind of refit (pre-processing, after a colour split) fails building its trainer, as
    a GPU out of memory does (a real one on an H100 found the refit half-started when it was built by the split
    step): the error is the one-line one, the step is not counted, and the run, stepped on, ends as an
    uninterrupted one."""
    from gstyle_core.device import DeviceMemoryError
    from gstyle_core.engine.phases import Refit

    variant = VARIANTS["a region, some unseen, 360° settings (4 views a step, random order, visible-rows Adam)"]
    reference = make_engine(**variant)
    while not reference.done:
        reference.step()
    build, failed = Refit._build, []

    def build_or_run_out(refit, ids, seed):
        if refit.name not in failed:
            failed.append(refit.name)
            raise torch.OutOfMemoryError("CUDA out of memory. Tried to allocate 2.00 MiB (a stand-in)")
        build(refit, ids, seed)

    monkeypatch.setattr(Refit, "_build", build_or_run_out)
    engine = make_engine(**variant)
    while not engine.done:
        before = engine.global_step
        try:
            engine.step()
        except DeviceMemoryError as error:
            assert "ran out of memory in" in str(error) and engine.global_step == before
    assert failed == ["preprocess", "refit"]
    for name, value in reference.params.items():
        assert torch.equal(engine.params[name], value), name
    assert torch.equal(engine.c_s, reference.c_s)


def test_the_progress_total_is_the_sum_of_the_phases_steps():
    """The first report's total is where the run ends, with and without the final colour match (which the total
    counted before even when it did not run)."""
    for after in (True, False):
        settings = resolve_settings("preview", "forward", 4, max_views=4, epochs=2, min_steps=0, working_width=32,
                                    refit_iterations=3, preprocess_rounds=1, force_preprocess=True, split_at=(0.5,),
                                    split_rate=0.1, colour_match_after=after, max_gaussians=10_000)
        engine = Stylizer(blob_scene(120, seed=2), ring_cameras(4), np.ones((8, 8, 3), np.float32), settings,
                          objective_factory=NoisyPull)
        planned = engine.total_steps()
        totals = set()
        while not engine.done:
            totals.add(engine.step().total_steps)
        assert totals == {planned} == {engine.global_step}, after
        assert ("finish" in engine.timings) is after


def test_elongation_clamps_follow_the_refit_length():
    assert ElongationClampStrategy(60).clamp_at == (15, 30, 45, 60)  # the preview's refit
    assert ElongationClampStrategy(1000).clamp_at == (250, 500, 750, 1000)
    assert ElongationClampStrategy(2).clamp_at == (1, 2)
    with pytest.raises(TypeError):
        ElongationClampStrategy()  # no default clamp points: a refit's length must be given


def test_a_checkpoint_of_the_previous_format_is_refused_in_one_line(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("GSTYLE_CACHE", str(tmp_path / "cache"))
    scene, out = tmp_path / "scene.ply", tmp_path / "out" / "o.ply"
    save_scene(blob_scene(50, seed=1), scene)
    path = stylize_checkpoint_path(out)
    path.parent.mkdir(parents=True)
    torch.save({"format": "gstyle-stylize-checkpoint/1", "meta": {}, "state": {"phase": "stylize"}}, path)
    with pytest.raises(CheckpointError, match="another version of G-Style"):
        read_checkpoint(path)
    assert cli_run(["stylize", str(scene), "--out", str(out), "--working-width", "32", "--resume"]) == 2
    err = capsys.readouterr().err.strip()
    assert "another version of G-Style" in err and "run without resuming" in err and "\n" not in err
    assert "Traceback" not in err and not out.exists()
