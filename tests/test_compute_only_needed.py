"""Compute only the effects a scene needs (issue #7 §3).

Each decision is (a) reported in ``Stylizer.decisions`` (hence OUT.json) or the studio's panel, (b) shown by
counters to skip its work, and (c) shown to leave results unchanged where the skipped effect had no influence.
"""

from __future__ import annotations

import multiprocessing
import queue
import re

import numpy as np
import pytest
import torch
from fakes import MeanColourPull, make_small_stylizer
from synthetic import blob_scene, look_at_camera

from gstyle_core.engine.flat_split import EVEN_ELONGATED_FRACTION, EVEN_FLAT_FRACTION, evenness_verdict
from gstyle_core.engine.settings import resolve_settings
from gstyle_core.engine.stylizer import Stylizer
from gstyle_core.engine.visibility import seen_mask
from gstyle_core.raster import rasterize
from gstyle_core.scene import GaussianScene, logit, used_sh_degree

N_HIDDEN = 90


def cameras(width: int = 48, height: int = 40):
    """Three forward-facing cameras at z = -3 looking towards +z."""
    return [look_at_camera((x, 0.0, -3.0), (0, 0, 0), width, height) for x in (-0.6, 0.0, 0.6)]


def hidden_block() -> GaussianScene:
    """90 Gaussians no camera sees: 30 behind every camera, 30 far beside every view, 30 below the 1/255 cut-off."""
    block = blob_scene(N_HIDDEN, seed=11, spread=0.3)
    block.means[:30] += np.array([0.0, 0.0, -7.0], np.float32)
    block.means[30:60] += np.array([25.0, 0.0, 0.0], np.float32)
    block.opacity_logits[60:] = logit(np.full(30, 1e-3))  # in front of the cameras, in view, but transparent
    return block


def style_image() -> np.ndarray:
    style = np.zeros((8, 8, 3), np.float32)
    style[..., 0] = 1.0
    style[::2, :, 2] = 0.5
    return style


def engine(scene: GaussianScene, objective_factory=MeanColourPull, photos=None, **overrides) -> Stylizer:
    opts = dict(max_views=3, epochs=3, min_steps=0, refit_iterations=2, split_at=(1 / 3,), working_width=40,
                preprocess_rounds=1)
    opts.update(overrides)
    settings = resolve_settings("preview", "forward", 3, **opts)
    return Stylizer(scene, cameras(), style_image(), settings, objective_factory=objective_factory, photos=photos)


def tensors(scene: GaussianScene) -> tuple[torch.Tensor, ...]:
    def t(a):
        return torch.from_numpy(np.ascontiguousarray(a, np.float32))

    return t(scene.means), t(scene.quats), t(scene.scales), t(scene.opacities)


def unseen_counts(text: str) -> tuple[int, int]:
    match = re.match(r"(\d+) of (\d+) Gaussians seen by no training camera", text)
    assert match, text
    return int(match.group(1)), int(match.group(2))


# ====================================================================== culling Gaussians no camera sees
def test_seen_mask_drops_exactly_gaussians_that_add_nothing():
    visible = blob_scene(150, seed=3)
    scene = GaussianScene.concatenate([hidden_block(), visible])
    means, quats, scales, opacities = tensors(scene)
    mask = seen_mask(means, quats, scales, opacities, cameras())
    assert not mask[:N_HIDDEN].any()  # behind, beside and transparent: all dropped
    assert mask[N_HIDDEN:].sum() >= 140  # the blob in front is (nearly all) kept
    sub = torch.nonzero(mask).flatten()
    colours = torch.from_numpy(scene.rgb.astype(np.float32))
    for cam in cameras():
        viewmat, K = (torch.from_numpy(np.asarray(m, np.float32)) for m in (cam.world_to_cam, cam.K))
        full = rasterize(means, quats, scales, opacities, colours, viewmat, K, cam.width, cam.height)
        part = rasterize(means[sub], quats[sub], scales[sub], opacities[sub], colours[sub], viewmat, K,
                         cam.width, cam.height)
        assert full.image.abs().sum() > 0
        torch.testing.assert_close(part.image, full.image, atol=1e-7, rtol=0)
        torch.testing.assert_close(part.alpha, full.alpha, atol=1e-7, rtol=0)


