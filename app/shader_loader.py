"""Load GLSL sources from the repository's ``shaders/`` folder by name."""

from __future__ import annotations

from functools import cache
from pathlib import Path

SHADER_DIR = Path(__file__).resolve().parents[1] / "shaders"


@cache
def shader_source(name: str) -> str:
    """Return the text of ``shaders/<name>`` (e.g. ``"splat.vert"``); a missing file is a clear error."""
    path = SHADER_DIR / name
    if not path.is_file():
        raise FileNotFoundError(f"shader {name!r} not found in {SHADER_DIR}")
    return path.read_text(encoding="utf-8")


def program_sources(stem: str) -> dict[str, str]:
    """Vertex and fragment shader sources for ``<stem>.vert`` / ``<stem>.frag`` as moderngl keyword arguments."""
    return {"vertex_shader": shader_source(f"{stem}.vert"), "fragment_shader": shader_source(f"{stem}.frag")}
