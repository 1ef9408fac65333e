"""The fringe halo figure (``style/fringe.py``, issue #50 item 4): how much brighter stylization made the capture's
fading edge than its body, measured on renders; a run's display figures carry it."""

from __future__ import annotations

import numpy as np
import pytest
from fakes import MeanColourPull
from synthetic import blob_scene, ring_cameras

from gstyle_core.engine.settings import resolve_settings
from gstyle_core.engine.stylizer import Stylizer
from gstyle_core.scene import logit
from gstyle_core.style.fringe import fringe_halo


def test_the_halo_figure_sees_a_brighter_rim():
    """A render whose low-alpha pixels were brightened scores a halo; one brightened evenly scores none."""
    rng = np.random.default_rng(0)
    alpha = np.clip(rng.uniform(-0.3, 1.0, (40, 48)), 0.0, 1.0)
    colour = rng.uniform(0.2, 0.6, (40, 48, 3))
    before = colour * alpha[..., None]
    rim = ((alpha > 0.02) & (alpha < 0.5))[..., None]
    bright = np.where(rim, 1.0, colour) * alpha[..., None]
    even = np.clip(colour + 0.1, 0, 1) * alpha[..., None]
    assert fringe_halo([before], [bright], [alpha]).halo > 0.3
    assert fringe_halo([before], [bright], [alpha]).bright_after > 0.9
    assert fringe_halo([before], [bright], [alpha]).bright_body == 0.0  # the body kept its mid colours
    assert fringe_halo([before], [even], [alpha]).halo == pytest.approx(0.0, abs=1e-9)
    assert fringe_halo([before], [before], [alpha]).bright_after == 0.0
    with pytest.raises(ValueError, match="one alpha each"):
        fringe_halo([before], [before, before], [alpha])


def test_a_runs_display_figures_carry_the_fringe_halo():
    """``quality.display`` (and the studio's summary) hold the halo of the same renders as the speckle figure."""
    from gstyle_core.engine.run_figures import result_summary
    from gstyle_core.style.fringe import fringe_halo_line

    scene = blob_scene(150, seed=3)
    scene.opacity_logits[1::2] = logit(np.full(75, 0.03)).astype(np.float32)  # a faint half: a fringe to measure
    settings = resolve_settings("preview", "360", 3, clip_available=False, max_views=3, epochs=2, min_steps=0,
                                preprocess_rounds=0, split_rate=0.0, working_width=32, match_detail_px=0.0)
    engine = Stylizer(scene, ring_cameras(3), np.full((8, 8, 3), 0.6, np.float32), settings,
                      objective_factory=MeanColourPull)
    while not engine.done:
        engine.step()
    fringe = result_summary(engine, width=64)["display"]["fringe"]
    assert fringe["fringe_alpha"] == [0.02, 0.5] and 0 < fringe["fringe_share"] < 1
    assert fringe["halo"] == pytest.approx(fringe["lift_fringe"] - fringe["lift_body"], abs=2e-4)
    assert fringe_halo_line(fringe).startswith("fringe halo (input alpha 0.02–0.5")


def test_the_bench_measures_results_and_crops_the_fringe(tmp_path, capsys):
    """bench/studies/fringe_halo.py: a result whose faint Gaussians turned white scores a halo; the picture is
    written."""
    import sys
    from pathlib import Path

    from gstyle_core.io import save_scene
    from gstyle_core.scene import rgb_to_sh_dc

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench" / "studies"))
    import fringe_halo as bench

    scene = blob_scene(150, seed=2)
    scene.opacity_logits[1::2] = logit(np.full(75, 0.05)).astype(np.float32)
    bright = blob_scene(150, seed=2)
    bright.opacity_logits[:] = scene.opacity_logits
    bright.sh_dc[1::2] = rgb_to_sh_dc(np.ones((75, 3)))  # the faint half white
    for name, s in (("in", scene), ("same", scene), ("bright", bright)):
        save_scene(s, tmp_path / f"{name}.ply")
    picture = tmp_path / "fringe.jpg"
    assert bench.main([str(tmp_path / n) for n in ("in.ply", "same.ply", "bright.ply")] +
                      ["--labels", "same,bright", "--width", "96", "--views", "2", "--crop", "48",
                       "--picture", str(picture)]) == 0
    result = capsys.readouterr().out.splitlines()[-1].split()
    figures = dict(item.split("=") for item in result[1:])
    assert float(figures["same_halo"]) == pytest.approx(0.0, abs=1e-9)
    assert float(figures["bright_halo"]) > 0.02  # 0.036: the faint white half also shows in the body a little
    assert picture.exists() and picture.stat().st_size > 0
