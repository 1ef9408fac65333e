"""The speckle figure at the display's size (``style/speckle.py``), the colour-smoothness term and the detail-keeping
colour match (issue #34)."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from synthetic import blob_scene, ring_cameras
from test_resume_phases import NoisyPull

from gstyle_core.engine.run_figures import display_speckle_line
from gstyle_core.engine.settings import resolve_settings
from gstyle_core.engine.stylizer import Stylizer
from gstyle_core.style.losses import StyleLoss, StyleWeights
from gstyle_core.style.pixel_terms import chroma_tv_loss
from gstyle_core.style.speckle import (
    chroma_energies,
    display_speckle,
    fine_share,
    luminance,
    opponent_chroma,
)
from gstyle_core.style.texture_scale import gaussian_blur


def smooth_noise(h: int, w: int, sigma: float, seed: int) -> np.ndarray:
    """Random colour noise blurred by ``sigma`` px, [H, W, 3] about grey."""
    rng = np.random.default_rng(seed)
    planes = torch.as_tensor(rng.normal(size=(3, h, w)), dtype=torch.float64)
    x = gaussian_blur(planes, sigma).permute(1, 2, 0).numpy() if sigma > 0 else planes.permute(1, 2, 0).numpy()
    return 0.5 + 0.2 * x / x.std()


def test_opponent_channels_and_luminance():
    img = np.array([[[1.0, 0.0, 0.0], [0.5, 0.5, 0.5]]])
    np.testing.assert_allclose(opponent_chroma(img)[0], [[1.0, 0.5], [0.0, 0.0]])
    np.testing.assert_allclose(luminance(img)[0, :, 0], [0.299, 0.5])
    grey = np.repeat(smooth_noise(32, 32, 1.0, 0)[..., :1], 3, axis=-1)
    assert chroma_energies(grey).sum() == pytest.approx(0.0, abs=1e-12)  # grey detail has no chroma
    assert chroma_energies(grey, channels="luminance").sum() > 0
    with pytest.raises(ValueError, match="channels"):
        chroma_energies(grey, channels="hue")


def test_fine_noise_has_a_high_fine_share_and_broad_noise_a_low_one():
    assert fine_share(chroma_energies(smooth_noise(96, 96, 0.0, 1))) > 0.8
    assert fine_share(chroma_energies(smooth_noise(96, 96, 8.0, 1))) < 0.1
    assert np.isnan(fine_share(np.zeros(4)))


def test_the_ratio_is_one_when_the_added_colour_is_the_painting_at_its_size():
    painting = smooth_noise(64, 80, 4.0, 3)  # long side 80: matched at 80 px, the renders' size
    before = [np.full((64, 80, 3), 0.5)]
    fig = display_speckle(before, [before[0] + (painting - 0.5)], None, painting, 80)
    assert fig.ratio == pytest.approx(1.0, abs=0.02)
    speckled = display_speckle(before, [before[0] + (smooth_noise(64, 80, 0.0, 4) - 0.5)], None, painting, 80)
    assert speckled.ratio > 2.0 and len(speckled.per_view_ratios) == 1
    d = speckled.to_dict()
    assert d["width"] == 80 and d["channels"] == "chroma" and d["speckle_ratio"] == round(speckled.ratio, 4)
    assert "speckle at 80 px" in display_speckle_line(d)


def test_coverage_weights_the_added_colour_and_bad_inputs_are_refused():
    before = np.full((40, 40, 3), 0.5)
    after = before.copy()
    after[:, :20] += smooth_noise(40, 20, 0.0, 5) - 0.5  # specks on the left only
    after[:, 20:] += smooth_noise(40, 20, 6.0, 6) - 0.5  # broad colour on the right
    left, right = np.zeros((40, 40)), np.zeros((40, 40))
    left[:, :20], right[:, 20:] = 1.0, 1.0
    painting = smooth_noise(40, 40, 3.0, 7)
    assert display_speckle([before], [after], [left], painting, 40).ratio > \
        display_speckle([before], [after], [right], painting, 40).ratio
    grey = np.repeat(painting[..., :1], 3, axis=-1)  # a painting without colour: no ratio (null in JSON)
    assert display_speckle([before], [after], None, grey, 40).to_dict()["speckle_ratio"] is None
    with pytest.raises(ValueError, match="differ in shape"):
        display_speckle([before], [after[:10]], None, painting, 40)
    with pytest.raises(ValueError, match="coverage"):
        display_speckle([before], [after], [left, left], painting, 40)


def test_colour_smoothness_counts_chroma_not_luminance_nor_the_silhouette():
    grey = torch.as_tensor(np.repeat(smooth_noise(24, 24, 0.0, 8)[..., :1], 3, -1)).permute(2, 0, 1)[None].float()
    assert float(chroma_tv_loss(grey)) == pytest.approx(0.0, abs=1e-12)
    speckled = torch.as_tensor(smooth_noise(24, 24, 0.0, 9)).permute(2, 0, 1)[None].float()
    smooth = torch.as_tensor(smooth_noise(24, 24, 4.0, 9)).permute(2, 0, 1)[None].float()
    assert float(chroma_tv_loss(speckled)) > 10 * float(chroma_tv_loss(smooth))
    red_disc = torch.zeros(1, 3, 24, 24)
    cov = torch.zeros(24, 24)
    cov[6:18, 6:18] = 1.0
    red_disc[:, 0] = cov  # a flat red object on black: its edge is the silhouette, not colour noise
    assert float(chroma_tv_loss(red_disc)) > 0
    assert float(chroma_tv_loss(red_disc, cov)) == pytest.approx(0.0, abs=1e-9)
    loss = StyleLoss(None, None, weights=StyleWeights(clip=0, nnfm=0, content=0, tv=0, chroma_tv=2.0))
    loss.chroma_floor = float(chroma_tv_loss(smooth))  # only the variation beyond the painting's counts
    total, terms = loss(speckled)
    assert terms["chroma_tv"] == pytest.approx(float(chroma_tv_loss(speckled)) - loss.chroma_floor, rel=1e-5)
    assert float(total) == pytest.approx(2.0 * terms["chroma_tv"], rel=1e-5)
    assert loss(smooth)[1]["chroma_tv"] == 0.0


def noisy_grey_scene(seed: int = 2):
    """A grey blob whose Gaussians differ slightly in colour, as a fit's colours do."""
    from gstyle_core.scene import rgb_to_sh_dc

    scene = blob_scene(3000, seed=seed, spread=0.5, scale=0.02)
    rng = np.random.default_rng(seed + 1000)  # not the blob's own draws (its positions come from ``seed``)
    scene.sh_dc = rgb_to_sh_dc(np.clip(0.5 + rng.normal(0, 0.02, (scene.count, 3)), 0, 1)).astype(np.float32)
    return scene


