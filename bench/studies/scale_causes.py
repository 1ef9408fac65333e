"""Why the added texture does not follow the stroke size: one stylization per variant, measured
(docs/notes/texture-scale.md).

Each run builds the engine as ``gstyle stylize`` does (``build.build_stylizer`` of ``cli.build_request``), changes one
thing, runs it to the end and writes ``OUT_before.png`` / ``OUT_after.png`` and ``OUT.json`` with the CLI's quality
figures (NNFM drop, structure and the texture-scale figure, masked by the evaluation views' alpha: ``evaluate_run``)
and the time per stylization step. Variants (prototypes only; the engine is not changed):

* ``--optim global``: Adam's per-colour normalisation replaced by one shared one (momentum as Adam's β1, the second
  moment averaged over all visible colours): every colour moves in proportion to its own gradient, with the same
  RMS step as Adam's. ``--optim eps``: Adam with ε = the RMS of the first step's gradient.
* ``--coherent-px P``: each colour gradient diffused over its neighbours in the scene in the optimiser step (repeated
  averaging over the 16 nearest Gaussians until it has spread over σ = P px × stroke size × the pixel footprint at
  the scene's median distance).
  Both patch the Stylize phase's optimiser start (``engine.stylize.colour_steps.start``), which optimises the active
  rows of c_s (``run_state.active.gather``).
* ``--multiscale L``: the broad-strokes term (multi-scale NNFM, ``style/multiscale.py``, now part of the engine) at
  weight L: the setting ``lambda_multiscale`` (same as ``--lambda-multiscale L``; strength applies). Without it the
  engine's own default holds (λ_NNFM when no CLIP weights are found, 0 with them); ``--multiscale 0`` switches it
  off (the "today" rows of docs/notes/texture-scale.md were measured without the term).
* ``--factors 2,4``: the broad-strokes term's downsampling factors (``multiscale.DEFAULT_FACTORS``, shipped 2,4,8).
* ``--field-steps C,F``: coherent strokes' shares of the learning rate for the colours and for the colour field
  (``colour_field.COLOUR_STEP_SHARE`` and ``FIELD_STEP_SHARE``, shipped 0.5,0.5); ``--colour-field 0`` (the CLI's)
  switches the field off.
* ``--epochs-factor``, ``--no-crop``, ``--seed`` and the CLI's own options (``--lambda-content``,
  ``--working-width``, ``--style-scale`` ...).

    python bench/studies/scale_causes.py --tag base --multiscale 0 --style
    ../shared/data/styles/starry_night_vangogh.jpg python bench/studies/scale_causes.py --tag global --optim global
    --multiscale 0 --style ...
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from gstyle_core.cli.stylize import add_stylize_arguments, build_request  # noqa: E402
from gstyle_core.engine import colour_field  # noqa: E402
from gstyle_core.engine.build import build_stylizer, style_paths  # noqa: E402
from gstyle_core.engine.run_figures import evaluate_run, texture_scale_line  # noqa: E402
from gstyle_core.engine.visible_adam import VisibleAdam  # noqa: E402
from gstyle_core.machine import set_torch_threads  # noqa: E402
from gstyle_core.scene_images import save_png  # noqa: E402
from gstyle_core.style import multiscale  # noqa: E402


class GlobalNormAdam(VisibleAdam):
    """VisibleAdam with one second moment for all colours (the mean of g² over the visible rows): the update keeps
    the gradient's relative sizes (SGD with momentum) at Adam's RMS step."""

    def __init__(self, param: torch.Tensor, lr: float) -> None:
        super().__init__(param, lr)
        self.v_all, self.t_all = 0.0, 0

    @torch.no_grad()
    def step(self) -> int:
        rows = self.visible_rows()
        if rows.numel() == 0:
            return 0
        b1, b2 = self.betas
        g, m, t = self.first_moment(rows)
        self.t_all += 1
        self.v_all = b2 * self.v_all + (1 - b2) * float((g * g).mean())
        v_hat = self.v_all / (1 - b2 ** self.t_all)
        m_hat = m / (1 - b1 ** t).reshape(-1, 1)
        self.param[rows] -= self.param_groups[0]["lr"] * m_hat / (v_hat ** 0.5 + self.eps)
        return int(rows.numel())


class FirstRmsEpsAdam(VisibleAdam):
    """VisibleAdam whose ε is set at the first step to the RMS of that step's visible gradient."""

    @torch.no_grad()
    def step(self) -> int:
        if self.eps == 1e-8 and self.param.grad is not None:
            rows = self.visible_rows()
            if rows.numel():
                self.eps = float(self.param.grad[rows].pow(2).mean().sqrt())
        return super().step()


