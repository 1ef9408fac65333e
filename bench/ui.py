"""UI frame rate of the studio while its worker stylizes, and what the UI costs the worker.

Runs the real app headless (glfw NULL platform + EGL, llvmpipe) at 800×600 with the panel, the real engine in its
spawned worker process, the app's frame cap, and a scripted session: the camera orbits for 3 s, then stays still
for 3 s, repeated (the worker streams colours all the time). Measured only once the engine is in its stylize
phase. Then the same worker runs alone (no UI, the bridge polled every 10 ms) from the start of stylize for the
same number of steps: ``worker_share`` = steps/s with the UI ÷ steps/s alone (the same steps, so the same mix of
stylize steps and the fast refit steps after a split).

    .venv/bin/python bench/ui.py [--scene PATH] [--seconds 24] [--size 800x600] [--fps 60] [--no-pacing]

``--idle``: instead, the idle CPU share (issue #27 item 7): the studio in a real window (``$DISPLAY``, else a private
Xvfb) with ``--no-engine``, left alone (camera still, nothing changing); its process's CPU time over ``--idle-seconds``
after ``--settle`` seconds, once rendering on demand (the default) and once with ``--always-draw``. Prints
``RESULT idle_cpu_share=… always_draw_cpu_share=…`` (fractions of one core; target ≤ 0.05).

Frame time = interval between consecutive frame starts (what the user sees), each frame ending with
``ctx.finish()`` (a real window's swap waits for the rasteriser the same way). Prints a table, the peak resident
memory of the UI process and of the worker's (``VmHWM``, with their sum per Gaussian), with ``--controls`` the
seconds each artist's control took to take effect (``drive_controls``), then
``RESULT ui_fps=… ui_p95_ms=… worker_steps_per_s=… worker_share=…``.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from app.engine_factory import make_stylizer  # noqa: E402
from app.main import parse_size  # noqa: E402
from app.open_files import load_scene_with_cameras  # noqa: E402
from app.studio import StudioApp  # noqa: E402
from app.window import open_window  # noqa: E402
from app.worker import ThreadWorkerBridge, WorkerBridge  # noqa: E402
from gstyle_core.machine import peak_rss_bytes  # noqa: E402

SEGMENT_S = 3.0


def stylize_started(bridge: WorkerBridge) -> bool:
    rep = bridge.state.last_report or {}
    return rep.get("phase") in ("stylize", "refit", "finish", "done")


def stat_cpu_seconds(stat_path: str) -> float:
    """User + system CPU seconds from a Linux /proc ``stat`` file (a process's or a thread's); NaN elsewhere."""
    try:
        fields = Path(stat_path).read_text().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    except (OSError, IndexError, ValueError):
        return float("nan")


def worker_cpu_seconds(bridge: WorkerBridge) -> float:
    """CPU seconds of the worker so far: its process, or its thread's task in this process (thread mode)."""
    handle = bridge._process
    if hasattr(handle, "pid"):
        return stat_cpu_seconds(f"/proc/{handle.pid}/stat")
    return stat_cpu_seconds(f"/proc/self/task/{handle.native_id}/stat")


def worker_alone(config: dict, steps: int, warmup_timeout: float, mode: str = "process") -> float:
    """Worker steps per second over the first ``steps`` steps of its stylize phase, with nobody drawing: the same
    steps the UI run made, so a phase mix that differs (refits are fast, stylize steps slow) cannot bias the ratio."""
    bridge = (ThreadWorkerBridge if mode == "thread" else WorkerBridge)(make_stylizer, config)
    bridge.start()
    try:
        deadline = time.perf_counter() + warmup_timeout
        while not stylize_started(bridge):
            bridge.poll()
            if bridge.state.error or time.perf_counter() > deadline:
                raise SystemExit(f"worker did not reach stylize: {bridge.state.error or 'timeout'}")
            time.sleep(0.03)
        start_steps, t0 = bridge.state.reports_received, time.perf_counter()
        cpu0 = worker_cpu_seconds(bridge)
        while (bridge.state.reports_received - start_steps < steps and not bridge.state.done
               and time.perf_counter() - t0 < warmup_timeout):
            bridge.poll()
            time.sleep(0.01)
        wall = time.perf_counter() - t0
        print(f"worker alone: {(worker_cpu_seconds(bridge) - cpu0) / wall:.2f} cores")
        return (bridge.state.reports_received - start_steps) / wall
    finally:
        bridge.quit()


