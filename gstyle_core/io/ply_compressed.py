"""PlayCanvas / SuperSplat "compressed PLY" (``element chunk`` + packed uint32 vertex properties).

Decoding follows the PlayCanvas engine's ``GSplatCompressedData`` rules:
- vertices come in chunks of 256; chunk ``c`` stores float min/max of position (x, y, z), of log-scale and,
  in newer files (18 properties), of colour (r, g, b);
- ``packed_position`` and ``packed_scale``: 11-10-11 bit unorms (x in the top 11 bits), lerped between the
  chunk min and max (scales in log space);
- ``packed_rotation``: top 2 bits = index of the largest component in (w, x, y, z) order, then three 10-bit
  unorms for the other components in order, each mapped by (u - 0.5) * sqrt(2); the largest one is
  sqrt(1 - sum of squares);
- ``packed_color``: 8-8-8-8 unorms r, g, b, a (r in the top byte); rgb lerped between the chunk colour min/max
  when present; sh_dc = (rgb - 0.5) / C0; opacity logit = logit(a), with a = 0 -> -40 and a = 1 -> +40;
- optional ``element sh`` with uchar f_rest_0..(3K-1) (channel-major like 3DGS): value * 8 / 255 - 4.
Positions are not re-oriented (the file keeps the source PLY's axes).
"""

from __future__ import annotations

import numpy as np

from ..errors import SceneFormatError
from ..scene import SH_C0, GaussianScene
from .ply_3dgs import REST_COUNT_TO_DEGREE
from .ply_header import PlyHeader, read_elements
from .quantize import from_smallest_three, opacity_logits_of

CHUNK = 256
CHUNK_BASE = [
    "min_x",
    "min_y",
    "min_z",
    "max_x",
    "max_y",
    "max_z",
    "min_scale_x",
    "min_scale_y",
    "min_scale_z",
    "max_scale_x",
    "max_scale_y",
    "max_scale_z",
]
CHUNK_COLOUR = ["min_r", "min_g", "min_b", "max_r", "max_g", "max_b"]
PACKED = ["packed_position", "packed_rotation", "packed_scale", "packed_color"]


def is_compressed_ply(header: PlyHeader) -> bool:
    """True when the header has a chunk element and packed_* vertex properties."""
    vertex = header.element("vertex")
    return (
        header.element("chunk") is not None
        and vertex is not None
        and "packed_position" in vertex.property_names()
    )


def _unorm(values: np.ndarray, shift: int, bits: int) -> np.ndarray:
    return ((values >> np.uint32(shift)) & np.uint32((1 << bits) - 1)).astype(np.float32) / ((1 << bits) - 1)


def _lerp(lo: np.ndarray, hi: np.ndarray, t: np.ndarray) -> np.ndarray:
    return lo * (1.0 - t) + hi * t