def pixel_footprint(engine) -> float:
    """Scene units per working-width pixel at the scene's median distance from the training cameras."""
    return colour_field.pixel_footprint(engine.params["means"].detach().numpy(), engine.cameras)


def neighbour_operator(points: np.ndarray, k: int = 16) -> tuple[torch.Tensor, float]:
    """Sparse row-normalised [N, N] averaging over each point and its ``k`` nearest (Gaussian weights, σ = the median
    k-th neighbour distance / 2); returns it and the mean squared distance it spreads a value over (one pass)."""
    from scipy.spatial import cKDTree

    d, j = cKDTree(points).query(points, k=k + 1)
    sigma = max(float(np.median(d[:, -1])) / 2, 1e-12)
    n = len(points)
    w = np.exp(-0.5 * (d / sigma) ** 2)
    w /= w.sum(axis=1, keepdims=True)
    spread = float((w * d * d).sum(axis=1).mean())
    idx = torch.as_tensor(np.stack([np.repeat(np.arange(n), k + 1), j.reshape(-1)]), dtype=torch.long)
    op = torch.sparse_coo_tensor(idx, torch.as_tensor(w.reshape(-1), dtype=torch.float32), (n, n)).coalesce()
    return op, spread


def patch_optimiser(engine, optim: str, coherent_px: float) -> dict:
    """Wrap the Stylize phase's optimiser start (``engine.stylize.colour_steps.start``: at its first step and after
    every split's refit) so that it starts a variant; returns a dict the patch fills with notes."""
    notes: dict = {}
    stylize, run = engine.stylize, engine.run_state
    steps = stylize.colour_steps
    original = steps.start

    def start(lr: float):
        original(lr)
        c_opt = steps.c_opt  # the optimised copy of the active rows of c_s
        if optim == "global":
            steps.optimiser = GlobalNormAdam(c_opt, lr=lr)
        elif optim == "eps":
            steps.optimiser = FirstRmsEpsAdam(c_opt, lr=lr)
        if coherent_px > 0:
            pos = run.active.gather(engine.params["means"].detach()).numpy()
            sigma = coherent_px * engine.settings.style_scale * pixel_footprint(engine)
            t0 = time.perf_counter()
            op, spread = neighbour_operator(pos)
            passes = int(min(64, max(1, np.ceil(2 * sigma * sigma / spread))))  # surface diffusion: 2σ² = n·spread
            notes.setdefault("neighbour_seconds", []).append(round(time.perf_counter() - t0, 2))
            notes.update(sigma_scene_units=sigma, passes=passes, one_pass_rms=spread ** 0.5)

            plain_step = steps.optimiser.step

            def smoothed_step():  # once per optimiser step, after the split ranking has read the raw gradient
                g = c_opt.grad
                if g is not None:
                    for _ in range(passes):
                        g = torch.sparse.mm(op, g)
                    c_opt.grad = g
                return plain_step()

            steps.optimiser.step = smoothed_step

    steps.start = start
    return notes


def time_multiscale(engine) -> dict:
    """Seconds spent in the broad-strokes term's forward passes (``objective.loss.multiscale_term``), accumulated from
    the first stylization step on in the returned dict's ``seconds`` (0 while the term is off)."""
    timer = {"seconds": 0.0, "hooked": None}
    steps = engine.stylize.colour_steps
    start = steps.start  # the objective is built right after the optimiser starts: build it here

    def before(_module, _inputs):
        timer["t0"] = time.perf_counter()

    def after(_module, _inputs, _output):
        timer["seconds"] += time.perf_counter() - timer.pop("t0", time.perf_counter())

    def start_and_hook(lr: float):
        start(lr)
        term = engine.build_objective().loss.multiscale_term
        if term is not None and term is not timer["hooked"]:  # (re)built: a new module to time
            term.register_forward_pre_hook(before)
            term.register_forward_hook(after)
            timer["hooked"] = term

    steps.start = start_and_hook
    return timer


