"""Every pair of an artist's paths, run together on real captures (issue #48).

    .venv/bin/python bench/paths.py [--whole] [--cases 3,7] [--csv docs/paths.csv]

The paths are the live controls of ``gstyle_core/engine/controls.py``'s table (each row's values drawn from its
kind: a λ off and on, a checkbox off and on, a log slider at half, one and twice its default, a linear one at its
ends and middle; ``control_values``) and the run options (``RUN_FACTORS``: tier and its level mode, scene kind,
precision, one or two paintings, a region with a hard or a soft edge, an interruption in each phase and the resume
after it, a refine or a continue of the finished run, the whole capture held or a cap below its count).
``covering_cases`` draws a covering array of strength 2 over them (allpairspy): every pair of values of two factors is
in at least one case. A control added to the table joins the matrix by itself.

Each case builds its engine through ``engine/build.py`` (what ``gstyle stylize`` and the studio's worker build
with) on a real capture: ``--scene 360`` a crop of 24,000 Gaussians of ``winter_fountain.cropped.splat`` with the
generated orbit, ``forward`` the fern's LLFF cameras and photos with its COLMAP points as Gaussians (the
initialisation ``gstyle fit`` starts from; no trained fern is in ``../shared``). ``run_case`` drives it step by step
and ``check_case`` asserts what the case's controls must do (``tests/test_paths.py`` runs every case in CI at
``SHORT`` settings: a few steps of each phase). ``--whole`` runs the same cases as shipped (the tier's own
budgets, 64 px narrower only where ``--working-width`` says) and prints a table of every case with its time and
figures; ``RESULT cases=N pairs=M failed=K`` last.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from gstyle_core.engine.controls import CONTROLS, Control  # noqa: E402
from gstyle_core.engine.settings import preset_values  # noqa: E402

DATA = ROOT.parent / "shared" / "data"
WINTER = DATA / "scenes" / "splat" / "winter_fountain.cropped.splat"
FERN = DATA / "scenes" / "llff_fern"
PAINTINGS = (ROOT / "assets" / "styles" / "starry_night.jpg", DATA / "styles" / "great_wave_hokusai.jpg")
CROP = 24_000  # Gaussians of the 360° crop

RUN_FACTORS: dict[str, tuple[Any, ...]] = {
    "interrupt": ("none", "preprocess", "colour_match", "stylize", "refine"),  # resume after a stop in that phase
    "tier": ("preview", "balanced", "final"),
    "region": ("none", "box", "soft"),
    "then": ("none", "refine", "continue"),  # after the run: a finer level, or the kept run continued elsewhere
    "level_mode": ("crops", "whole"),
    "scene": ("360", "forward"),
    "precision": ("fp32", "bf16"),
    "paintings": (1, 2),
    "capacity": ("whole", "reduced"),  # reduced: a cap below the capture's count (the rest from neighbours)
    "lod": ("off", "on"),  # the level of detail's cut (on: the run holds merged parents; a reduced cap is of those)
}
REDUCED_SHARE = 0.6  # the cap of a "reduced" case: this share of the capture's Gaussians
# A few steps of each phase: the tiers keep their phases and levels (their widths scaled to a 64-px working width)
SHORT = dict(working_width=64, max_views=4, epochs=3.0, min_steps=0, refit_iterations=3, preprocess_rounds=1,
             force_preprocess=True, refine_epochs=1.0, nnfm_candidates=2048)
SHORT_LEVELS = {"preview": (), "balanced": (96,), "final": (96, 128)}


def control_values(row: Control) -> tuple[Any, ...]:
    """The values a control takes in the matrix: "off"/"on" for a λ (on: the preset's value, or the table's default,
    or the middle of its range), 0/1 for a checkbox, half/one/twice the default for a log slider, the ends and the
    middle for a linear one."""
    if row.name.startswith("lambda_"):
        return ("off", "on")
    if row.widget == "checkbox":
        return (0.0, 1.0)
    if row.log:
        return tuple(dict.fromkeys(min(max(row.default * k, row.low), row.high) for k in (0.5, 1.0, 2.0)))
    return (row.low, (row.low + row.high) / 2, row.high)


def matrix_factors() -> dict[str, tuple[Any, ...]]:
    """Every factor of the matrix and its values: the run options, then the table's controls (the mix of two
    paintings is the ``paintings`` factor's)."""
    controls = {row.name: control_values(row) for row in CONTROLS if not row.with_paintings}
    return {**RUN_FACTORS, **controls}


