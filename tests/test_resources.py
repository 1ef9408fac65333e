"""Bounded resources: the Gaussian cap (default: from free memory) cuts splits back, lowest priority first."""

from __future__ import annotations

import torch
from fakes import short_pull_run

from gstyle_core.engine.resources import (
    FALLBACK_MAX_GAUSSIANS,
    GPU_BYTES_AT_512,
    available_memory_bytes,
    bytes_per_gaussian,
    card_free_bytes,
    default_max_gaussians,
    gpu_bytes_per_gaussian,
)
from tests.synthetic import blob_scene, ring_cameras


def _engine(n=200, **overrides):
    return short_pull_run(blob_scene(n, seed=3), ring_cameras(4), 0, **overrides)


def test_default_cap_follows_the_available_memory():
    gib = 2**30
    cap, how = default_max_gaussians(192, available=8 * gib)
    assert cap == int(8 * gib * 0.5 // bytes_per_gaussian(192)) and "8.0 GiB available" in how
    assert default_max_gaussians(512, available=8 * gib)[0] < cap  # wider renders cost more per Gaussian
    assert default_max_gaussians(192, available=0)[0] == FALLBACK_MAX_GAUSSIANS
    assert available_memory_bytes() > 0
    eng = _engine()
    assert eng.settings.max_gaussians == 0 and eng.max_gaussians > 1000
    assert "GiB available" in eng.decisions["max_gaussians"]


def test_on_a_gpu_the_cards_free_memory_caps_the_count_too():
    gib = 2**30
    assert gpu_bytes_per_gaussian(512) == GPU_BYTES_AT_512  # the width measured
    assert gpu_bytes_per_gaussian(256) < GPU_BYTES_AT_512 < gpu_bytes_per_gaussian(1024)
    host_cap, host_how = default_max_gaussians(512, available=64 * gib)
    cap, how = default_max_gaussians(512, available=64 * gib, card_free=2 * gib)  # a small card, a large host
    assert cap == int(2 * gib * 0.5 // GPU_BYTES_AT_512) < host_cap and "2.0 GiB free on the GPU" in how
    assert default_max_gaussians(512, available=64 * gib, card_free=80 * gib) == (host_cap, host_how)  # host binds
    assert default_max_gaussians(512, available=0, card_free=2 * gib)[0] == cap  # host unknown: the card's still
    assert default_max_gaussians(512, available=64 * gib, card_free=None) == (host_cap, host_how)
    if not torch.cuda.is_available():
        assert card_free_bytes(torch.device("cuda")) is None  # no card: no figure, no crash


def test_tiny_cap_reduces_splits_and_reports_it():
    eng = _engine(max_gaussians=230)
    assert eng.decisions["max_gaussians"].startswith("at most 230 Gaussians")
    messages = []
    while not eng.done:
        rep = eng.step()
        messages.append(rep.message)
        assert eng.gaussian_count <= 230
    reduced = eng.decisions.get("reductions", [])
    assert reduced and all("by the cap of 230" in r for r in reduced)
    assert sum("split reduced from" in m for m in messages) == len(reduced)  # in the step reports too
    assert eng.gaussian_count > 200  # the cap cut the splits back, it did not cancel them


def test_the_highest_priority_candidates_survive_the_cap():
    eng = _engine(n=100, max_gaussians=109)  # room for 9 more: three 4-way splits
    before = eng.params["means"].detach().clone()
    mask = torch.zeros(100, dtype=torch.bool)
    mask[10:30] = True  # 20 candidates
    priority = torch.zeros(100)
    priority[10:30] = torch.arange(20, dtype=torch.float32)  # 27, 28, 29 rank highest
    assert eng.run_state.split(mask, 4, 8.0, priority=priority) == 3
    assert eng.gaussian_count == 109
    after = eng.params["means"].detach()
    survivors = {i for i in range(100) if (after == before[i]).all(dim=1).any()}
    assert set(range(100)) - survivors == {27, 28, 29}
    assert "split reduced from 20 to 3" in eng.decisions["reductions"][-1]
    assert eng.run_state.split(mask & (torch.arange(100) < 27), 4, 8.0, priority=priority) == 0  # full: nothing splits
