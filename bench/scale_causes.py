"""Why the added texture does not follow the stroke size: one stylization per variant, measured (docs/texture-scale.md).

Each run builds the engine as ``gstyle stylize`` does (``build_stylizer``), changes one thing, runs it to the end and
writes ``OUT_before.png`` / ``OUT_after.png`` and ``OUT.json`` with the CLI's quality figures (NNFM drop, structure:
``evaluate_run``), the texture-scale figure (``style/texture_scale.py``, masked by the evaluation views' alpha) and
the time per stylization step. Variants (prototypes only; the engine is not changed):

* ``--optim global``: Adam's per-colour normalisation replaced by one shared one (momentum as Adam's β1, the second
  moment averaged over all visible colours): every colour moves in proportion to its own gradient, with the same
  RMS step as Adam's. ``--optim eps``: Adam with ε = the RMS of the first step's gradient.
* ``--coherent-px P``: each colour gradient diffused over its neighbours in the scene in the optimiser step (repeated
  averaging over the 16 nearest Gaussians until it has spread over σ = P px × stroke size × the pixel footprint at
  the scene's median distance).
* ``--multiscale L``: the multi-scale term (``style/multiscale.py``) added to the objective with weight L × strength.
* ``--epochs-factor``, ``--no-crop`` and the CLI's own options (``--lambda-content``, ``--working-width``,
  ``--style-scale`` ...).

    python bench/scale_causes.py --tag base --style ../shared/data/styles/starry_night_vangogh.jpg
    python bench/scale_causes.py --tag global --optim global --style ...
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from gstyle_core.pipeline.cli import add_stylize_arguments, build_stylizer, evaluate_run  # noqa: E402
from gstyle_core.pipeline.visible_adam import VisibleAdam  # noqa: E402
from gstyle_core.render_cli import render_scene_image, save_png  # noqa: E402
from gstyle_core.style.texture_scale import matched_side, texture_scale  # noqa: E402

EVAL_WIDTH = 256  # evaluate_run's width


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
    means = engine.params["means"].detach().numpy()
    centre = np.median(means, axis=0)
    dists = [np.linalg.norm(c.position - centre) / c.fx for c in engine.cameras]
    return float(np.median(dists))


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
    """Replace the engine's colour optimiser start by a variant; returns a dict the patch fills with notes."""
    notes: dict = {}
    original = engine._start_colour_optimiser

    def start(ids):
        original(ids)
        if optim == "global":
            engine._opt = GlobalNormAdam(engine._c_opt, lr=engine._lr())
        elif optim == "eps":
            engine._opt = FirstRmsEpsAdam(engine._c_opt, lr=engine._lr())
        if coherent_px > 0:
            pos = engine.params["means"].detach()
            pos = (pos if ids is None else pos[ids]).numpy()
            sigma = coherent_px * engine.settings.style_scale * pixel_footprint(engine)
            t0 = time.perf_counter()
            op, spread = neighbour_operator(pos)
            passes = int(min(64, max(1, np.ceil(2 * sigma * sigma / spread))))  # surface diffusion: 2σ² = n·spread
            notes.setdefault("neighbour_seconds", []).append(round(time.perf_counter() - t0, 2))
            notes.update(sigma_scene_units=sigma, passes=passes, one_pass_rms=spread ** 0.5)

            param, plain_step = engine._c_opt, engine._opt.step

            def smoothed_step():  # once per optimiser step, after the split ranking has read the raw gradient
                g = param.grad
                if g is not None:
                    for _ in range(passes):
                        g = torch.sparse.mm(op, g)
                    param.grad = g
                return plain_step()

            engine._opt.step = smoothed_step

    engine._start_colour_optimiser = start
    return notes


class WithMultiScale:
    """The engine's StyleObjective plus λ·(multi-scale term) on the same (cropped) render."""

    def __init__(self, objective, weight: float, factors: tuple[float, ...]) -> None:
        from gstyle_core.style.multiscale import MultiScaleStyleLoss

        self.inner = objective
        self.weight = weight
        self.term = MultiScaleStyleLoss(objective.vgg, objective._styles_small, factors=factors,
                                        style_weights=objective._style_weights())
        self.seconds = 0.0

    def __getattr__(self, name):
        return getattr(self.inner, name)

    def __call__(self, image, content, view, coverage=None):
        total, terms = self.inner(image, content, view, coverage=coverage)
        t0 = time.perf_counter()
        box = self.inner.network_box(view, coverage)
        img, cov = (image, coverage) if box is None else (image[box], coverage[box])
        ms = self.term(img.permute(2, 0, 1)[None], cov)
        self.seconds += time.perf_counter() - t0
        strength = float(self.inner._settings.strength)
        return total + self.weight * strength * ms, {**terms, "multiscale": float(ms.detach())}