def allowed(names: list[str], values: list[Any]) -> bool:
    """Whether a (partial) case makes sense: a level mode other than the default and a stop in a finer level need
    a tier with finer levels."""
    case = dict(zip(names, values, strict=False))
    if case.get("tier") == "preview" and (case.get("level_mode", "crops") != "crops"
                                          or case.get("interrupt") == "refine"):
        return False
    return True


def covering_cases(factors: dict[str, tuple[Any, ...]] | None = None) -> list[dict[str, Any]]:
    """A covering array of strength 2 over ``factors`` (default ``matrix_factors()``), as dicts, in a fixed order."""
    from allpairspy import AllPairs

    factors = matrix_factors() if factors is None else factors
    names = list(factors)
    rows = AllPairs([list(factors[n]) for n in names], filter_func=lambda values: allowed(names, values))
    cases = [dict(zip(names, row, strict=True)) for row in rows]
    for a, va, b, vb in missing_pairs(cases, factors):  # allpairspy can leave a pair out under a filter
        base = next(c for c in cases if allowed(names, [{**c, a: va, b: vb}[n] for n in names]))
        cases.append({**base, a: va, b: vb})
    return cases


def missing_pairs(cases: list[dict[str, Any]], factors: dict[str, tuple[Any, ...]] | None = None
                  ) -> list[tuple[str, Any, str, Any]]:
    """The pairs of values (factor, value, factor, value) that ``allowed`` admits and no case has."""
    factors = matrix_factors() if factors is None else factors
    names = list(factors)
    missing = []
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            seen = {(c[a], c[b]) for c in cases}
            missing += [(a, va, b, vb) for va in factors[a] for vb in factors[b]
                        if allowed([a, b], [va, vb]) and (va, vb) not in seen]
    return missing


def pair_count(factors: dict[str, tuple[Any, ...]] | None = None) -> int:
    """How many pairs of values ``allowed`` admits."""
    factors = matrix_factors() if factors is None else factors
    names = list(factors)
    return sum(allowed([a, b], [va, vb]) for i, a in enumerate(names) for b in names[i + 1:]
               for va in factors[a] for vb in factors[b])


# ------------------------------------------------------------------------------------------------ captures
def capture_360(folder: Path) -> Path:
    """The 360° capture: the ``CROP`` Gaussians of winter_fountain nearest its median centre, as a 3DGS .ply."""
    from gstyle_core.io import load_scene, save_scene

    path = folder / "winter_crop.ply"
    if not path.exists():
        scene, _ = load_scene(WINTER)
        centre = np.median(scene.means, axis=0)
        keep = np.sort(np.argsort(np.linalg.norm(scene.means - centre, axis=1))[:CROP])
        save_scene(scene.subset(keep), path)
    return path


def capture_forward(folder: Path) -> Path:
    """The forward-facing capture: the fern's COLMAP points as Gaussians (SH degree 0), as a 3DGS .ply."""
    from gstyle_core.cameras import load_cameras
    from gstyle_core.fit.init import scene_from_points
    from gstyle_core.io import save_scene

    path = folder / "fern_points.ply"
    if not path.exists():
        cams = load_cameras(str(FERN))
        save_scene(scene_from_points(cams.points, cams.point_colors, sh_degree=0, initial_opacity=0.5), path)
    return path


def captures_missing() -> str | None:
    """Why the captures cannot be made (None: they can)."""
    missing = [str(p) for p in (WINTER, FERN / "poses_bounds.npy", PAINTINGS[1]) if not p.exists()]
    return f"shared data absent: {', '.join(missing)}" if missing else None


