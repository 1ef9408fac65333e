"""A selected region (issue #15, item 4): in the engine, the export, the CLI, OUT.json and checkpoints.

Tiny synthetic scenes and the mean-colour stand-in objective: each test runs in seconds on 2 cores.
"""

from __future__ import annotations

import argparse
import json

import numpy as np
import pytest
import torch
from fakes import MeanColourPull
from synthetic import blob_scene, ring_cameras

from gstyle_core.engine.checkpoint import engine_fingerprint
from gstyle_core.engine.region import RegionError, box_mask, check_region, parse_region, rect_mask, selection_mask
from gstyle_core.engine.settings import resolve_settings
from gstyle_core.engine.stylizer import Stylizer
from gstyle_core.io import load_scene, save_scene

HALF = (-10.0, -10.0, -10.0, 0.0, 10.0, 10.0)  # the x <= 0 half of the blob
FIELDS = ("means", "log_scales", "quats", "opacity_logits", "sh_dc", "sh_rest")


def red() -> np.ndarray:
    style = np.zeros((8, 8, 3), np.float32)
    style[..., 0] = 1.0
    return style


def make_engine(scene=None, region=HALF, selection=None, **overrides) -> Stylizer:
    opts = dict(max_views=3, epochs=3, min_steps=0, refit_iterations=3, split_at=(1 / 3,), working_width=32,
                preprocess_rounds=1, force_preprocess=True, split_rate=0.2, region=region)
    opts.update(overrides)
    settings = resolve_settings("preview", "forward", 3, **opts)
    scene = blob_scene(200, seed=5, sh_degree=3) if scene is None else scene
    return Stylizer(scene, ring_cameras(3), red(), settings, objective_factory=MeanColourPull, selection=selection)


@pytest.fixture(scope="module")
def finished():
    """A region run to the end: pre-processing split, colour-gradient split, refits, final colour match."""
    engine = make_engine()
    engine.run()
    return engine


# ====================================================================== boxes and masks
@pytest.mark.parametrize("bad, words", [
    ("0,0,0,1,1", "six"), ("0,0,0,1,1,x", "six comma-separated"), ("nan,0,0,1,1,1", "finite"),
    ("0,0,0,1,inf,1", "finite"), ("2,0,0,1,1,1", "x0 = 2 is larger than x1 = 1"),
    ("0,0,3,1,1,1", "z0 = 3 is larger than z1 = 1")])
def test_invalid_boxes_are_refused_saying_why(bad, words):
    with pytest.raises(RegionError, match=words):
        parse_region(bad)


def test_box_and_rectangle_masks():
    means = np.array([[0, 0, 0], [1, 1, 1], [2, 0, 0], [-1, 0, 5]], np.float32)
    assert box_mask(means, (0, 0, 0, 1, 1, 1)).tolist() == [True, True, False, False]  # faces included
    assert check_region([0, 0, 0, 0, 0, 0]) == (0.0,) * 6  # a flat box is allowed
    cam = ring_cameras(1, width=48, height=40)[0]
    pts = np.array([[0.0, 0.0, 0.0], [0.5, 0.0, 0.0], [-0.5, 0.0, 0.0]])
    uv = np.array([[cam.fx * p[0] / p[2] + cam.cx, cam.fy * p[1] / p[2] + cam.cy] for p in
                   (pts @ cam.world_to_cam[:3, :3].T + cam.world_to_cam[:3, 3])])
    (u0, v0), (u1, _v1) = uv[0], uv[1]
    rect = (min(u0, u1) - 1, v0 - 1, max(u0, u1) + 1, v0 + 1)  # corners in either order
    assert rect_mask(pts, cam, rect).tolist() == [True, True, False]
    assert rect_mask(pts, cam, (rect[2], rect[3], rect[0], rect[1])).tolist() == [True, True, False]
    behind = -(cam.world_to_cam[:3, :3].T @ cam.world_to_cam[:3, 3]) * 2  # beyond the camera, opposite the scene
    assert not rect_mask(behind[None], cam, (0, 0, 48, 40)).any()


def test_a_region_that_selects_nothing_is_a_clear_error():
    with pytest.raises(RegionError, match="selects none of the 200 Gaussians"):
        make_engine(region=(50, 50, 50, 60, 60, 60))
    with pytest.raises(RegionError, match="selects none"):
        make_engine(region=None, selection=np.zeros(200, bool))
    with pytest.raises(RegionError, match="shape"):
        selection_mask(np.zeros((5, 3)), selection=np.ones(4, bool))
    with pytest.raises(ValueError, match="finite"):
        resolve_settings("preview", "forward", 3, region=(0, 0, float("nan"), 1, 1, 1))