@pytest.mark.slow
def test_unseen_gaussians_are_not_rendered_optimised_or_split():
    visible = blob_scene(150, seed=3)
    block = hidden_block()
    a = engine(GaussianScene.concatenate([block, visible]))  # the hidden block first: it stays at [:N_HIDDEN]
    b = engine(visible)
    after_match = None
    while not a.done:
        a.step()
        if a.phase == "stylize" and after_match is None:
            after_match = a.c_s[:N_HIDDEN].clone()  # c_s of the block right after the colour match
        if a.phase == "finish":  # stylization over: the block's colours were never touched
            torch.testing.assert_close(a.c_s[:N_HIDDEN], after_match, atol=0, rtol=0)
    b.run()
    # (a) reported, with the counts
    unseen_a, total_a = unseen_counts(a.decisions["culled"])
    unseen_b, total_b = unseen_counts(b.decisions["culled"])
    assert (unseen_a - unseen_b, total_a - total_b) == (N_HIDDEN, N_HIDDEN)
    # (b) counters: every cache, the optimiser and every refit held exactly the Gaussians of the run without the block
    assert a.counters["cache_builds"] > 0 and a.counters["visibility_passes"] >= 2
    assert a.counters == b.counters
    # never split, never moved
    assert a.gaussian_count - b.gaussian_count == N_HIDDEN
    start = block.with_sh_degree(0)
    for key in ("means", "log_scales", "quats", "opacity_logits", "sh_dc"):
        assert np.array_equal(a.params[key].detach().numpy()[:N_HIDDEN], getattr(start, key)), key
    # (c) the visible part is the run without the block: the same operations on the same shapes (the counters
    # above), so no rounding tells them apart on any CPU (measured: identical at 1 and 2 threads)
    for key in ("means", "log_scales", "quats", "opacity_logits", "sh_dc"):
        torch.testing.assert_close(a.params[key].detach()[N_HIDDEN:], b.params[key].detach(), atol=1e-5, rtol=0)
    torch.testing.assert_close(a.c_s[N_HIDDEN:], b.c_s, atol=1e-5, rtol=0)
    assert b.gaussian_count > visible.count  # the comparison covered pre-processing and colour-gradient splits


def test_without_culling_every_gaussian_is_cached_and_optimised():
    scene = GaussianScene.concatenate([hidden_block(), blob_scene(150, seed=3)])
    eng = engine(scene, cull_unseen=False, preprocess_rounds=0)
    while eng.phase != "stylize":
        eng.step()
    eng.step()
    assert eng.decisions["culled"].startswith("off")
    assert eng.counters["visibility_passes"] == 0
    assert eng.counters["cache_gaussians"] == eng.counters["optimised_colours"] == scene.count


# ====================================================================== pre-processing skipped for even sizes
def even_scene(n: int = 150) -> GaussianScene:
    scene = blob_scene(n, seed=3)
    scene.log_scales[:] = np.log(0.06)  # every Gaussian the same round size
    return scene


def test_evenness_verdict_thresholds():
    even, text = evenness_verdict({"area_cv": 0.1, "flat_fraction": 0.0, "elongated_fraction": 0.0})
    assert even and "flat fraction 0.0000 (even below 0.001)" in text
    assert not evenness_verdict({"area_cv": 0.1, "flat_fraction": EVEN_FLAT_FRACTION, "elongated_fraction": 0})[0]
    assert not evenness_verdict({"area_cv": 0.1, "flat_fraction": 0, "elongated_fraction": EVEN_ELONGATED_FRACTION})[0]