# ------------------------------------------------------------------------------------------------ one case
@dataclass
class CaseRun:
    """What a case's run left: the engine at its end, the input scene, every step's report, the engine's objectives
    (each level's, as built), the global step the run stopped and resumed at, and the seconds it took."""

    case: dict[str, Any]
    engine: Any
    scene: Any
    reports: list[Any] = field(default_factory=list)
    objectives: list[Any] = field(default_factory=list)
    resumed_at: int | None = None
    levels: int = 0  # the widths the run worked at before its ``then``
    seconds: float = 0.0


def scene_box(scene, soft: bool) -> tuple[tuple[float, ...], float]:
    """A region around the middle of a scene: its centres' 20-80 % quantiles on every axis; the soft edge 5 % of
    the box's diagonal."""
    lo, hi = np.quantile(scene.means, 0.2, axis=0), np.quantile(scene.means, 0.8, axis=0)
    return tuple(float(v) for v in (*lo, *hi)), (0.05 * float(np.linalg.norm(hi - lo)) if soft else 0.0)


def case_request(case: dict[str, Any], folder: Path, whole: bool = False):
    """The ``BuildRequest`` of a case (``SHORT`` settings unless ``whole``) and its input scene."""
    from gstyle_core.engine.build import BuildRequest
    from gstyle_core.io import load_scene

    forward = case["scene"] == "forward"
    scene_path = capture_forward(folder) if forward else capture_360(folder)
    scene, _ = load_scene(scene_path)
    overrides: dict[str, Any] = dict(SHORT) if not whole else {}
    if not whole:
        overrides["refine_widths"] = SHORT_LEVELS[case["tier"]]
    preset = preset_values(case["tier"], case["scene"], clip_available=False)
    for row in CONTROLS:
        value = case.get(row.name)
        if value is None or row.with_paintings:
            continue
        if row.name.startswith("lambda_"):
            value = 0.0 if value == "off" else (preset[row.name] or row.default
                                                or math.sqrt(row.low * row.high))
        overrides[row.name] = value
    overrides.update(precision=case["precision"], refine_mode=case["level_mode"], device="cpu",
                     lod=case.get("lod", "off"))
    if case["region"] != "none":
        overrides["region"], overrides["region_feather"] = scene_box(scene, case["region"] == "soft")
    styles = [str(p) for p in PAINTINGS[:case["paintings"]]]
    if case["paintings"] > 1:
        overrides["style_weights"] = (0.6, 0.4)
    request = BuildRequest(scene=str(scene_path), style=styles, cameras=str(FERN) if forward else None,
                           preset=case["tier"], scene_kind=case["scene"], overrides=overrides)
    if case.get("capacity") == "reduced":  # a cap below what the run would hold: the capture, or the cut's parents
        from gstyle_core.engine.build import build_stylizer

        overrides["max_gaussians"] = int(REDUCED_SHARE * build_stylizer(request).engine.cut_input.count)
    return request, scene


def _objectives(engine) -> list[Any]:
    run = engine.run_state
    return [o for o in run.objectives() if o is not None and hasattr(o, "loss")]


def _step_to_end(engine, run: CaseRun, stop_in: str | None = None) -> bool:
    """Step ``engine`` to its end, keeping reports and objectives; with ``stop_in`` return True right after the first
    step of that phase (a refine phase: ``refine``) instead."""
    while not engine.done:
        report = engine.step()
        run.reports.append(report)
        run.objectives += [o for o in _objectives(engine) if all(o is not k for k in run.objectives)]
        if stop_in is not None and report.phase.split(" ")[0].startswith(stop_in) and not engine.done:
            return True
    return False


