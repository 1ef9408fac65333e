"""The standard 3DGS ``.ply`` layout (Kerbl et al.): read any PLY encoding, write binary little-endian.

Per vertex: x, y, z, [nx, ny, nz], f_dc_0..2, f_rest_0..(3K-1), opacity, scale_0..2, rot_0..3. ``f_rest`` is
stored channel-major (all K red coefficients, then green, then blue); in memory it is ``sh_rest[N, K, 3]``.
Scales are log std-devs, opacity is a logit, rot is (w, x, y, z). Extra properties are ignored.
A file whose f_rest values are all exactly zero (what ``save_scene`` writes for degree-0 scenes) loads as
SH degree 0, with a warning.
"""

from __future__ import annotations

from typing import IO

import numpy as np

from ..errors import SceneFormatError
from ..scene import GaussianScene
from .ply_header import PlyElement, PlyHeader, read_elements

REQUIRED = [
    "x",
    "y",
    "z",
    "f_dc_0",
    "f_dc_1",
    "f_dc_2",
    "opacity",
    "scale_0",
    "scale_1",
    "scale_2",
    "rot_0",
    "rot_1",
    "rot_2",
    "rot_3",
]
REST_COUNT_TO_DEGREE = {0: 0, 9: 1, 24: 2, 45: 3}
WRITE_REST_FIELDS_SH0 = 45  # viewers that insist on f_rest fields get 45 zeros for degree-0 scenes


def _rest_field_count(vertex: PlyElement, name: str) -> int:
    rest = [p for p in vertex.property_names() if p.startswith("f_rest_")]
    if set(rest) != {f"f_rest_{i}" for i in range(len(rest))}:
        raise SceneFormatError(f"{name}: f_rest_* properties are not numbered 0..{len(rest) - 1}")
    if len(rest) not in REST_COUNT_TO_DEGREE:
        raise SceneFormatError(f"{name}: {len(rest)} f_rest_* properties match no SH degree (0, 9, 24 or 45)")
    return len(rest)


def check_3dgs_vertex(vertex: PlyElement | None, name: str) -> int:
    """Check the vertex element has the 3DGS properties as float/double; return the f_rest count."""
    if vertex is None:
        raise SceneFormatError(f"{name}: PLY has no 'vertex' element")
    types = dict(vertex.properties)
    missing = [p for p in REQUIRED if p not in types]
    if missing:
        raise SceneFormatError(f"{name}: not a 3DGS PLY, missing properties: {', '.join(missing)}")
    n_rest = _rest_field_count(vertex, name)
    needed = REQUIRED + [f"f_rest_{i}" for i in range(n_rest)]
    wrong = [f"{p} ({types[p]})" for p in needed if types[p] not in ("f4", "f8")]
    if wrong:
        raise SceneFormatError(f"{name}: properties must be float or double, got {', '.join(wrong[:4])}")
    return n_rest


def read_3dgs_ply(data: bytes, header: PlyHeader, name: str) -> tuple[GaussianScene, int, list[str]]:
    """Decode a 3DGS PLY; returns the scene, the count in the file and warnings."""
    vertex = header.element("vertex")
    n_rest = check_3dgs_vertex(vertex, name)
    tables, trailing = read_elements(data, header, {"vertex"}, name)
    v = tables["vertex"]
    warnings = []
    if trailing and header.elements[-1] is vertex:
        unit = "numbers" if header.fmt == "ascii" else "bytes"
        warnings.append(f"ignored {trailing:,} trailing {unit} after the declared {vertex.count:,} vertices")

    def cols(names: list[str]) -> np.ndarray:
        out = np.empty((len(v), len(names)), np.float32)
        for j, p in enumerate(names):
            out[:, j] = v[p]
        return out

    k = n_rest // 3
    if n_rest and not any(np.any(v[f"f_rest_{i}"]) for i in range(n_rest)):
        warnings.append(f"all {n_rest} f_rest values are zero: loaded as SH degree 0")
        k = n_rest = 0
    rest = cols([f"f_rest_{i}" for i in range(n_rest)]).reshape(len(v), 3, k).transpose(0, 2, 1)
    scene = GaussianScene(
        means=cols(["x", "y", "z"]),
        log_scales=cols(["scale_0", "scale_1", "scale_2"]),
        quats=cols(["rot_0", "rot_1", "rot_2", "rot_3"]),
        opacity_logits=cols(["opacity"])[:, 0].copy(),
        sh_dc=cols(["f_dc_0", "f_dc_1", "f_dc_2"]),
        sh_rest=np.ascontiguousarray(rest),
    )
    return scene, vertex.count, warnings


def _write_fields(n_rest: int) -> list[str]:
    return (
        ["x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2"]
        + [f"f_rest_{i}" for i in range(n_rest)]
        + ["opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"]
    )


def encode_3dgs_header(count: int, n_rest: int) -> bytes:
    """The binary little-endian header for ``count`` vertices with ``n_rest`` f_rest fields."""
    lines = [
        "ply",
        "format binary_little_endian 1.0",
        "comment written by G-Style Studio",
        f"element vertex {count}",
    ]
    lines += [f"property float {p}" for p in _write_fields(n_rest)]
    lines.append("end_header")
    return ("\n".join(lines) + "\n").encode("ascii")


def encode_3dgs_body(scene: GaussianScene, keep_sh: bool) -> bytes:
    """Vertex records as float32 little-endian, in the order of ``encode_3dgs_header``."""
    n = scene.count
    k = scene.sh_rest.shape[1] if keep_sh else 0
    n_rest = 3 * k if k else WRITE_REST_FIELDS_SH0
    table = np.zeros((n, 9 + n_rest + 8), "<f4")
    table[:, 0:3] = scene.means
    table[:, 6:9] = scene.sh_dc
    if k:
        table[:, 9 : 9 + n_rest] = scene.sh_rest.transpose(0, 2, 1).reshape(n, n_rest)
    tail = 9 + n_rest
    table[:, tail] = scene.opacity_logits
    table[:, tail + 1 : tail + 4] = scene.log_scales
    table[:, tail + 4 : tail + 8] = scene.quats
    return table.tobytes()


def rest_field_count(scene: GaussianScene, keep_sh: bool) -> int:
    """How many f_rest fields ``save_scene`` writes for this scene."""
    k = scene.sh_rest.shape[1] if keep_sh else 0
    return 3 * k if k else WRITE_REST_FIELDS_SH0


def write_3dgs_ply(fh: IO[bytes], scene: GaussianScene, keep_sh: bool) -> None:
    """Write header and body to an open binary file."""
    fh.write(encode_3dgs_header(scene.count, rest_field_count(scene, keep_sh)))
    fh.write(encode_3dgs_body(scene, keep_sh))