def test_preprocessing_is_skipped_for_even_sizes_and_forcing_it_buys_nothing():
    skipped = engine(even_scene(), split_rate=0.0)
    forced = engine(even_scene(), split_rate=0.0, force_preprocess=True)
    phases = {}
    for eng in (skipped, forced):
        reports = []
        while not eng.done:
            reports.append(eng.step())
        phases[id(eng)] = [r.phase for r in reports]
    assert skipped.decisions["preprocess"].startswith("skipped: Gaussian sizes already even (flat fraction 0.0000")
    assert skipped.decisions["size_evenness"] == {"area_cv": 0.0, "flat_fraction": 0.0, "elongated_fraction": 0.0}
    assert forced.decisions["preprocess"].startswith("1 round(s), forced although the sizes are even")
    # the work skipped: the pre-processing round (its split and its refit iterations)
    assert "preprocess" not in phases[id(skipped)]
    assert phases[id(forced)].count("preprocess") == forced.settings.refit_iterations + 1
    assert forced.gaussian_count == skipped.gaussian_count == 150  # forced, it found nothing to split
    # it had no influence beyond the refit's small drift: the stylized views agree (the drift is the forced refit's
    # Adam steps, about lr each whatever the gradient, not rounding: measured mean 7.5e-4 at most, 13x under)
    for cam in cameras():
        images = []
        for eng in (skipped, forced):
            means, quats, scales, opacities = tensors(eng.stylized_scene())
            viewmat, K = (torch.from_numpy(np.asarray(m, np.float32)) for m in (cam.world_to_cam, cam.K))
            images.append(rasterize(means, quats, scales, opacities, eng.c_s.float(), viewmat, K, cam.width,
                                    cam.height).image)
        assert float((images[0] - images[1]).abs().mean()) < 0.01


def test_uneven_sizes_are_preprocessed_with_the_criterion_reported():
    eng = engine(blob_scene(150, seed=3), preprocess_rounds=1)
    while eng.phase == "ground_truth":
        eng.step()
    assert eng.phase == "preprocess"
    assert eng.decisions["preprocess"].startswith("1 round(s), sizes uneven (flat fraction")
    assert eng.decisions["size_evenness"]["flat_fraction"] > EVEN_FLAT_FRACTION


# ====================================================================== loss terms of weight 0, CLIP without weights
@pytest.fixture
def random_vgg_objective(vgg, no_clip_weights):
    """The real StyleObjective on a randomly initialised VGG, with no CLIP weights anywhere."""
    from gstyle_core.engine.objective import StyleObjective

    return lambda style, settings: StyleObjective(style, settings, vgg=vgg)


def _render_gradient(eng: Stylizer, image: torch.Tensor, view: int) -> torch.Tensor:
    """The gradient of the engine's stylization loss for ``view`` with respect to the rendered ``image``."""
    leaf = image.detach().clone().requires_grad_(True)
    loss, _ = eng.build_objective()(leaf, eng.content_images[view], view, coverage=eng.objective_coverage(view))
    loss.backward()
    return leaf.grad