def run_case(case: dict[str, Any], folder: Path, whole: bool = False) -> CaseRun:
    """Build the case's engine and drive it as the CLI and the worker do: a stop (checkpoint written and read back,
    a new engine resumed from it) where the case says, then its ``then``."""
    from gstyle_core.engine.build import build_stylizer
    from gstyle_core.engine.checkpoint import read_checkpoint, save_checkpoint

    t0 = time.perf_counter()
    request, scene = case_request(case, folder, whole)
    engine = build_stylizer(request).engine
    run = CaseRun(case, engine, scene)
    stop = None if case["interrupt"] == "none" else case["interrupt"]
    if _step_to_end(engine, run, stop):  # stopped: the run goes on in a new engine from its checkpoint
        path = save_checkpoint(folder / "case.ckpt", engine.state_dict(), {"kind": "paths"})
        state, _ = read_checkpoint(path)
        engine = run.engine = build_stylizer(request).engine
        engine.load_state_dict(state)
        run.resumed_at = engine.global_step
        _step_to_end(engine, run)
    run.levels = len(engine.levels)
    if case["then"] == "refine":
        engine.refine()
        _step_to_end(engine, run)
    elif case["then"] == "continue":  # the studio's "Continue this run": the kept run in a new engine
        kept = engine.state_dict()
        engine = run.engine = build_stylizer(request).engine
        engine.load_state_dict(kept)
        engine.set_params(keep_colours=1.0)  # ticked after the run: the scene's hues at once
        run.case = {**case, "keep_colours": 1.0}
    run.seconds = time.perf_counter() - t0
    return run


# ------------------------------------------------------------------------------------------------ what must hold
STYLE_TERMS = ("clip", "nnfm", "multiscale")  # the terms the style strength multiplies
FLOORED = ("chroma_tv",)  # terms counted only above a floor: 0 is a value they may take while on


def _term_weights(run: CaseRun) -> dict[str, float]:
    """Each λ term's weight as the loss used it (the settings at the end; strength on the style terms)."""
    s = run.engine.settings
    weights = {name: float(getattr(s.weights, name)) for name in
               (row.name.removeprefix("lambda_") for row in CONTROLS if row.name.startswith("lambda_"))}
    return {k: v * (s.strength if k in STYLE_TERMS else 1.0) for k, v in weights.items()}


def check_terms(run: CaseRun) -> None:
    """A term that is on shows in the losses of the optimising steps; a term that is off is 0 in every one of them
    and its network was never built (no VGG pass at all when no term needs VGG)."""
    optimising = [r for r in run.reports if r.phase.startswith(("stylize", "refine")) and r.losses]
    assert optimising, "no optimising step reported its losses"
    for term, weight in _term_weights(run).items():
        values = [r.losses.get(term, 0.0) for r in optimising]
        assert all(math.isfinite(v) for v in values), (term, values)
        if weight == 0:
            assert all(v == 0 for v in values), f"{term} is off but was computed: {values}"
        elif term not in FLOORED:
            assert any(v != 0 for v in values), f"{term} is on (λ {weight:g}) but never in the losses"
    weights = _term_weights(run)
    for objective in run.objectives:
        if weights["clip"] == 0:
            assert objective.loss.clip_term is None, "the CLIP term was built while off"
        if weights["multiscale"] == 0:
            assert objective.loss.multiscale_term is None, "the broad-strokes term was built while off"
        if not any(weights[t] for t in ("nnfm", "content", "multiscale", "clip")):
            assert objective.calls["vgg"] == 0, "VGG ran with every term that needs it off"


def check_painting(run: CaseRun) -> None:
    """The painting is matched at the stroke size (its long side ``style_side`` of each level's width) and two
    paintings are both in the objective, with their weights."""
    from gstyle_core.engine.objective import style_side
    from gstyle_core.style.nnfm import WeightedTargets

    s = run.engine.settings
    for objective in run.objectives:
        side, _ = style_side(objective.width or s.working_width, s.style_scale)
        assert all(max(small.shape[-2:]) == side for small in objective._styles_small), (side, s.style_scale)
        if run.case["paintings"] > 1:
            assert isinstance(objective.target, WeightedTargets) and len(objective.target.targets) == 2
            assert np.allclose(objective.target.weights, (0.6, 0.4))
    if run.case["paintings"] > 1:
        assert "2 paintings mixed 0.60 / 0.40" in run.engine.decisions["styles"]