def run(args: argparse.Namespace, extra: argparse.Namespace) -> dict:
    """One stylization with the variant in ``extra``; writes the outputs under ``extra.out_dir``."""
    overrides = {}
    if extra.no_crop:
        overrides["crop_to_scene"] = False
    if extra.seed is not None:
        overrides["seed"] = extra.seed
    engine, scene, _, _, style = build_stylizer(args, **overrides)
    if extra.epochs_factor != 1:
        overrides["epochs"] = engine.settings.epochs * extra.epochs_factor
        engine, scene, _, _, style = build_stylizer(args, **overrides)
    notes = patch_optimiser(engine, extra.optim, extra.coherent_px)
    wrapper: list[WithMultiScale] = []
    if extra.multiscale > 0:
        from gstyle_core.pipeline.objective import StyleObjective

        factors = tuple(float(f) for f in extra.factors.split(","))

        def factory(style_in, settings):
            wrapper.append(WithMultiScale(StyleObjective(style_in, settings), extra.multiscale, factors))
            return wrapper[-1]

        engine._objective_factory = factory
    t0 = time.perf_counter()
    engine.run()
    seconds = time.perf_counter() - t0
    q = evaluate_run(engine, scene, style)
    before, after = q.pop("images")
    s = engine.settings
    from gstyle_core.pipeline.stylizer import choose_views

    cams = [engine.full_cameras[i].resized_to_width(EVAL_WIDTH) for i in choose_views(engine.full_cameras, 3)]
    alpha = np.concatenate([render_scene_image(scene, c, with_alpha=True)[1] for c in cams], axis=1)
    styles = style if isinstance(style, list) else [style]
    fig = texture_scale(before, after, alpha.reshape(before.shape[:2]), styles,
                        matched_side(s.working_width, s.style_scale, EVAL_WIDTH), s.style_weights or None)
    stem = Path(extra.out_dir) / extra.tag
    stem.parent.mkdir(parents=True, exist_ok=True)
    save_png(f"{stem}_before.png", before)
    save_png(f"{stem}_after.png", after)
    steps = engine.stylize_steps
    from gstyle_core.pipeline.cli import style_paths

    out = {"tag": extra.tag, "scene": args.scene or "demo", "style": args.style, "variant": vars(extra),
           "styles": [{"path": p, "weight": w} for p, w in zip(style_paths(args.style), s.style_weights, strict=True)],
           "nnfm_drop": q["nnfm_drop"], "structure": q["structure"], "texture_scale": fig.to_dict(),
           "seconds_total": round(seconds, 1), "seconds_stylize": round(engine.timings.get("stylize", 0.0), 1),
           "stylize_steps": steps, "seconds_per_step": round(engine.timings.get("stylize", 0.0) / max(1, steps), 3),
           "multiscale_seconds": round(wrapper[-1].seconds, 1) if wrapper else 0.0,
           "gaussians": engine.gaussian_count, "settings": s.to_dict(), "notes": notes, "quality": q}
    Path(f"{stem}.json").write_text(json.dumps(out, indent=1, default=str))
    print(f"{extra.tag}: NNFM drop {100 * q['nnfm_drop']:.1f} %, structure {q['structure']:.3f}, "
          f"{out['seconds_per_step']:.2f} s/step, {seconds:.0f} s (shared machine)")
    print(fig.line())
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_stylize_arguments(p)
    p.add_argument("--tag", required=True, help="name of this run's outputs")
    p.add_argument("--out-dir", default="/tmp/scale")
    p.add_argument("--optim", choices=("adam", "global", "eps"), default="adam")
    p.add_argument("--coherent-px", type=float, default=0.0)
    p.add_argument("--multiscale", type=float, default=0.0, help="λ of the multi-scale term (0: off)")
    p.add_argument("--factors", default="2,4", help="its downsampling factors")
    p.add_argument("--epochs-factor", type=float, default=1.0)
    p.add_argument("--no-crop", action="store_true")
    p.add_argument("--seed", type=int, default=None, help="the engine's seed (default: the settings')")
    args = p.parse_args(argv)
    names = ("tag", "out_dir", "optim", "coherent_px", "multiscale", "factors", "epochs_factor", "no_crop", "seed")
    extra = argparse.Namespace(**{n: getattr(args, n) for n in names})
    if args.threads:
        torch.set_num_threads(args.threads)
    run(args, extra)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