@pytest.mark.slow
def test_zero_weight_terms_are_never_computed_and_change_nothing(random_vgg_objective):
    common = dict(preprocess_rounds=0, split_rate=0.0, colour_match_after=False, epochs=1, lambda_clip=0.0,
                  lambda_multiscale=0.0, lambda_chroma_tv=0.0)
    skipped = engine(blob_scene(150, seed=3), random_vgg_objective, lambda_content=0.0, **common)
    tiny = engine(blob_scene(150, seed=3), random_vgg_objective, lambda_content=1e-9, **common)
    while skipped.phase != "stylize":
        skipped.step()
    start = skipped.c_s.clone()
    skipped.run()
    tiny.run()
    steps = skipped.stylize_steps
    assert skipped.decisions["loss_terms"] == ("computed: nnfm, tv; never computed (weight 0): clip, content, "
                                               "multiscale, chroma_tv, edges")
    assert skipped.decisions["clip"] == "CLIP term off (λ_CLIP = 0)"
    assert skipped.objective.calls == {"vgg": steps, "clip": 0}  # NNFM only: no content features, no CLIP
    assert tiny.objective.calls == {"vgg": steps + len(tiny.cameras), "clip": 0}  # + one content pass per view
    assert float((skipped.c_s - start).abs().max()) > 1e-3  # the runs did change the colours
    # Skipping the term changes nothing: at one state both objectives give the same gradient. (Not the colours after
    # the runs: Adam moves a colour by about lr whatever its gradient's size, so a near-zero gradient whose sign
    # depends on float32 rounding can move the runs apart on another CPU.) The state: the final renders' negatives,
    # far from the content targets, where the content term pulls hardest. The only arithmetic difference is the
    # added 1e-9 x content gradient, which changes each sum of the backward pass by at most one rounding (2^-24 of its
    # size); the VGG backward carries that on linearly: a few ulps of the largest gradient. 16 ulps holds that with
    # margin. Measured here: identical at 1e-9; λ_content = 1e-3 gives 4.1 ulps, 0.05 (the default) 29, 1.0 fails.
    eps = torch.finfo(torch.float32).eps
    for view in range(len(skipped.cameras)):
        image = 1.0 - skipped.render(view)
        g_skipped, g_tiny = _render_gradient(skipped, image, view), _render_gradient(tiny, image, view)
        torch.testing.assert_close(g_tiny, g_skipped, rtol=0, atol=16 * eps * float(g_skipped.abs().max()))


def test_clip_without_weights_never_runs_and_weights_set_to_zero_stop_the_networks(random_vgg_objective):
    eng = engine(blob_scene(150, seed=3), random_vgg_objective, preprocess_rounds=0, split_rate=0.0,
                 lambda_clip=10.0, lambda_content=0.0, lambda_multiscale=0.0, lambda_chroma_tv=0.0)
    while eng.phase != "stylize":
        eng.step()
    eng.step()
    assert "not found" in eng.decisions["clip"] and "substitute" in eng.decisions["clip"]
    assert eng.objective.calls == {"vgg": 2, "clip": 0}  # NNFM + the coarse-VGG substitute; the ViT never runs
    eng.set_params(lambda_clip=0.0, lambda_nnfm=0.0)
    assert eng.decisions["loss_terms"] == ("computed: tv; never computed (weight 0): clip, nnfm, content, multiscale, "
                                           "chroma_tv, edges")
    eng.step()
    assert eng.objective.calls == {"vgg": 2, "clip": 0}


# ====================================================================== view-dependent SH only where it shows
@pytest.fixture
def sh_calls(monkeypatch):
    """Record the degree of every SH evaluation the rasterizer makes."""
    import gstyle_core.raster.render as render_module

    calls: list[int] = []
    original = render_module.eval_sh_colors

    def counting(coeffs, means, camera_position, degree):
        calls.append(int(degree))
        return original(coeffs, means, camera_position, degree)

    monkeypatch.setattr(render_module, "eval_sh_colors", counting)
    return calls


def test_sh_is_evaluated_only_for_ground_truth_renders(sh_calls):
    eng = engine(blob_scene(120, seed=4, sh_degree=3), preprocess_rounds=0, split_rate=0.0, epochs=1)
    for _ in range(len(eng.cameras)):
        eng.step()
    assert sh_calls == [3] * len(eng.cameras)  # one degree-3 evaluation per ground-truth view
    eng.run()
    assert [d for d in sh_calls if d > 0] == [3] * len(eng.cameras)  # never during stylization
    assert eng.decisions["sh"].startswith("SH evaluated only for the 3 ground-truth renders at degree 3")
    assert eng.stylized_scene().sh_degree == 0


def test_sh_is_never_evaluated_with_photos(sh_calls):
    photos = [np.full((40, 48, 3), 0.5, np.float32)] * 3
    eng = engine(blob_scene(120, seed=4, sh_degree=3), photos=photos, preprocess_rounds=0, split_rate=0.0, epochs=1)
    eng.run()
    assert [d for d in sh_calls if d > 0] == []
    assert eng.decisions["sh"].startswith("SH degree 3 never evaluated: ground truth from photos")