def check_region(run: CaseRun) -> None:
    """The Gaussians outside a region's box (grown by its soft edge) come out of the export as the input's rows,
    every attribute bit for bit; without a region every Gaussian is selected."""
    engine = run.engine
    if run.case["region"] == "none":
        assert engine.selection is None
        return
    out, outside = engine.stylized_scene(), np.flatnonzero(~engine.full_selection)
    assert len(outside) > 100, "the box leaves too few Gaussians outside to check"
    fields = ("means", "log_scales", "quats", "opacity_logits", "sh_dc", "sh_rest")
    missing = missing_rows(out, run.scene, outside, fields)  # wherever the export put them
    assert not missing, f"{missing} Gaussians outside the region changed or are missing from the export"


def missing_rows(out, scene, rows: np.ndarray, fields: tuple[str, ...]) -> int:
    """How many of ``scene``'s ``rows`` have no row of ``out`` equal to them in every one of ``fields``, bit for bit
    (as multisets: a capture may hold the same Gaussian twice; SH bands compared where both have the same layout)."""
    from collections import Counter

    def keys(s, index):
        parts = [np.ascontiguousarray(getattr(s, f)[index], np.float32).reshape(len(index), -1) for f in fields
                 if f != "sh_rest" or s.sh_rest.shape[1] == scene.sh_rest.shape[1] == out.sh_rest.shape[1]]
        return Counter(row.tobytes() for row in np.concatenate(parts, axis=1))

    centres = {m.tobytes() for m in np.ascontiguousarray(scene.means[rows], np.float32)}
    near = [i for i, m in enumerate(np.ascontiguousarray(out.means, np.float32)) if m.tobytes() in centres]
    return sum((keys(scene, rows) - keys(out, np.array(near, np.int64))).values())


def check_colours(run: CaseRun) -> None:
    """The colours are finite and in range; with keep colours every coloured Gaussian (of the selection) has its
    ground truth's hue."""
    from gstyle_core.style.keep_colours import chroma

    snap = run.engine.snapshot()
    colours, gt = np.asarray(snap["colors"], np.float64), np.asarray(snap["colors_gt"], np.float64)
    assert np.isfinite(colours).all() and colours.min() >= 0 and colours.max() <= 1
    if not run.case["keep_colours"]:
        return
    mask = np.ones(len(colours), bool) if snap.get("selected") is None else np.asarray(snap["selected"], bool)
    a, b = chroma(colours[mask]), chroma(gt[mask])
    strong = (np.linalg.norm(a, axis=1) > 0.04) & (np.linalg.norm(b, axis=1) > 0.04) & (gt[mask] < 1).all(1) \
        & (gt[mask] > 0).all(1)
    cos = (a[strong] * b[strong]).sum(1) / np.linalg.norm(a[strong], axis=1) / np.linalg.norm(b[strong], axis=1)
    gap = np.degrees(np.arccos(np.clip(cos, -1, 1)))
    assert strong.sum() > 50 and np.percentile(gap, 99) < 1.0, (int(strong.sum()), np.percentile(gap, 99))


def check_run(run: CaseRun) -> None:
    """The run ended; a stopped one resumed where it stopped and counted on; its precision is the one asked for."""
    engine = run.engine
    assert engine.done
    if run.case["interrupt"] != "none":
        assert run.resumed_at is not None, f"the run never reached {run.case['interrupt']}"
    assert run.case["precision"] in engine.decisions["precision"]
    assert len(engine.levels) == run.levels + (run.case["then"] == "refine"), (engine.levels, run.levels)