def ui_session(args, config: dict) -> dict:
    """Frame intervals (ms) while moving and while still, and the worker's steps/s, with the UI running."""
    import glfw

    window = open_window(*args.size, headless=True)
    loaded = load_scene_with_cameras(args.scene, None)
    app = StudioApp(window.ctx, loaded=loaded, style_path=config["style"], engine_factory=make_stylizer,
                    engine_config=dict(config), output_dir=str(ROOT / "out" / "bench_ui"), worker_mode=args.worker)
    app.progressive = args.pacing
    period = 1.0 / args.fps if args.fps > 0 else 0.0
    frames = {"moving": [], "still": []}
    parts: list[dict[str, float]] = []  # per measured frame: where its time went (``frame_parts``)
    timed = time_parts(app)
    scales: list[float] = []
    details: list[float] = []
    try:
        app.engine.start()
        t_measure = None
        start_steps = 0
        deadline = time.perf_counter()
        last_start = None
        warmup_end = time.perf_counter() + args.warmup_timeout
        while True:
            start = time.perf_counter()
            if t_measure is None and app.engine.bridge is not None and stylize_started(app.engine.bridge):
                t_measure, start_steps, last_start = start, app.engine.bridge.state.reports_received, None
                cpu0 = time.process_time()
                worker_cpu0 = worker_cpu_seconds(app.engine.bridge)
            elapsed = start - (t_measure if t_measure is not None else start)
            if t_measure is not None and elapsed >= args.seconds:
                break
            if t_measure is None and start > warmup_end:
                raise SystemExit(f"worker did not reach stylize: {app.engine.bridge.state.error or 'timeout'}")
            moving = int(elapsed // SEGMENT_S) % 2 == 0
            if last_start is not None and t_measure is not None:
                frames["moving" if moving else "still"].append((start - last_start) * 1e3)
            last_start = start
            timed.clear()
            t_frame = time.perf_counter()
            window.begin_frame()
            screen = window.ctx.screen
            screen.viewport = (0, 0, *window.framebuffer_size)
            screen.use()
            if moving:
                app.control.orbit(4.0, 0.0)
            app.frame(screen)
            t_ui = time.perf_counter()
            window.end_frame(swap=False)
            glfw.swap_buffers(window.handle)
            window.ctx.finish()
            if t_measure is not None:
                parts.append({**timed, "imgui draw + finish": (time.perf_counter() - t_ui) * 1e3,
                              "frame": (time.perf_counter() - t_frame) * 1e3, "moving": float(moving)})
                scales.append(app.views.view.stats.last_scale)
                if moving:
                    details.append(app.views.view.stats.last_detail)
            if period:
                deadline = max(deadline + period, time.perf_counter() - period)
                time.sleep(max(0.0, deadline - time.perf_counter()))
        wall = time.perf_counter() - t_measure
        steps = (app.engine.bridge.state.reports_received - start_steps) / wall
        ui_cores = (time.process_time() - cpu0) / wall  # the UI process, all its threads (llvmpipe's included)
        worker_cores = (worker_cpu_seconds(app.engine.bridge) - worker_cpu0) / wall
        if args.worker == "thread":
            ui_cores -= worker_cores  # the worker thread is part of the UI process
        stats = app.views.view.stats
        memory = {"ui": peak_rss_bytes(), "worker": worker_peak_rss(app.engine.bridge)}
        result = {"memory": memory, "parts": parts, "frames": frames, "steps_per_s": steps,
                  "steps": app.engine.bridge.state.reports_received - start_steps,
                  "median_scale": float(np.median(scales)),
                  "moving_detail": float(np.median(details)) if details else 1.0, "ui_cores": ui_cores,
                  "worker_cores": worker_cores,
                  "builds": stats.builds_completed, "gaussians": app.views.stylized.count}
        result["controls"] = drive_controls(app, window, args.warmup_timeout) if args.controls else []
        return result
    finally:
        app.close()
        window.close()


PARTS = ("engine updates", "scene view")  # the studio's methods timed per frame: their names in the table


def time_parts(app: StudioApp) -> dict[str, float]:
    """Wrap the studio's per-frame work (``PARTS``) so that each frame's milliseconds in it land in the returned dict
    (cleared by the caller at each frame's start)."""
    timed: dict[str, float] = {}

    def wrap(name: str, method):
        def timed_method(*a, **k):
            t0 = time.perf_counter()
            try:
                return method(*a, **k)
            finally:
                timed[name] = timed.get(name, 0.0) + (time.perf_counter() - t0) * 1e3
        return timed_method

    app.sync.apply_updates = wrap("engine updates", app.sync.apply_updates)
    app.render_view = wrap("scene view", app.render_view)
    return timed


def draw_frame(app: StudioApp, window) -> None:
    """One studio frame as the measured loop draws it (camera still)."""
    import glfw

    window.begin_frame()
    screen = window.ctx.screen
    screen.viewport = (0, 0, *window.framebuffer_size)
    screen.use()
    app.frame(screen)
    window.end_frame(swap=False)
    glfw.swap_buffers(window.handle)
    window.ctx.finish()


def drive_controls(app: StudioApp, window, timeout: float) -> list[tuple[str, float, str]]:
    """``--controls``: after the measurement, with frames drawn all the while, the artist's controls one after
    another: pause, the NNFM slider doubled, resume until a step lands, export (.ply), restart, then undo (the result
    before the restart comes back). Returns (control, seconds until it took effect, what showed it)."""
    from app.panels import Command

    def until(predicate) -> float:
        t0 = time.perf_counter()
        while not predicate():
            if time.perf_counter() - t0 > timeout:
                raise SystemExit(f"a control did not take effect in {timeout:g} s: {app.panel.status}")
            draw_frame(app, window)
        return time.perf_counter() - t0

    bridge, done = app.engine.bridge, []
    app.execute(Command("pause"))
    done.append(("pause", until(lambda: bridge.state.paused), "the worker says it paused"))
    value = 2 * float(bridge.state.params.get("lambda_nnfm", 1.0))
    app.execute(Command("set_params", {"lambda_nnfm": value}))
    done.append(("NNFM slider x2", until(lambda: bridge.state.params.get("lambda_nnfm") == value),
                 "the worker echoes the new weight"))
    steps = bridge.state.reports_received
    app.execute(Command("resume"))
    done.append(("resume", until(lambda: bridge.state.reports_received > steps), "a step lands"))
    exported = len(bridge.state.exported)
    app.execute(Command("export", {"format": "ply"}))
    done.append(("export .ply", until(lambda: len(bridge.state.exported) > exported or bridge.state.error),
                 f"written: {bridge.state.exported[-1] if bridge.state.exported else bridge.state.error}"))
    app.execute(Command("restart"))
    history = app.session.history
    done.append(("restart", until(lambda: history.done and history.done[-1].action == "restart"),
                 "the result before it is kept for undo"))
    app.execute(Command("undo"))
    session = app.session
    done.append(("undo of the result", until(lambda: session.result is not None),
                 f"{session.loaded.scene.count:,} Gaussians shown again" if session.loaded is not None else "shown"))
    return done


def print_slow_frames(parts: list[dict[str, float]], limit_ms: float = 50.0) -> None:
    """Where the frames over ``limit_ms`` spent their time, against all frames (means, ms): the cause of the p95."""
    slow = [p for p in parts if p["frame"] > limit_ms]
    names = [*PARTS, "imgui draw + finish"]
    print(f"frames over {limit_ms:g} ms: {len(slow)} of {len(parts)} ({sum(p['moving'] for p in slow):.0f} moving); "
          "mean ms of each part, slow frames / all frames:")
    for name in names:
        mean_slow = np.mean([p.get(name, 0.0) for p in slow]) if slow else 0.0
        print(f"  {name:<22} {mean_slow:8.1f} / {np.mean([p.get(name, 0.0) for p in parts]):6.1f}")
    rest = [p["frame"] - sum(p.get(n, 0.0) for n in names) for p in slow]
    print(f"  {'rest (panel, input)':<22} {np.mean(rest) if rest else 0.0:8.1f}")


def worker_peak_rss(bridge: WorkerBridge) -> int:
    """The worker process's peak resident memory; 0 for a worker thread (its memory is the UI process's)."""
    process = getattr(bridge, "_process", None)
    return peak_rss_bytes(process.pid) if process is not None and process.pid else 0


def summary(ms: list[float]) -> tuple[float, float, float]:
    a = np.asarray(ms)
    return float(1e3 / np.median(a)), float(np.percentile(a, 95)), float(a.max())


def idle_share(args, *extra: str) -> float:
    """CPU share of one core the studio's process uses while nothing changes (see the module docstring)."""
    import subprocess

    env, xvfb = dict(os.environ), None
    if not env.get("DISPLAY"):
        env["DISPLAY"] = ":91"
        xvfb = subprocess.Popen(["Xvfb", ":91", "-screen", "0", "1280x800x24", "-nolisten", "tcp"],
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        time.sleep(1.0)
    argv = [sys.executable, "-m", "app.main", *([args.scene] if args.scene else []), "--no-engine", "--size",
            f"{args.size[0]}x{args.size[1]}", "--output-dir", str(ROOT / "out" / "bench_ui"), *extra]
    proc = subprocess.Popen(argv, cwd=ROOT, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        time.sleep(args.settle)
        t0, c0 = time.monotonic(), stat_cpu_seconds(f"/proc/{proc.pid}/stat")
        time.sleep(args.idle_seconds)
        return (stat_cpu_seconds(f"/proc/{proc.pid}/stat") - c0) / (time.monotonic() - t0)
    finally:
        proc.terminate()
        proc.wait(60)
        if xvfb is not None:
            xvfb.terminate()
            xvfb.wait(10)


def idle_report(args) -> None:
    """``--idle``: the idle CPU share, rendering on demand and drawing every frame."""
    on_demand, always = idle_share(args), idle_share(args, "--always-draw")
    print(f"studio idle ({args.scene or 'bundled demo'}, {args.size[0]}x{args.size[1]}, --no-engine, "
          f"{args.idle_seconds:g} s after {args.settle:g} s): {100 * on_demand:.1f} % of a core rendering on demand, "
          f"{100 * always:.1f} % drawing every frame")
    print(f"RESULT idle_cpu_share={on_demand:.3f} always_draw_cpu_share={always:.3f}")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--scene", default=None, help="scene (default: the bundled demo, 40k Gaussians)")
    p.add_argument("--style", default=str(ROOT / "assets" / "styles" / "starry_night.jpg"))
    p.add_argument("--seconds", type=float, default=24.0)
    p.add_argument("--size", type=parse_size, default=(800, 600))
    p.add_argument("--fps", type=float, default=60.0, help="the app's frame cap (the studio's default is 60)")
    p.add_argument("--no-pacing", dest="pacing", action="store_false")
    p.add_argument("--warmup-timeout", type=float, default=600.0)
    p.add_argument("--gl-threads", type=int, default=None,
                   help="llvmpipe rasteriser threads of the UI (LP_NUM_THREADS; default: the app's choice)")
    p.add_argument("--worker-nice", type=int, default=None, help="niceness added to the worker (default: the app's)")
    p.add_argument("--worker", choices=["process", "thread"], default="process",
                   help="run the engine in a spawned process (the app's choice) or in a thread of the UI process")
    p.add_argument("--controls", action="store_true",
                   help="after the measurement, drive pause, a slider, resume, export, restart and undo (timed)")
    p.add_argument("--idle", action="store_true", help="measure the idle CPU share instead (module docstring)")
    p.add_argument("--idle-seconds", type=float, default=5.0)
    p.add_argument("--settle", type=float, default=10.0, help="--idle: seconds from start to the measurement")
    args = p.parse_args()
    if args.idle:
        idle_report(args)
        return
    if args.gl_threads is not None:
        os.environ["LP_NUM_THREADS"] = str(args.gl_threads)  # read by Mesa when the GL context is created
    if args.worker_nice is not None:
        os.environ["GSTYLE_WORKER_NICE"] = str(args.worker_nice)
    config = {"scene": args.scene, "style": args.style, "cameras": None, "preset": "preview"}
    ui = ui_session(args, config)
    alone = worker_alone(config, max(1, ui["steps"]), args.warmup_timeout, args.worker)
    print(f"scene {args.scene or 'bundled demo'}: {ui['gaussians']} Gaussians, {args.size[0]}x{args.size[1]}, "
          f"cap {args.fps:g} fps, pacing {'on' if args.pacing else 'off'}; {args.seconds:g} s measured; "
          f"LP_NUM_THREADS={os.environ.get('LP_NUM_THREADS', 'unset')}, "
          f"worker: {args.worker}, nice +{os.environ.get('GSTYLE_WORKER_NICE', 'default')}")
    print(f"{'segment':<8} {'frames':>6} {'fps (median)':>12} {'p95 ms':>8} {'max ms':>8}")
    for name, ms in ui["frames"].items():
        if ms:
            fps, p95, worst = summary(ms)
            print(f"{name:<8} {len(ms):>6} {fps:>12.1f} {p95:>8.1f} {worst:>8.1f}")
    every = ui["frames"]["moving"] + ui["frames"]["still"]
    fps, p95, worst = summary(every)
    print(f"{'all':<8} {len(every):>6} {fps:>12.1f} {p95:>8.1f} {worst:>8.1f}")
    print(f"median render scale while measured: {ui['median_scale']:.2f}; median detail while moving: "
          f"{ui['moving_detail']:.2f} of the Gaussians; full-resolution builds completed: {ui['builds']}")
    share = ui["steps_per_s"] / max(alone, 1e-9)
    memory = ui["memory"]
    print_slow_frames(ui["parts"])
    for name, seconds, shown in ui["controls"]:
        print(f"control {name}: {seconds:.1f} s ({shown})")
    print(f"peak memory: UI process {memory['ui'] / 2**30:.2f} GiB, worker process {memory['worker'] / 2**30:.2f} GiB; "
          f"{(memory['ui'] + memory['worker']) / ui['gaussians']:,.0f} bytes a Gaussian together")
    print(f"CPU used: UI process (all threads) {ui['ui_cores']:.2f}, worker {ui['worker_cores']:.2f} of "
          f"{os.cpu_count()} cores")
    print(f"worker steps/s: {ui['steps_per_s']:.2f} with the UI, {alone:.2f} alone ({100 * share:.0f} %)")
    print(f"RESULT ui_fps={fps:.1f} ui_p95_ms={p95:.1f} worker_steps_per_s={ui['steps_per_s']:.2f} "
          f"worker_share={share:.2f}")


if __name__ == "__main__":
    main()