# ====================================================================== the engine and the export
def test_outside_gaussians_come_out_of_the_export_untouched(finished, tmp_path):
    scene = blob_scene(200, seed=5, sh_degree=3)
    outside = ~box_mask(scene.means, HALF)
    assert 20 < outside.sum() < 180
    path = tmp_path / "region.ply"
    save_scene(finished.stylized_scene(), path)
    out = load_scene(path)[0]
    assert out.sh_rest.shape[1] == 15  # the outside Gaussians keep their SH bands
    kept = ~finished.selection
    assert kept.sum() == outside.sum()
    rows = finished.origin[kept]
    assert sorted(rows.tolist()) == np.flatnonzero(outside).tolist()
    for name in FIELDS:  # float-identical, every attribute
        assert np.array_equal(getattr(out, name)[kept], getattr(scene, name)[rows]), name
    # ... and the engine never moved them (refits, clamps and colour matches leave them be)
    for name in FIELDS[:5]:
        assert np.array_equal(finished.params[name].detach().numpy()[kept], getattr(scene, name)[rows]), name
    assert np.array_equal(out.sh_rest[~kept], np.zeros_like(out.sh_rest[~kept]))  # stylized: diffuse only


def test_only_the_selected_gaussians_are_split_refitted_and_stylized(finished):
    e = finished
    selected_at_start = int(box_mask(blob_scene(200, seed=5).means, HALF).sum())
    assert e.gaussian_count > 200 and int(e.selection.sum()) > selected_at_start  # children inherit the selection
    assert int((~e.selection).sum()) == 200 - selected_at_start  # no outside Gaussian was split
    assert e.counters["optimised_colours"] <= int(e.selection.sum())
    assert e.counters["refit_gaussians"] <= int(e.selection.sum())
    sel = e.selection
    c_gt, c_s = e.gt_colours().numpy(), e.c_s.numpy()
    assert np.array_equal(c_s[~sel], c_gt[~sel])  # outside: their own colour
    assert np.abs(c_s[sel] - c_gt[sel]).mean() > 0.1  # inside: the painting's
    assert c_s[sel, 0].mean() > c_gt[sel, 0].mean() + 0.1  # redder (the style is red)
    assert "109 of 200 Gaussians selected" in e.decisions["region"]


def test_the_losses_see_only_the_selected_part():
    seen = []

    class Recording(MeanColourPull):
        def __call__(self, image, content, view, coverage=None):
            seen.append(coverage)
            return super().__call__(image, content, view, coverage)

    settings = resolve_settings("preview", "forward", 3, max_views=3, epochs=1, min_steps=0, working_width=32,
                                preprocess_rounds=0, split_rate=0.0, region=HALF)
    scene = blob_scene(200, seed=5)
    e = Stylizer(scene, ring_cameras(3), red(), settings, objective_factory=Recording)
    while e.phase != "stylize":
        e.step()
    e.step()
    cov = seen[0]
    assert cov is not None and torch.equal(cov, e.region_coverage[0])
    # the scene's coverage where the outside Gaussians alone are: the objective's weight there is (near) 0
    from gstyle_core.fit.model import params_from_scene, render_params

    inside = box_mask(scene.means, HALF)
    alone = {k: render_params(params_from_scene(scene.subset(np.flatnonzero(m))), e.cameras[0]).alpha
             for k, m in (("in", inside), ("out", ~inside))}
    only_outside = (alone["out"] > 0.5) & (alone["in"] < 1e-3)
    assert only_outside.sum() > 10
    assert float(cov[only_outside].max()) < 1e-3
    assert float(cov.sum()) < float(e.coverage[0].sum()) * 0.9
    assert "selected region" in e.decisions["network_area"]


# ====================================================================== checkpoints
def test_the_selection_is_checkpointed_with_the_rest(finished):
    e = make_engine()
    while e.splits_done == 0:  # past the colour-gradient split: the selection grew with children
        e.step()
    state = e.state_dict()
    other = make_engine()
    other.load_state_dict(state)
    assert np.array_equal(other.selection, e.selection) and np.array_equal(other.origin, e.origin)
    other.run()
    e.run()
    assert np.array_equal(other.stylized_scene().sh_dc, e.stylized_scene().sh_dc)
    with pytest.raises(ValueError, match="selected region"):
        make_engine(region=None).load_state_dict(state)
    fp = engine_fingerprint(e)
    assert fp["settings"] != engine_fingerprint(make_engine(region=(-10, -10, -10, 0.1, 10, 10)))["settings"]
    sel = np.zeros(200, bool)
    sel[:50] = True
    assert engine_fingerprint(make_engine(region=None, selection=sel))["selection"] != \
        engine_fingerprint(make_engine(region=None, selection=~sel))["selection"]


# ====================================================================== command line and OUT.json
def test_cli_region_is_refused_when_invalid(capsys):
    from gstyle_core.cli import stylize as cli

    parser = argparse.ArgumentParser()
    cli.add_stylize_arguments(parser)
    with pytest.raises(SystemExit):
        parser.parse_args(["--region", "1,0,0,0,1,1"])
    assert "x0 = 1 is larger than x1 = 0" in capsys.readouterr().err
    assert parser.parse_args(["--region=-1,-2,-3,1,2,3"]).region == (-1, -2, -3, 1, 2, 3)  # "=": a leading minus