def matched_engine(detail_px: float) -> Stylizer:
    settings = resolve_settings("preview", "360", 4, max_views=4, epochs=1, min_steps=0, working_width=32,
                                preprocess_rounds=0, split_rate=0.0, match_detail_px=detail_px)
    painting = np.full((16, 16, 3), 0.5, np.float32)
    painting[:8, :, 0], painting[8:, :, 2] = 0.7, 0.7  # reddish and bluish: far more colourful than the scene
    engine = Stylizer(noisy_grey_scene(), ring_cameras(4), painting, settings, objective_factory=NoisyPull)
    while engine.phase != "stylize":
        engine.step()
    return engine


def test_the_detail_keeping_match_maps_the_palette_without_multiplying_each_gaussians_difference():
    plain, kept = matched_engine(0.0), matched_engine(4.0)
    assert plain.settings.match_detail_px == 0.0 and kept.settings.match_detail_px == 4.0
    gt = plain.gt_colours().double()
    assert torch.equal(kept.gt_colours().double(), gt)
    # each Gaussian's own colour difference (independent of its place): how much of it comes through the match
    x = gt - gt.mean(0)

    def gain(engine) -> torch.Tensor:
        y = engine.c_s.double() - engine.c_s.double().mean(0)
        return torch.linalg.lstsq(x, y).solution  # [3, 3]: y ≈ x @ gain

    eye = torch.eye(3, dtype=torch.float64)
    amplified = [float(torch.linalg.matrix_norm(gain(e) - eye)) for e in (plain, kept)]
    assert amplified[0] > 5.0  # the plain map multiplies it by its gain (the confetti)
    assert amplified[1] < 0.15 * amplified[0]  # the detail-keeping one passes it on (but its share in its base)
    for engine in (plain, kept):  # both move the scene onto the painting's palette (its mean here: the scene's
        # colours vary only Gaussian by Gaussian, so it has no broad colours to spread)
        np.testing.assert_allclose(engine.c_s.mean(0).numpy(), [0.6, 0.5, 0.6], atol=0.03)
    # the content targets are what the matched Gaussians render (inside the scene)
    for engine in (plain, kept):
        run = engine.run_state
        for v in range(len(run.cameras)):
            inside = run.coverage[v] > 0.95
            err = (engine.render(v) - run.content_images[v]).abs().max(-1).values[inside]
            assert float(err.mean()) < (0.02 if engine is plain else 0.05), v


def test_the_defaults_turn_both_on_and_zero_turns_them_off():
    calibrated = resolve_settings("balanced", "360", 24, clip_available=False)
    assert calibrated.match_detail_px == 4.0
    assert calibrated.weights.chroma_tv == pytest.approx(15 * calibrated.weights.nnfm)
    assert calibrated.refine_widths == resolve_settings("final", "360", 24).refine_widths == (512,)
    paper = resolve_settings("preview", "360", 24, defaults="paper")  # not a 360° calibration: there too
    assert paper.match_detail_px == 4.0 and paper.weights.chroma_tv == pytest.approx(15 * paper.weights.nnfm)
    given = resolve_settings("preview", "360", 24, lambda_chroma_tv=7.0, match_detail_px=0.0, clip_available=False)
    assert given.weights.chroma_tv == 7.0 and given.match_detail_px == 0.0

    for bad in (-1.0, float("nan")):
        with pytest.raises(ValueError, match="match_detail_px"):
            resolve_settings("preview", "360", 24, match_detail_px=bad)
