"""Checkpoints of a stylization run: where they live, what they hold, and the checks made before resuming.

A checkpoint is one ``torch.save`` file in ``cache_dir()/checkpoints/`` (never beside the output), written
atomically. It holds ``{"format": FORMAT, "meta": {...}, "state": engine.state_dict()}``; ``meta`` carries a
fingerprint of the run's inputs (digests of the loaded scene, style image, cameras, photos and the resolved
settings), the command-line arguments, the phase/step reached and the time it was written. Numpy arrays in the
state are stored as tensors so that the file loads with ``torch.load(weights_only=True)``: a checkpoint is data,
never code. Unreadable, truncated or foreign files and files made for other inputs raise ``CheckpointError``.
torch is imported only to save and load (fingerprints and paths do not need it).
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import re
import time
from pathlib import Path
from typing import Any

import numpy as np

from ..atomic import atomic_write
from ..errors import GStyleError, OutputWriteError
from ..outputs import writing
from ..paths import cache_dir

FORMAT = "gstyle-stylize-checkpoint/2"  # 2: the engine's state as its phases' states (engine/phases)
_FORMAT_FAMILY = FORMAT.rsplit("/", 1)[0]
SUFFIX = ".ckpt"
_NDARRAY = "__ndarray__"


class CheckpointError(GStyleError):
    """A checkpoint that cannot be used: missing, unreadable, or made for other inputs."""


def checkpoints_dir() -> Path:
    """``cache_dir()/checkpoints`` (not created here)."""
    return cache_dir() / "checkpoints"


def _digest(*parts: str) -> str:
    h = hashlib.blake2b(digest_size=8)
    for part in parts:
        h.update(part.encode("utf-8", "surrogateescape") + b"\0")
    return h.hexdigest()


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", text)[:40] or "run"


def stylize_checkpoint_path(out: str | Path) -> Path:
    """Checkpoint of ``gstyle stylize ... --out OUT``: keyed by the absolute output path."""
    target = Path(out).expanduser().resolve()
    return checkpoints_dir() / f"stylize-{_slug(target.stem)}-{_digest(str(target))}{SUFFIX}"


def studio_checkpoint_path(scene: str | Path, style: str | Path | list[str] | None) -> Path:
    """Checkpoint of a studio session: keyed by the absolute scene and style paths (a mix: all its paintings)."""
    scene_abs = str(Path(scene).expanduser().resolve())
    styles = [style] if isinstance(style, (str, Path)) else list(style or [])
    style_abs = "|".join(str(Path(s).expanduser().resolve()) for s in styles)
    return checkpoints_dir() / f"studio-{_slug(Path(scene).stem)}-{_digest(scene_abs, style_abs)}{SUFFIX}"


# ---------------------------------------------------------------------------------------------- fingerprint
def _hash_arrays(arrays) -> str:
    h = hashlib.blake2b(digest_size=16)
    for a in arrays:
        a = np.ascontiguousarray(np.asarray(a))
        h.update(f"{a.dtype.str}{a.shape}".encode())
        h.update(a.tobytes())
    return h.hexdigest()


def saved_capacity(state: dict[str, Any]) -> tuple[int, str] | None:
    """The cap on Gaussians a checkpointed engine state was planned with (``Stylizer.state_dict``'s "capacity"; None
    for a state from before caps were kept, or a test double's): a resumed run holds the same part of a large capture
    whatever memory is free now."""
    cap = state.get("capacity") if isinstance(state, dict) else None
    if not cap:
        return None
    how = str(cap[1]) if "kept from the run resumed" in str(cap[1]) else f"{cap[1]}, kept from the run resumed"
    return int(cap[0]), how


def engine_fingerprint(engine: Any) -> dict[str, str]:
    """Digests of what an engine was built from (scene, style, cameras, photos, settings but its device and palette
    match), for resume checks.

    Call it right after building the engine (settings may change later through ``set_params``). Engines without
    these attributes (test doubles) give an empty fingerprint, which matches anything.
    """
    out: dict[str, str] = {}
    scene = getattr(engine, "input_scene", None)
    if scene is not None:
        out["scene"] = _hash_arrays([scene.means, scene.log_scales, scene.quats, scene.opacity_logits, scene.sh_dc,
                                     scene.sh_rest])
    styles = getattr(engine, "styles", None) or ([engine.style] if getattr(engine, "style", None) is not None else [])
    if styles:
        out["style image"] = _hash_arrays(styles)
    cams = getattr(engine, "full_cameras", None)
    if cams is not None:
        out["cameras"] = _hash_arrays([np.array([c.width, c.height, c.fx, c.fy, c.cx, c.cy], np.float64)
                                       for c in cams] + [c.world_to_cam for c in cams])
    photos = getattr(engine, "photos", None)
    if photos is not None:
        out["photos"] = _hash_arrays(photos)
    selection = getattr(engine, "input_selection", None)
    if selection is not None:
        out["selection"] = _hash_arrays([np.asarray(selection, bool)])
    settings = getattr(engine, "settings", None)
    if settings is not None and hasattr(settings, "to_dict"):
        # where it computes is not what it computes: a run saved on the GPU goes on on the CPU and back (the device
        # reads as its default here, so the digests of checkpoints saved with it stay as they were)
        values = {**settings.to_dict(), "device": "auto"}
        # the palette match only blends the final colour match, which a finished run keeps both ends of: a run goes
        # on at another strength (and the digests of checkpoints written before it was a setting stay as they were)
        values.pop("palette_match", None)
        out["settings"] = _digest(json.dumps(values, sort_keys=True, default=str))
    return out


# ---------------------------------------------------------------------------------------------- save / load
def _to_storable(obj: Any) -> Any:
    """Numpy arrays -> tagged tensors, numpy scalars -> Python numbers (so ``weights_only`` loading works)."""
    if isinstance(obj, np.ndarray):
        import torch

        return {_NDARRAY: torch.from_numpy(np.array(obj, copy=True))}
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, dict):
        return {k: _to_storable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return type(obj)(_to_storable(v) for v in obj)
    if isinstance(obj, Path):
        return str(obj)
    return obj


def _from_storable(obj: Any) -> Any:
    if isinstance(obj, dict):
        if set(obj) == {_NDARRAY}:
            return obj[_NDARRAY].numpy()
        return {k: _from_storable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return type(obj)(_from_storable(v) for v in obj)
    return obj


def save_checkpoint(path: str | Path, state: dict[str, Any], meta: dict[str, Any]) -> Path:
    """Write ``state`` (an engine's ``state_dict()``) with ``meta`` atomically (a failure: ``OutputWriteError``,
    the previous checkpoint whole); leftovers of killed writes go."""
    import torch

    path = Path(path)
    with writing(path):  # a read-only or full cache: ``OutputWriteError``, one line
        path.parent.mkdir(parents=True, exist_ok=True)
    for stale in path.parent.glob(f".{path.name}.*.tmp"):  # a previous writer was killed mid-write
        with contextlib.suppress(OSError):
            stale.unlink()
    info = {"phase": state.get("phase"), "step": state.get("global_step", state.get("steps")), "saved_at": time.time()}
    payload = {"format": FORMAT, "meta": _to_storable({**meta, **info}), "state": _to_storable(state)}
    with atomic_write(path, "wb") as fh:
        torch.save(payload, fh)
    return path


def read_checkpoint(path: str | Path) -> tuple[dict[str, Any], dict[str, Any]]:
    """``(state, meta)`` of a checkpoint file; ``CheckpointError`` when missing, unreadable or not a checkpoint."""
    import torch

    path = Path(path)
    if not path.is_file():
        raise CheckpointError(f"no checkpoint at {path}")
    try:
        obj = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:  # noqa: BLE001 - any failure to unpickle means the file cannot be used
        raise CheckpointError(f"checkpoint {path} is unreadable (truncated or corrupt: {type(exc).__name__}); "
                              "delete it or run without resuming") from None
    found = obj.get("format") if isinstance(obj, dict) else None
    if isinstance(found, str) and found.startswith(_FORMAT_FAMILY + "/") and found != FORMAT:
        raise CheckpointError(f"checkpoint {path} was written by another version of G-Style ({found}; this one "
                              f"reads {FORMAT}); run without resuming (a new run replaces it)")
    if not isinstance(obj, dict) or found != FORMAT or not isinstance(obj.get("state"), dict):
        found = found if isinstance(obj, dict) else type(obj).__name__
        raise CheckpointError(f"{path} is not a G-Style checkpoint of format {FORMAT} (found {found!r})")
    return _from_storable(obj["state"]), _from_storable(obj.get("meta") or {})


def check_fingerprint(path: str | Path, meta: dict[str, Any], fingerprint: dict[str, str]) -> None:
    """Raise ``CheckpointError`` naming what differs when ``meta`` was saved for other inputs."""
    saved = meta.get("fingerprint") or {}
    differ = [k for k, v in fingerprint.items() if k in saved and saved[k] != v]
    differ += [k for k in saved if k not in fingerprint and fingerprint]
    if differ:
        raise CheckpointError(f"checkpoint {path} was made for a different {', '.join(differ)}; "
                              "use the same inputs and options, or run without resuming")


def load_checkpoint(path: str | Path, fingerprint: dict[str, str] | None = None
                    ) -> tuple[dict[str, Any], dict[str, Any]]:
    """``read_checkpoint`` then, when ``fingerprint`` is given, ``check_fingerprint``."""
    state, meta = read_checkpoint(path)
    if fingerprint:
        check_fingerprint(path, meta, fingerprint)
    return state, meta


def describe_checkpoint(path: str | Path) -> str:
    """One line about a checkpoint file (for ``gstyle cache``); says so when it is unreadable."""
    try:
        _state, meta = read_checkpoint(path)
    except CheckpointError as exc:
        return f"unusable: {exc}"
    when = time.strftime("%Y-%m-%d %H:%M", time.localtime(meta.get("saved_at", 0)))
    what = meta.get("out") or meta.get("scene") or "?"
    return f"{meta.get('kind', '?')} {what}: phase {meta.get('phase')}, step {meta.get('step')}, saved {when}"


# ---------------------------------------------------------------------------------------------- during a run
class RunCheckpointer:
    """Saves an engine's ``state_dict()`` at every phase end and every ``every`` seconds (0: phase ends only).

    A periodic save that cannot be written (a full disk, a read-only cache) does not stop the run: ``failed``
    holds its one-line reason, ``failures`` counts them, and the last checkpoint written (if any) stays."""

    def __init__(self, engine: Any, path: str | Path, meta: dict[str, Any], every: float) -> None:
        self.engine, self.path, self.meta, self.every = engine, Path(path), meta, float(every)
        self._phase = engine.phase
        self._last = time.monotonic()
        self.saved = 0
        self.failed: str | None = None
        self.failures = 0

    def after_step(self) -> bool:
        """Save when the phase changed or the interval passed (never once the run is done); True if it saved."""
        phase = self.engine.phase
        due = phase != self._phase or (self.every > 0 and time.monotonic() - self._last >= self.every)
        self._phase = phase
        if not due or getattr(self.engine, "done", False):
            return False
        try:
            self.save()
        except OutputWriteError as exc:
            self._last = time.monotonic()  # try again at the next phase end or interval
            self.failed, self.failures = str(exc), self.failures + 1
            return False
        return True

    def save(self) -> Path:
        """Write the checkpoint now."""
        save_checkpoint(self.path, self.engine.state_dict(), self.meta)
        self._last = time.monotonic()
        self.saved += 1
        return self.path

    def remove(self) -> None:
        """Delete the checkpoint (after the outputs are complete)."""
        with contextlib.suppress(FileNotFoundError):
            self.path.unlink()


@contextlib.contextmanager
def deferred_interrupts():
    """Within the block, a first SIGINT/SIGTERM sets ``flag["stop"]`` instead of interrupting (so the current step
    ends cleanly and a checkpoint can be written); a second one interrupts. Outside the main thread: no change."""
    import signal
    import threading

    flag = {"stop": False}
    if threading.current_thread() is not threading.main_thread():
        yield flag
        return

    def handler(signum, _frame):
        if flag["stop"]:  # asked twice: stop at once
            raise KeyboardInterrupt
        flag["stop"] = True

    previous = {sig: signal.signal(sig, handler) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield flag
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)