def _check(header: PlyHeader, name: str) -> tuple[bool, int]:
    chunk, vertex = header.element("chunk"), header.element("vertex")
    ctypes, vtypes = dict(chunk.properties), dict(vertex.properties)
    missing = [p for p in CHUNK_BASE if p not in ctypes] + [p for p in PACKED if p not in vtypes]
    if missing:
        raise SceneFormatError(f"{name}: compressed PLY is missing properties: {', '.join(missing)}")
    has_colour = all(p in ctypes for p in CHUNK_COLOUR)
    wrong = [
        f"{p} ({ctypes[p]})"
        for p in CHUNK_BASE + (CHUNK_COLOUR if has_colour else [])
        if ctypes[p] not in ("f4", "f8")
    ]
    wrong += [f"{p} ({vtypes[p]})" for p in PACKED if vtypes[p] != "u4"]
    if wrong:
        raise SceneFormatError(f"{name}: compressed PLY has wrong property types: {', '.join(wrong[:4])}")
    expected_chunks = -(-vertex.count // CHUNK)
    if chunk.count != expected_chunks:
        raise SceneFormatError(
            f"{name}: {chunk.count} chunks for {vertex.count} vertices (expected {expected_chunks})"
        )
    n_rest = 0
    sh = header.element("sh")
    if sh is not None:
        n_rest = len(sh.properties)
        if n_rest not in REST_COUNT_TO_DEGREE or sh.count != vertex.count:
            raise SceneFormatError(
                f"{name}: sh element has {n_rest} properties x {sh.count} rows; "
                f"expected 9/24/45 x {vertex.count}"
            )
        if set(sh.property_names()) != {f"f_rest_{i}" for i in range(n_rest)}:
            raise SceneFormatError(f"{name}: sh element properties must be f_rest_0..{n_rest - 1}")
        if any(t != "u1" for _, t in sh.properties):
            raise SceneFormatError(f"{name}: sh element properties must be uchar")
    return has_colour, n_rest


def _decode_rotation(packed: np.ndarray) -> np.ndarray:
    """2-bit largest index + three 10-bit components -> (w, x, y, z)."""
    norm = np.float32(np.sqrt(2.0))
    small = np.stack([(_unorm(packed, s, 10) - 0.5) * norm for s in (20, 10, 0)], axis=1)
    return from_smallest_three((packed >> np.uint32(30)).astype(np.int64), small).astype(np.float32)


def read_compressed_ply(data: bytes, header: PlyHeader, name: str) -> tuple[GaussianScene, int, list[str]]:
    """Decode a PlayCanvas compressed PLY into a scene; returns scene, count in file and warnings."""
    has_colour, n_rest = _check(header, name)
    wanted = {"chunk", "vertex"} | ({"sh"} if n_rest else set())
    tables, trailing = read_elements(data, header, wanted, name)
    chunks, v = tables["chunk"], tables["vertex"]
    n = len(v)
    warnings = (
        [f"ignored {trailing:,} trailing bytes"] if trailing and header.elements[-1].name in wanted else []
    )

    def per_vertex(fields: list[str]) -> np.ndarray:
        table = np.stack([chunks[f].astype(np.float32) for f in fields], axis=1)
        return np.repeat(table, CHUNK, axis=0)[:n]

    def unpack_111011(values: np.ndarray) -> np.ndarray:
        return np.stack([_unorm(values, 21, 11), _unorm(values, 11, 10), _unorm(values, 0, 11)], axis=1)

    lo_hi = per_vertex(CHUNK_BASE)
    means = _lerp(lo_hi[:, 0:3], lo_hi[:, 3:6], unpack_111011(v["packed_position"].astype(np.uint32)))
    log_scales = _lerp(lo_hi[:, 6:9], lo_hi[:, 9:12], unpack_111011(v["packed_scale"].astype(np.uint32)))
    colour_packed = v["packed_color"].astype(np.uint32)
    rgba = np.stack([_unorm(colour_packed, s, 8) for s in (24, 16, 8, 0)], axis=1)
    rgb = rgba[:, :3]
    if has_colour:
        c = per_vertex(CHUNK_COLOUR)
        rgb = _lerp(c[:, 0:3], c[:, 3:6], rgb)
    opacity = opacity_logits_of(rgba[:, 3])
    sh_rest = np.zeros((n, 0, 3), np.float32)
    if n_rest:
        sh = tables["sh"]
        raw = np.stack([sh[f"f_rest_{i}"] for i in range(n_rest)], axis=1).astype(np.float32)
        sh_rest = np.ascontiguousarray(
            (raw * (8.0 / 255.0) - 4.0).reshape(n, 3, n_rest // 3).transpose(0, 2, 1)
        )
    scene = GaussianScene(
        means=means.astype(np.float32),
        log_scales=log_scales.astype(np.float32),
        quats=_decode_rotation(v["packed_rotation"].astype(np.uint32)),
        opacity_logits=opacity.astype(np.float32),
        sh_dc=((rgb - 0.5) / SH_C0).astype(np.float32),
        sh_rest=sh_rest.astype(np.float32),
    )
    return scene, n, warnings