def test_all_zero_sh_bands_are_skipped_with_identical_ground_truth(sh_calls):
    scene = blob_scene(120, seed=4, sh_degree=3)
    scene.sh_rest[:, 3:] = 0.0  # degree 2 and 3 bands all zero: only degree 1 shows
    assert used_sh_degree(scene.sh_rest) == 1
    eng = engine(scene, preprocess_rounds=0)
    for _ in range(len(eng.cameras)):
        eng.step()
    assert sh_calls == [1] * len(eng.cameras)
    assert "degree 1 (higher bands are all zero)" in eng.decisions["sh"]
    coeffs = torch.from_numpy(np.concatenate([scene.sh_dc[:, None], scene.sh_rest], 1))
    # The engine renders from its parameters (torch's exp and sigmoid), this render from the scene's numpy-derived
    # scales and opacities: they may differ by an ulp, which moves each of the few Gaussians a pixel blends by a few
    # ulps of the pixel's value (<= 1). The zero bands themselves add exact zeros. 32 ulps: measured here 1 ulp.
    eps = torch.finfo(torch.float32).eps
    for cam, gt in zip(eng.cameras, eng.gt_images, strict=True):
        viewmat, K = (torch.from_numpy(np.asarray(m, np.float32)) for m in (cam.world_to_cam, cam.K))
        full = rasterize(*tensors(scene), coeffs, viewmat, K, cam.width, cam.height, sh_degree=3).image
        torch.testing.assert_close(gt, full.clamp(0, 1), atol=32 * eps, rtol=0)


# ====================================================================== the viewer: no re-sort, no re-upload
def viewer_arrays(n: int = 200, sh_degree: int = 0) -> dict[str, np.ndarray]:
    from app.studio import scene_arrays

    return scene_arrays(blob_scene(n, seed=2, sh_degree=sh_degree))


def test_renderer_unchanged_frame_does_no_sort_or_upload_and_colours_upload_alone(ctx):
    from app.renderer import SplatRenderer

    cam = look_at_camera((0.2, -0.5, -3.0), (0, 0, 0), 64, 48)
    fbo = ctx.framebuffer([ctx.texture((64, 48), 4, dtype="f4")])
    r = SplatRenderer(ctx)
    r.set_scene(viewer_arrays())
    assert r.uploads == {"geometry": 1, "colors": 1}
    r.render(cam, fbo)
    r.render(cam, fbo)  # same view, same data
    assert (r.sort_count, r.uploads) == (1, {"geometry": 1, "colors": 1})
    r.update_colors(np.full((r.count, 3), 0.3, np.float32))  # colour-only update
    r.render(cam, fbo)
    assert (r.sort_count, r.uploads) == (1, {"geometry": 1, "colors": 2})
    r.render(look_at_camera((0.4, -0.5, -3.0), (0, 0, 0), 64, 48), fbo)  # the view moved: a sort, no upload
    assert (r.sort_count, r.uploads) == (2, {"geometry": 1, "colors": 2})
    r.release()


def test_renderer_evaluates_sh_on_the_gpu_for_real_sh_only_and_uploads_nothing_when_the_camera_moves(ctx):
    from app.gl_io import read_rgb_float
    from app.renderer import SH_LAYER, SplatRenderer
    from app.splat_data import sh_colors

    fbo = ctx.framebuffer([ctx.texture((64, 48), 4, dtype="f4")])
    r = SplatRenderer(ctx, layout="float32")  # exact colours both ways (half-float SH: test_app_renderer)
    arrays = viewer_arrays(sh_degree=3)
    r.set_scene(arrays)
    assert SH_LAYER in r.layers
    uploads = dict(r.uploads)  # geometry, diffuse colours and the SH coefficients: once
    sh = np.concatenate([arrays["sh_dc"][:, None], arrays["sh_rest"]], 1)
    for eye in ((0.2, -0.5, -3.0), (0.5, -0.5, -3.0), (-1.0, 0.3, -2.5)):
        cam = look_at_camera(eye, (0, 0, 0), 64, 48)
        r.render(cam, fbo, layer=SH_LAYER)
        on_gpu = read_rgb_float(fbo)
        r.update_colors(sh_colors(sh, arrays["means"], cam.position), "evaluated")  # the CPU's evaluation
        r.render(cam, fbo, layer="evaluated")
        np.testing.assert_allclose(on_gpu, read_rgb_float(fbo), atol=2e-5)
    assert r.uploads["colors"] == uploads["colors"] + 3  # only this test's own layer "evaluated"
    # a degree-3 scene whose higher bands are all zero has no SH to show: no layer, no coefficients uploaded
    arrays["sh_rest"] = np.zeros_like(arrays["sh_rest"])
    r.set_scene(arrays)
    assert SH_LAYER not in r.layers and r.uploads["colors"] == uploads["colors"] + 4  # + the diffuse layer
    r.release()


