"""Load GLSL sources from the repository's ``shaders/`` folder by name."""

from __future__ import annotations

from functools import cache
from pathlib import Path

_CHECKOUT_DIR = Path(__file__).resolve().parents[1] / "shaders"  # the repository's shaders/ (editable install)
_INSTALLED_DIR = Path(__file__).resolve().parent / "shaders"  # where a regular install puts them (app.shaders)
SHADER_DIR = _CHECKOUT_DIR if _CHECKOUT_DIR.is_dir() else _INSTALLED_DIR


@cache
def shader_source(name: str) -> str:
    """Return the text of ``shaders/<name>`` (e.g. ``"splat.vert"``); a missing file is a clear error."""
    path = SHADER_DIR / name
    if not path.is_file():
        raise FileNotFoundError(f"shader {name!r} not found in {SHADER_DIR}")
    return path.read_text(encoding="utf-8")


def program_sources(stem: str) -> dict[str, str]:
    """Vertex, fragment (and, when ``<stem>.geom`` exists, geometry) shader sources for ``<stem>.*`` as moderngl
    keyword arguments."""
    sources = {"vertex_shader": shader_source(f"{stem}.vert"), "fragment_shader": shader_source(f"{stem}.frag")}
    if (SHADER_DIR / f"{stem}.geom").is_file():
        sources["geometry_shader"] = shader_source(f"{stem}.geom")
    return sources


def with_defines(source: str, *names: str) -> str:
    """``source`` with ``#define NAME 1`` for each name, placed after its ``#version`` line (GLSL wants it first)."""
    head, _, rest = source.partition("\n")
    return "\n".join([head, *(f"#define {name} 1" for name in names), rest])