def test_cli_region_runs_and_is_recorded(tmp_path, monkeypatch):
    from gstyle_core.cli import stylize as cli
    from gstyle_core.engine import objective

    monkeypatch.setattr(objective, "StyleObjective", MeanColourPull)
    monkeypatch.setattr(cli, "evaluate_run", lambda engine, scene, style, **_: {
        "images": (np.zeros((4, 4, 3), np.float32), np.zeros((4, 4, 3), np.float32)),
        "initial": {"nnfm": 1.0}, "final": {"nnfm": 1.0}, "nnfm_drop": 0.0, "structure": 1.0})
    scene = blob_scene(120, seed=2, sh_degree=1)
    scene_path, style_path = tmp_path / "s.ply", tmp_path / "red.png"
    save_scene(scene, scene_path)
    from PIL import Image

    Image.fromarray((red() * 255).astype(np.uint8)).save(style_path)
    parser = argparse.ArgumentParser()
    cli.add_stylize_arguments(parser)
    out = tmp_path / "o.ply"
    args = parser.parse_args([str(scene_path), "--style", str(style_path), "--out", str(out), "--working-width", "32",
                              "--region=-5,-5,-5,0,5,5", "--scene-kind", "forward"])
    assert cli.stylize_command(args) == 0
    summary = json.loads(out.with_suffix(".json").read_text())
    assert summary["source_scene"] == str(scene_path.resolve())  # the result reopens with its way back
    inside = box_mask(scene.means, (-5, -5, -5, 0, 5, 5))
    assert summary["settings"]["region"] == [-5, -5, -5, 0, 5, 5]
    assert summary["region"]["box"] == [-5, -5, -5, 0, 5, 5]
    assert summary["region"]["selected"] == int(inside.sum()) and summary["region"]["total"] == 120
    assert "selected and stylized" in summary["decisions"]["region"]
    written = load_scene(out)[0]
    assert written.sh_rest.shape[1] == 3
    outside_rows = {tuple(r) for r in np.concatenate([scene.means[~inside], scene.sh_rest[~inside].reshape(-1, 9)],
                                                     axis=1).tolist()}
    written_rows = {tuple(r) for r in np.concatenate([written.means, written.sh_rest.reshape(-1, 9)], axis=1).tolist()}
    assert outside_rows <= written_rows  # every outside Gaussian, SH bands included, is in the file as it was


# ====================================================================== a soft edge
def test_feather_weights_fall_from_one_inside_to_zero_at_the_feather():
    from gstyle_core.engine.region import feather_weights, grown_box

    box = (0.0, 0.0, 0.0, 1.0, 1.0, 1.0)
    points = np.array([[0.5, 0.5, 0.5], [1.0, 0.5, 0.5], [1.1, 0.5, 0.5], [1.2, 0.5, 0.5], [1.3, 1.3, 0.5],
                       [-0.5, 0.5, 0.5]])
    w = feather_weights(points, box, 0.2)
    assert w.tolist() == pytest.approx([1.0, 1.0, 0.5, 0.0, 0.0, 0.0], abs=1e-6)
    assert feather_weights(points, box, 0.0).tolist() == [1.0, 1.0, 0.0, 0.0, 0.0, 0.0]  # the hard edge
    assert grown_box(box, 0.25) == (-0.25, -0.25, -0.25, 1.25, 1.25, 1.25)


def test_a_feathered_region_fades_the_style_out_across_its_band():
    """The band outside the box is selected and stylized too, and shown and exported mixed with its own colours by
    its distance: full style inside, the scene's colours beyond the feather."""
    from gstyle_core.engine.region import feather_weights
    from gstyle_core.scene import sh_dc_to_rgb

    scene = blob_scene(200, seed=5, sh_degree=0)
    hard = make_engine(scene=scene, region_feather=0.0)
    soft = make_engine(scene=scene, region_feather=0.3)
    in_band = (feather_weights(scene.means, HALF, 0.3) > 0) & ~box_mask(scene.means, HALF)
    assert in_band.sum() > 5
    assert soft.input_selection.sum() == hard.input_selection.sum() + in_band.sum()
    assert "feathered over 0.3 scene units" in soft.decisions["region"]
    soft.run()
    out = soft.stylized_scene()
    rgb, gt = sh_dc_to_rgb(out.sh_dc), soft.run_state.gt_rgb().numpy()
    c_s = soft.c_s.detach().clamp(0, 1).numpy()
    w = feather_weights(soft.params["means"].detach().numpy(), HALF, 0.3)[:, None]
    selected = soft.selection
    np.testing.assert_allclose(rgb[selected], (gt + w * (c_s - gt))[selected], atol=2e-3)
    inside = selected & (w[:, 0] == 1.0)
    assert np.abs(rgb[inside] - c_s[inside]).max() < 2e-3  # full style inside the box
    np.testing.assert_allclose(soft.snapshot()["colors"], np.clip(gt + w * (c_s - gt), 0, 1), atol=1e-5)