class _StubBridge:
    """Just enough of WorkerBridge for StudioApp's snapshot handling."""

    def __init__(self) -> None:
        from app.worker import WorkerState

        self.state = WorkerState(alive=True)

    def poll(self) -> list:
        return []

    def quit(self) -> None:
        pass


def test_studio_uploads_only_what_changed_and_shows_decisions(ctx, tmp_path):
    pytest.importorskip("imgui_bundle")
    from app.studio import LoadedScene, StudioApp

    scene = blob_scene(200, seed=2, sh_degree=3)
    app = StudioApp(ctx, loaded=LoadedScene("synthetic", scene, cameras(64, 48)), output_dir=tmp_path)
    try:
        assert "sh" in app.views.original.layers and "sh" not in app.views.stylized.layers  # SH: original view only
        bridge = app.engine.bridge = _StubBridge()
        geometry = {k: getattr(scene, k) for k in ("means", "log_scales", "quats", "opacity_logits")}

        def deliver(colour_version, geometry_version, colours):
            bridge.state.snapshot.update(geometry, colors=np.full((200, 3), colours, np.float32),
                                         colors_gt=np.full((200, 3), 0.5, np.float32),
                                         colour_version=colour_version, geometry_version=geometry_version)
            bridge.state.snapshots_received += 1
            app.sync.apply_updates()
            return dict(app.views.stylized.uploads)

        first = deliver(0, 0, 0.2)
        assert deliver(0, 0, 0.2) == first  # nothing changed: no upload at all
        colour_only = deliver(1, 0, 0.4)
        assert colour_only == {"geometry": first["geometry"], "colors": first["colors"] + 1}  # diffuse only
        moved = deliver(1, 1, 0.4)
        assert moved == {"geometry": first["geometry"] + 1, "colors": colour_only["colors"] + 2}  # + c_s and c_gt
        bridge.state.decisions = {"culled": "3 of 200 Gaussians seen by no training camera"}
        app.fill_panel()
        assert app.panel.decisions["culled"].startswith("3 of 200")
        assert app.panel.viewer_notes[0].startswith("viewer SH: evaluated for the original scene only")
        assert "depth sorts" in app.panel.viewer_notes[1]
    finally:
        app.engine.bridge = None
        app.close()


# ====================================================================== decisions reach the app
def test_engine_decisions_are_forwarded_by_the_worker_and_listed_by_the_panel():
    from app.engine_host import EngineHost
    from app.panels import decision_lines
    from app.worker import WorkerBridge

    events: queue.Queue = queue.Queue()
    host = EngineHost(make_small_stylizer, {"n": 150}, events, multiprocessing.Semaphore(2), None)
    host.build()
    for _ in range(4):
        host.step()
    bridge = WorkerBridge(make_small_stylizer)

    def drain() -> list[tuple[str, object]]:
        out = []
        while not events.empty():
            kind, payload = events.get()
            out.append((kind, payload))
            if kind != "snapshot":
                bridge._apply(kind, payload)
        return out

    sent = [payload for kind, payload in drain() if kind == "decisions"]
    assert len(sent) >= 2  # at build, then as the engine decided (pre-processing, culling)
    assert all(a != b for a, b in zip(sent[:-1], sent[1:], strict=True))  # only when they changed
    assert bridge.state.decisions == host.engine.decisions
    assert host.engine.phase == "preprocess"
    host.step()  # a refit iteration: the decisions stay as they are, nothing is sent
    kinds = [kind for kind, _ in drain()]
    assert "report" in kinds and "decisions" not in kinds
    lines = decision_lines(bridge.state.decisions)
    assert any(line.startswith("culled: ") for line in lines)
    assert any(line.startswith("size evenness: area_cv=") for line in lines)


