"""``bench/stylize.py``'s part timer against the engine's loss code: every part the loss runs is timed (the network
passes go through ``VGGFeatures.stacked`` and the coarse substitute through ``per_image``; a timer wrapping only
``forward`` would report them as 0 and leave their time in the rest)."""

from __future__ import annotations

import numpy as np
import pytest
from bench_cli import load_bench
from fakes import engine_at_stylize
from synthetic import blob_scene


@pytest.mark.parametrize("clip", [0.0, 10.0], ids=["no CLIP term", "coarse substitute"])
def test_the_part_timer_times_the_network_passes_the_loss_makes(vgg, clip):
    bench = load_bench("stylize")
    style = np.random.default_rng(1).uniform(size=(16, 16, 3)).astype(np.float32)
    engine = engine_at_stylize(vgg, blob_scene(150, seed=3), style, lambda_clip=clip)
    for _ in range(3):  # one view a step: every view's content features made (by ``forward``) before the timed step
        engine.step()
    timer = bench.instrument(engine)
    try:
        with timer.on():
            rep = engine.step()
    finally:
        timer.restore()
    assert rep.phase == "stylize" and rep.losses
    parts = ["VGG forward", "NNFM forward", "content term forward", "backward (all terms)"]
    for part in parts + (["CLIP / coarse substitute forward"] if clip else []):
        assert timer.seconds.get(part, 0.0) > 0.0, part
    assert timer.seconds.get("content features (once per view)", 0.0) == 0.0
    network = vars(engine.objective.loss.vgg)
    assert "stacked" not in network and "forward" not in network  # restored: the class's methods again