def build(args: argparse.Namespace, overrides: dict):
    """The engine ``gstyle stylize`` builds for ``args``, with ``overrides`` (``StylizeSettings`` fields) on top."""
    request = build_request(args)
    request.overrides.update(overrides)
    return build_stylizer(request)


def run(args: argparse.Namespace, extra: argparse.Namespace) -> dict:
    """One stylization with the variant in ``extra``; writes the outputs under ``extra.out_dir``."""
    overrides = {}
    if extra.no_crop:
        overrides["crop_to_scene"] = False
    if extra.seed is not None:
        overrides["seed"] = extra.seed
    if extra.multiscale is not None:
        overrides["lambda_multiscale"] = extra.multiscale
    engine, scene, _, _, style = build(args, overrides)
    if extra.epochs_factor != 1:
        overrides["epochs"] = engine.settings.epochs * extra.epochs_factor
        engine, scene, _, _, style = build(args, overrides)
    notes = patch_optimiser(engine, extra.optim, extra.coherent_px)
    multiscale = time_multiscale(engine)
    t0 = time.perf_counter()
    engine.run()
    seconds = time.perf_counter() - t0
    q = evaluate_run(engine, scene, style)
    before, after = q.pop("images")
    s = engine.settings
    stem = Path(extra.out_dir) / extra.tag
    stem.parent.mkdir(parents=True, exist_ok=True)
    save_png(f"{stem}_before.png", before)
    save_png(f"{stem}_after.png", after)
    steps = engine.stylize_steps
    out = {"tag": extra.tag, "scene": args.scene or "demo", "style": args.style, "variant": vars(extra),
           "styles": [{"path": p, "weight": w} for p, w in zip(style_paths(args.style), s.style_weights, strict=True)],
           "nnfm_drop": q["nnfm_drop"], "structure": q["structure"], "texture_scale": q["texture_scale"],
           "seconds_total": round(seconds, 1), "seconds_stylize": round(engine.timings.get("stylize", 0.0), 1),
           "stylize_steps": steps, "seconds_per_step": round(engine.timings.get("stylize", 0.0) / max(1, steps), 3),
           "multiscale_seconds": round(multiscale["seconds"], 1),
           "gaussians": engine.gaussian_count, "settings": s.to_dict(), "notes": notes, "quality": q}
    Path(f"{stem}.json").write_text(json.dumps(out, indent=1, default=str))
    print(f"{extra.tag}: NNFM drop {100 * q['nnfm_drop']:.1f} %, structure {q['structure']:.3f}, "
          f"{out['seconds_per_step']:.2f} s/step, {seconds:.0f} s (shared machine)")
    print(texture_scale_line(q["texture_scale"]))
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_stylize_arguments(p)
    p.add_argument("--tag", required=True, help="name of this run's outputs")
    p.add_argument("--out-dir", default="/tmp/scale")
    p.add_argument("--optim", choices=("adam", "global", "eps"), default="adam")
    p.add_argument("--coherent-px", type=float, default=0.0)
    p.add_argument("--multiscale", type=float, default=None,
                   help="λ of the broad-strokes term, i.e. --lambda-multiscale (default: the engine's; 0: off)")
    p.add_argument("--factors", default=None, help="the broad-strokes term's downsampling factors, e.g. 2,4")
    p.add_argument("--field-steps", default=None,
                   help="coherent strokes: the colours' and the field's shares of the learning rate, e.g. 1,1")
    p.add_argument("--epochs-factor", type=float, default=1.0)
    p.add_argument("--no-crop", action="store_true")
    p.add_argument("--seed", type=int, default=None, help="the engine's seed (default: the settings')")
    args = p.parse_args(argv)
    if args.multiscale is not None and args.lambda_multiscale is not None \
            and args.multiscale != args.lambda_multiscale:
        p.error("--multiscale and --lambda-multiscale set the same weight: give one")
    if args.factors:
        multiscale.DEFAULT_FACTORS = tuple(float(f) for f in args.factors.split(","))
    if args.field_steps:
        colours, field = (float(x) for x in args.field_steps.split(","))
        colour_field.COLOUR_STEP_SHARE, colour_field.FIELD_STEP_SHARE = colours, field
    names = ("tag", "out_dir", "optim", "coherent_px", "multiscale", "factors", "field_steps", "epochs_factor",
             "no_crop", "seed")
    extra = argparse.Namespace(**{n: getattr(args, n) for n in names})
    if args.threads:
        set_torch_threads(args.threads)
    run(args, extra)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