def test_decisions_section_draws_every_line_when_open_and_none_when_closed(monkeypatch):
    pytest.importorskip("imgui_bundle")
    from imgui_bundle import imgui
    from imgui_driver import install

    from app.panels import PanelState, decision_lines
    from app.panels.run_sections import decisions_section
    from app.window import DisplayUnavailableError, open_window

    try:
        win = open_window(320, 240, headless=True)
    except DisplayUnavailableError as exc:
        pytest.skip(f"no headless GL window (glfw NULL + EGL): {exc}")
    recorder = install(monkeypatch)
    state = PanelState(decisions={"preprocess": "0 round(s), sizes even", "reductions": ["a", "b"]},
                       viewer_notes=["x"])
    drawn = {}
    try:
        for is_open in (False, True):
            win.begin_frame()
            imgui.begin("test")
            imgui.set_next_item_open(is_open)
            decisions_section(state)
            imgui.end()
            win.end_frame(swap=False)
            drawn[is_open] = list(recorder.texts)
            recorder.texts.clear()
    finally:
        win.close()
    assert [w.path for w in recorder.widgets] == ["Decisions", "Decisions"]
    assert drawn[False] == []
    assert drawn[True] == ["Splat sizes already even: no splitting before the painting",  # worded for an artist
                           *decision_lines(state.decisions), "x"]
    assert drawn[True][1:] == ["preprocess: 0 round(s), sizes even", "reductions: a; b", "x"]


def test_checkpoint_resume_with_culled_gaussians_matches_uninterrupted_run():
    scene = GaussianScene.concatenate([hidden_block(), blob_scene(150, seed=3)])
    a = engine(scene, preprocess_rounds=0, epochs=2, refit_iterations=1)
    while a.phase != "stylize" or a.stylize.step_index < 2:  # inside stylization: Adam holds the seen colours only
        a.step()
    assert a.stylize.c_opt is not None and a.stylize.c_opt.shape[0] < a.gaussian_count
    b = engine(scene, preprocess_rounds=0, epochs=2, refit_iterations=1)
    b.load_state_dict(a.state_dict())
    a.run()
    b.run()
    assert a.gaussian_count == b.gaussian_count
    torch.testing.assert_close(b.c_s, a.c_s, atol=1e-5, rtol=0)
    assert b.decisions["culled"] == a.decisions["culled"]


@pytest.mark.parametrize("views_per_step", [1, 3])
def test_every_term_off_steps_through_to_the_end_and_leaves_the_colours_alone(vgg, no_clip_weights, views_per_step):
    """An artist may turn every λ to 0: each step's loss is then a constant with nothing to backpropagate (it raised
    'element 0 of tensors does not require grad' until #48); the run goes on, VGG never runs and the stylization
    moves no colour."""
    from fakes import engine_at_stylize
    from synthetic import blob_scene as scene_of

    off = {f"lambda_{t}": 0.0 for t in ("clip", "nnfm", "multiscale", "content", "tv", "chroma_tv", "edges")}
    style = np.random.default_rng(0).uniform(size=(24, 24, 3)).astype(np.float32)
    engine = engine_at_stylize(vgg, scene_of(150, seed=3), style, views_per_step=views_per_step, **off)
    before = engine.run_state.c_s.clone()
    while engine.phase == "stylize":
        report = engine.step()
        assert report.losses["total"] == 0.0
    assert torch.equal(engine.run_state.c_s, before)
    assert engine.build_objective().calls["vgg"] == 0
