"""``gstyle cache [--clear [--checkpoints-only]]``: what the cache folder holds, with sizes; emptying it."""

from __future__ import annotations

import argparse
import os
import shutil
from pathlib import Path

from ..crash import CRASHES
from ..paths import cache_dir


def add_cache_arguments(p: argparse.ArgumentParser) -> None:
    """Arguments of ``gstyle cache``."""
    p.add_argument("--clear", action="store_true", help="delete what the cache folder holds")
    p.add_argument("--checkpoints-only", action="store_true",
                   help="with --clear: delete only the checkpoints of interrupted runs")


def _size(path: Path) -> int:
    if path.is_file() or path.is_symlink():
        return path.lstat().st_size
    return sum(p.lstat().st_size for p in path.rglob("*") if p.is_file() or p.is_symlink())


def human_size(n: int) -> str:
    """``1.5 MiB`` style sizes."""
    size = float(n)
    for unit in ("B", "KiB", "MiB", "GiB"):
        if size < 1024 or unit == "GiB":
            return f"{size:.0f} {unit}" if unit == "B" else f"{size:.1f} {unit}"
        size /= 1024
    return f"{size:.1f} GiB"


def _describe(entry: Path) -> str:
    from ..style import precision
    from ..style.vgg import CACHE_FILE

    if entry.name == CACHE_FILE:
        return "converted VGG-16 weights"
    if entry.name == precision.CACHE_FILE:
        return "fp32 or bf16 per CPU model (--precision auto)"
    if entry.name == "checkpoints" and entry.is_dir():
        return "checkpoints of interrupted runs (gstyle stylize --resume, gstyle-studio --resume)"
    if entry.name == "results" and entry.is_dir():
        return "the runs of results the studio saved (Continue this run; the newest 24 within 2 GB)"
    if entry.name == CRASHES and entry.is_dir():
        return "crash logs: the tracebacks of unexpected errors (gstyle, the studio), named by their time"
    if entry.name == "history" and entry.is_dir():
        return "results kept for the studio's undo (deleted when it closes)"
    if entry.is_dir() and any(entry.rglob("*.nbi")):
        return "numba compiled kernels"
    return "other"


def numba_cache_location() -> Path:
    """Where numba keeps the compiled rasterizer kernels: ``$NUMBA_CACHE_DIR``, else ``__pycache__`` beside them."""
    explicit = os.environ.get("NUMBA_CACHE_DIR")
    if explicit:
        return Path(explicit).expanduser()
    return Path(__file__).resolve().parent / "raster" / "__pycache__"


def list_cache() -> list[str]:
    """Lines describing the cache folder's entries (checkpoints one by one) and the numba cache."""
    from ..engine.checkpoint import describe_checkpoint

    root = cache_dir()
    lines = [f"cache folder: {root}"]
    entries = sorted(root.iterdir()) if root.is_dir() else []
    total = 0
    for entry in entries:
        size = _size(entry)
        total += size
        lines.append(f"  {human_size(size):>10}  {entry.name}{'/' if entry.is_dir() else ''}  ({_describe(entry)})")
        if entry.name == "checkpoints" and entry.is_dir():
            for ckpt in sorted(entry.glob("*.ckpt")):
                lines.append(f"  {human_size(_size(ckpt)):>10}    {ckpt.name}: {describe_checkpoint(ckpt)}")
    lines.append(f"  {human_size(total):>10}  in all" if entries else "  (empty)")
    numba_dir = numba_cache_location()
    try:
        inside = numba_dir.resolve().is_relative_to(root.resolve())
    except OSError:
        inside = False
    if not inside:
        kernels = [p for p in numba_dir.glob("*.nb[ci]")] if numba_dir.is_dir() else []
        size = sum(p.stat().st_size for p in kernels)
        lines.append(f"numba compiled kernels (outside the cache folder, not cleared): {numba_dir}, "
                     f"{human_size(size)} in {len(kernels)} files")
    return lines


def clear_cache(checkpoints_only: bool = False) -> tuple[int, int]:
    """Delete the cache folder's contents (or only ``checkpoints/``); returns (entries or checkpoints removed,
    bytes freed)."""
    root = cache_dir()
    targets = [root / "checkpoints"] if checkpoints_only else (sorted(root.iterdir()) if root.is_dir() else [])
    removed = freed = 0
    for target in targets:
        if not (target.exists() or target.is_symlink()):
            continue
        freed += _size(target)
        if target.is_dir() and not target.is_symlink():
            removed += len(list(target.glob("*.ckpt"))) if checkpoints_only else 1
            shutil.rmtree(target)
        else:
            target.unlink()
            removed += 1
    return removed, freed


def cache_command(args: argparse.Namespace) -> int:
    """Run ``gstyle cache``."""
    from ..errors import GStyleError

    if args.checkpoints_only and not args.clear:
        raise GStyleError("--checkpoints-only goes with --clear")
    if args.clear:
        removed, freed = clear_cache(args.checkpoints_only)
        what = "checkpoints" if args.checkpoints_only else "cache entries"
        print(f"removed {removed} {what} from {cache_dir()} ({human_size(freed)} freed)")
        return 0
    print("\n".join(list_cache()))
    return 0