def check_capacity(run: CaseRun) -> None:
    """A reduced run held the most visible part of the capture and its export is the whole capture: the held
    Gaussians as the run left them, then every other input Gaussian with its own geometry."""
    engine, n = run.engine, run.scene.count
    if run.case.get("capacity") != "reduced":
        assert not engine.capacity.reduced
        return
    plan, held_from = engine.capacity, engine.cut_input  # the capture, or the cut's parents of a run on a cut
    assert plan.reduced and len(plan.held) == int(REDUCED_SHARE * held_from.count)
    assert "all" in engine.decisions["capacity"]
    out = engine.stylized_scene()
    assert out.count >= n
    rest = np.setdiff1d(np.arange(held_from.count), plan.held)
    if engine.lod is None:
        assert out.count == engine.gaussian_count + n - len(plan.held)
        tail = out.subset(np.arange(engine.gaussian_count, out.count))
        for name in ("means", "log_scales", "quats", "opacity_logits"):
            assert np.array_equal(getattr(tail, name), getattr(run.scene, name)[rest]), f"{name} of the rest changed"
        return
    # on a cut: every input Gaussian of a merged parent, held or not, is in the export with its own geometry
    children = np.flatnonzero(engine.lod.merged[engine.lod.child_parent])
    missing = missing_rows(out, run.scene, children, ("means", "log_scales", "quats", "opacity_logits"))
    assert not missing, f"{missing} input Gaussians of merged parents changed shape or are missing from the export"


def check_case(run: CaseRun) -> None:
    """Everything a case's controls must do (AssertionError saying which did not)."""
    check_run(run)
    check_capacity(run)
    check_terms(run)
    check_painting(run)
    check_region(run)
    check_colours(run)


# ------------------------------------------------------------------------------------------------ the bench
def case_label(case: dict[str, Any]) -> str:
    """A case in one short line: the run options, then the controls away from their first value."""
    first = {name: values[0] for name, values in matrix_factors().items()}
    run = " ".join(str(case[k]) for k in RUN_FACTORS)
    moved = " ".join(f"{k}={case[k]}" for k in case if k not in RUN_FACTORS and case[k] != first[k])
    return f"{run} | {moved}"


def figures(run: CaseRun) -> dict[str, float]:
    """The run's quality figures at its end (``run_figures.evaluate_run``, no display-size renders)."""
    from gstyle_core.engine.run_figures import evaluate_run

    q = evaluate_run(run.engine, run.scene, run.engine.style_input(), display_width=0)
    return {"nnfm_drop": 1.0 - q["final"]["nnfm"] / q["initial"]["nnfm"], "structure": float(q["structure"])}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--whole", action="store_true", help="whole runs as shipped (default: SHORT settings)")
    p.add_argument("--cases", default=None, help="run only these case numbers, e.g. 0,5")
    p.add_argument("--work", default="out/paths", help="folder for the captures and checkpoints")
    p.add_argument("--raise", dest="raise_", action="store_true", help="stop at the first failure with its traceback")
    args = p.parse_args(argv)
    why = captures_missing()
    if why:
        print(f"paths: {why}")
        return 2
    folder = Path(args.work)
    folder.mkdir(parents=True, exist_ok=True)
    cases = covering_cases()
    print(f"{len(cases)} cases cover {pair_count() - len(missing_pairs(cases))} of {pair_count()} pairs of values "
          f"({len(matrix_factors())} factors)")
    picked = range(len(cases)) if args.cases is None else [int(c) for c in args.cases.split(",")]
    failed = 0
    print(f"{'case':>4} {'seconds':>8} {'drop':>6} {'struct':>6}  result  paths")
    for i in picked:
        try:
            run = run_case(cases[i], folder, whole=args.whole)
            check_case(run)
            f, result = figures(run), "ok"
        except Exception as exc:  # a bench reports every case, the failed ones with why
            if args.raise_:
                raise
            failed += 1
            f, result = {"nnfm_drop": math.nan, "structure": math.nan}, f"FAILED {type(exc).__name__}: {exc}"
            run = None
        seconds = run.seconds if run is not None else math.nan
        print(f"{i:>4} {seconds:>8.1f} {100 * f['nnfm_drop']:>5.1f}% {f['structure']:>6.2f}  {result[:60]:<6}  "
              f"{case_label(cases[i])}", flush=True)
    print(f"RESULT cases={len(picked)} pairs={pair_count()} failed={failed}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
