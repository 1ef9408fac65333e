"""``--precision auto|fp32|bf16``: the choice with a fake timer and fake CPUs (nothing is timed here, so the tests hold
on any x86-64 CPU), the remembered choice and its cache file, the bf16 NNFM search, and what a run records."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from gstyle_core.machine import CpuInfo
from gstyle_core.style import precision
from gstyle_core.style.features import normalise_vectors
from gstyle_core.style.nnfm import StyleTarget, nnfm_loss
from gstyle_core.style.precision import (
    CACHE_FILE,
    CACHE_FORMAT,
    PRECISION_ENV,
    choose_precision,
    machine_key,
    measure,
    read_choices,
    resolve_precision,
    working_size,
)
from gstyle_core.style.vgg import VGGFeatures

AMX = CpuInfo("Intel(R) Xeon(R) Platinum 8480+", 8, ("avx2", "avx512f", "avx512_bf16", "amx_bf16", "amx_tile"))
HASWELL = CpuInfo("Intel(R) Core(TM) i7-4770 CPU @ 3.40GHz", 4, ("avx2",))
UNKNOWN = CpuInfo("mystery", 2, None)  # no /proc/cpuinfo flags: only a timing can tell
SIZE = working_size(192)
NO_ENV: dict[str, str] = {}


class FakeTimer:
    """Seconds per precision, as given; records every call."""

    def __init__(self, fp32: float, bf16: float) -> None:
        self.seconds = {"fp32": fp32, "bf16": bf16}
        self.calls: list[tuple[str, tuple[int, int]]] = []

    def __call__(self, which: str, size: tuple[int, int]) -> float:
        self.calls.append((which, size))
        return self.seconds[which]


def refuse(which: str, size: tuple[int, int]) -> float:
    raise AssertionError(f"timed {which} at {size}, which this case must not do")


def choose(tmp_path, timer=refuse, cpu=AMX, env=NO_ENV, requested="auto"):
    return choose_precision(requested, SIZE, cache_dir=tmp_path, timer=timer, cpu=cpu, env=env)


def test_an_explicit_precision_is_taken_as_asked_without_timing(tmp_path):
    assert choose(tmp_path, requested="fp32") == ("fp32", "fp32: asked for (--precision fp32)")
    which, why = choose(tmp_path, cpu=HASWELL, requested="bf16")  # even where it is slow: asked for
    assert which == "bf16" and why.startswith("bf16: asked for") and "NNFM search" in why
    assert not (tmp_path / CACHE_FILE).exists()
    with pytest.raises(ValueError, match="precision must be one of auto, fp32, bf16, got 'fp16'"):
        choose(tmp_path, requested="fp16")


def test_auto_picks_bf16_where_it_is_faster_and_remembers_it(tmp_path):
    timer = FakeTimer(fp32=0.20, bf16=0.09)
    which, why = choose(tmp_path, timer)
    assert which == "bf16" and "measured now" in why and "fp32/bf16 = 2.22" in why and "remembered in" in why
    assert len(timer.calls) == 2 + 2 and {s for _, s in timer.calls} == {SIZE}  # warm-ups, one decisive round
    saved = json.loads((tmp_path / CACHE_FILE).read_text())
    entry = saved["choices"][machine_key(AMX)]
    assert saved["format"] == CACHE_FORMAT and entry["precision"] == "bf16" and entry["size"] == list(SIZE)
    assert (entry["fp32_s"], entry["bf16_s"]) == (0.2, 0.09) and "avx512_bf16" in entry["cpu"]
    again, why_again = choose(tmp_path)  # the second time on this machine: nothing is timed
    assert again == "bf16" and "remembered for" in why_again and machine_key(AMX) in why_again


@pytest.mark.parametrize("bf16", [0.25, 0.19])  # slower, and faster by less than the margin
def test_auto_keeps_fp32_unless_bf16_is_clearly_faster(tmp_path, bf16):
    which, why = choose(tmp_path, FakeTimer(fp32=0.20, bf16=bf16))
    assert which == "fp32" and "measured now" in why
    assert read_choices(tmp_path / CACHE_FILE)[machine_key(AMX)]["precision"] == "fp32"


def test_a_cpu_without_native_bf16_gets_fp32_without_a_timing(tmp_path, monkeypatch):
    monkeypatch.setattr(precision.platform, "machine", lambda: "x86_64")
    which, why = choose(tmp_path, cpu=HASWELL)  # `refuse` fails the test if anything is timed
    assert which == "fp32" and "no native bf16" in why and "not timed" in why
    assert not (tmp_path / CACHE_FILE).exists()
    assert precision.native_bf16(HASWELL, "aarch64") is None  # not x86: a timing decides
    timer = FakeTimer(fp32=0.2, bf16=0.1)
    assert choose(tmp_path, timer, cpu=UNKNOWN)[0] == "bf16" and timer.calls


def test_the_environment_decides_auto_only(tmp_path):
    env = {PRECISION_ENV: " BF16 "}
    assert choose(tmp_path, env=env) == ("bf16", f"bf16 (auto): set by ${PRECISION_ENV}")
    assert choose(tmp_path, env=env, requested="fp32")[0] == "fp32"
    which, why = choose(tmp_path, FakeTimer(0.2, 0.1), env={PRECISION_ENV: "fast"})
    assert which == "bf16" and "'fast' ignored" in why


def test_the_test_suite_runs_fp32_without_timing():
    from gstyle_core.engine.settings import resolve_settings

    settings = resolve_settings("preview", "forward", 3)
    assert settings.precision == "auto"
    assert resolve_precision(settings, timer=refuse)[0] == "fp32"  # conftest's GSTYLE_PRECISION


@pytest.mark.parametrize("content", [
    "{not json", json.dumps([1, 2]), json.dumps({"format": "other/9", "choices": {}}),
    json.dumps({"format": CACHE_FORMAT, "choices": {machine_key(AMX): {"precision": "fp16"}}}),
])
def test_a_corrupt_cache_file_is_ignored_and_rewritten(tmp_path, content):
    path = tmp_path / CACHE_FILE
    path.write_text(content)
    assert choose(tmp_path, FakeTimer(0.2, 0.1))[0] == "bf16"
    assert read_choices(path)[machine_key(AMX)]["precision"] == "bf16"
    assert not [p for p in tmp_path.iterdir() if p.name != CACHE_FILE]  # no temporary file left behind


def test_other_machines_entries_are_kept_and_an_unwritable_cache_costs_only_a_timing(tmp_path):
    choose(tmp_path, FakeTimer(0.2, 0.1), cpu=AMX)
    choose(tmp_path, FakeTimer(0.1, 0.2), cpu=UNKNOWN)
    choices = read_choices(tmp_path / CACHE_FILE)
    assert {k: v["precision"] for k, v in choices.items()} == {machine_key(AMX): "bf16", machine_key(UNKNOWN): "fp32"}
    blocked = tmp_path / "a-file"
    blocked.write_text("")
    which, why = choose(blocked, FakeTimer(0.2, 0.1))  # the cache folder is a file: nothing can be written
    assert which == "bf16" and "not remembered" in why


def _scripted(times: list[float], calls: list[str]):
    seconds = iter(times)

    def timer(which, size):
        calls.append(which)
        return next(seconds)

    return timer


def test_measure_warms_up_then_interleaves_and_keeps_the_best():
    calls: list[str] = []
    assert measure(_scripted([9.0, 9.0, 0.3, 0.25, 0.22, 0.1], calls), SIZE, rounds=2) == {"fp32": 0.22, "bf16": 0.1}
    assert calls == ["fp32", "bf16", "fp32", "bf16", "fp32", "bf16"]
    calls.clear()  # a lopsided first round decides alone: on a CPU where bf16 is emulated that saves a slow run
    assert measure(_scripted([9.0, 9.0, 0.1, 0.8], calls), SIZE, rounds=2) == {"fp32": 0.1, "bf16": 0.8}
    assert calls == ["fp32", "bf16", "fp32", "bf16"]


def test_the_probe_leaves_the_runs_random_state_alone():
    torch.manual_seed(3)
    expected = torch.rand(4)
    torch.manual_seed(3)
    seconds = precision.ProbeTimer()("fp32", (16, 16))
    assert seconds > 0 and torch.equal(torch.rand(4), expected)


def test_a_bf16_search_finds_a_neighbour_as_near_as_fp32s():
    gen = torch.Generator().manual_seed(0)
    common = torch.randn(768, 1, generator=gen)  # painting and render vectors all alike (cosines ~0.9): close calls
    style = normalise_vectors(common + 0.3 * torch.randn(768, 300, generator=gen), dim=0)
    render = (common + 0.3 * torch.randn(768, 42, generator=gen)).t().reshape(1, 6, 7, 768).permute(0, 3, 1, 2)
    exact = StyleTarget(style)
    assert exact.search_matrix is exact.matrix  # fp32: no copy, the search as it always was
    fp32 = nnfm_loss(render, exact, reduction="none")
    bf16 = nnfm_loss(render, StyleTarget(style, search_dtype=torch.bfloat16), reduction="none")
    assert bf16.dtype == torch.float32 and (bf16 >= fp32 - 1e-6).all()  # never nearer than the true nearest
    assert float((bf16 - fp32).max()) < 0.01 and float(bf16.mean() - fp32.mean()) < 0.002
    brute = 1 - (normalise_vectors(render.permute(0, 2, 3, 1).flatten(0, 2), 1) @ style).max(dim=1).values
    assert torch.allclose(fp32.flatten(), brute, atol=1e-6)  # fp32: the exact nearest neighbour


def test_the_bf16_search_takes_the_first_of_equal_scores_as_fp32s_does():
    from gstyle_core.style.nnfm import nearest_indices

    scores = torch.tensor([[0.5, 0.75, 0.75, 0.1], [0.2, 0.2, 0.2, 0.2], [0.9, 0.3, 0.9, 0.0]])
    assert nearest_indices(scores).tolist() == [1, 0, 0] == nearest_indices(scores.bfloat16()).tolist()
    many = torch.randn(300, 500, generator=torch.Generator().manual_seed(2)).bfloat16()  # rounding makes ties
    assert torch.equal(nearest_indices(many), many.float().argmax(dim=1))


def test_a_style_target_searches_in_its_networks_precision():
    torch.manual_seed(0)
    painting = torch.rand(1, 3, 24, 24)
    vgg = VGGFeatures()
    assert StyleTarget.from_image(vgg, painting).search_matrix.dtype == torch.float32
    vgg.set_compute_mode(torch.bfloat16, channels_last=True)
    target = StyleTarget.from_image(vgg, painting)
    assert target.matrix.dtype == torch.float32 and target.search_matrix.dtype == torch.bfloat16


def _run(monkeypatch, steps: int = 3, **overrides):
    """A tiny real engine whose objective loads its VGG (random weights) as the product does."""
    from fakes import engine_with_random_vgg

    engine = engine_with_random_vgg(monkeypatch, **overrides)
    while engine.phase != "stylize":
        engine.step()
    losses = [engine.step().losses for _ in range(steps)]
    return engine, losses


def test_a_bf16_run_uses_bf16_networks_and_records_why(monkeypatch):
    engine, losses = _run(monkeypatch, precision="bf16")
    objective = engine.objective
    assert objective.precision == "bf16" and objective.vgg.compute_dtype == torch.bfloat16
    assert objective.vgg.channels_last and objective.target.search_matrix.dtype == torch.bfloat16
    assert engine.decisions["precision"].startswith("bf16: asked for")
    assert engine.c_s.dtype == torch.float32 and all(np.isfinite(v) for step in losses for v in step.values())
    fp32_engine, fp32_losses = _run(monkeypatch, precision="fp32")
    assert fp32_engine.objective.vgg.compute_dtype == torch.float32
    assert fp32_engine.decisions["precision"] == "fp32: asked for (--precision fp32)"
    assert losses[0]["nnfm"] == pytest.approx(fp32_losses[0]["nnfm"], rel=0.05)


def test_bf16_covers_the_broad_strokes_term_and_leaves_the_colour_field_fp32(monkeypatch):
    """The broad-strokes term runs on the objective's network: its levels' NNFM searches are bf16 like block 3's; the
    coherent-strokes field, like the colours, stays fp32; the term's loss agrees with fp32's."""
    runs = {p: _run(monkeypatch, precision=p, lambda_multiscale=50.0, colour_field=True) for p in ("bf16", "fp32")}
    engine, losses = runs["bf16"]
    term = engine.build_objective().loss.multiscale_term
    assert term is not None and term.vgg is engine.objective.vgg
    assert all(t.search_matrix.dtype == torch.bfloat16 and t.matrix.dtype == torch.float32 for t in term.targets)
    field = engine.stylize.field
    assert field is not None and field.values.dtype == torch.float32 and engine.c_s.dtype == torch.float32
    fp32_engine, fp32_losses = runs["fp32"]
    fp32_term = fp32_engine.build_objective().loss.multiscale_term
    assert all(t.search_matrix.dtype == torch.float32 for t in fp32_term.targets)
    assert losses[0]["multiscale"] == pytest.approx(fp32_losses[0]["multiscale"], rel=0.05)
    assert all(np.isfinite(v) for step in losses for v in step.values())


def test_auto_resolved_to_fp32_is_the_fp32_run_bit_for_bit(monkeypatch):
    _, auto = _run(monkeypatch)
    fp32_engine, fp32 = _run(monkeypatch, precision="fp32")
    assert auto == fp32
    with pytest.raises(ValueError, match="precision must be one of auto, fp32, bf16"):
        _run(monkeypatch, precision="half")


def test_the_cli_and_the_studio_take_the_option():
    import argparse

    from app.engine_factory import ENGINE_OPTIONS
    from app.main import build_parser
    from gstyle_core.cli.stylize import add_stylize_arguments, build_request

    parser = argparse.ArgumentParser()
    add_stylize_arguments(parser)
    assert build_request(parser.parse_args(["--precision", "bf16"])).overrides["precision"] == "bf16"
    assert build_request(parser.parse_args([])).overrides["precision"] is None  # the settings' default: auto
    with pytest.raises(SystemExit):
        parser.parse_args(["--precision", "fp16"])
    assert "precision" in ENGINE_OPTIONS and build_parser().parse_args(["--precision", "fp32"]).precision == "fp32"


def test_gstyle_cache_names_the_file(tmp_path, monkeypatch):
    from gstyle_core.cli.cache import list_cache

    monkeypatch.setenv("GSTYLE_CACHE", str(tmp_path))
    choose(tmp_path, FakeTimer(0.2, 0.1))
    assert any(CACHE_FILE in line and "--precision auto" in line for line in list_cache())
