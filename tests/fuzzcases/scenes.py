"""Fuzz cases for ``load_scene``: every scene format, from a small valid file, mutated.

Valid files come from our writers (3DGS PLY, .splat) or small encoders here (the PLY encodings we only
read, PlayCanvas compressed PLY, SPZ v1-v4); the mutations are byte-level (see ``draw``) or structural:
lying element/point counts, wrong property types, dropped or repeated header lines, another format line,
NaN/inf floats, lying SPZ header fields and v4 stream tables, and for SOG bundles (``tests/fuzzcases/sog.py``)
lying meta.json fields and damaged, missing, lossy or mis-sized images inside an intact ZIP.
"""

from __future__ import annotations

import gzip
import re
import struct
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import zstandard

from gstyle_core.errors import SceneFormatError
from gstyle_core.io import load_scene
from gstyle_core.io.ply_3dgs import encode_3dgs_body, encode_3dgs_header, rest_field_count
from gstyle_core.io.splat import encode_splat
from gstyle_core.io.validate import LOG_SCALE_MAX, LOG_SCALE_MIN, OPACITY_LOGIT_LIMIT
from gstyle_core.scene import GaussianScene
from tests.fuzzcases.common import HUGE_COUNTS, NASTY_FLOATS, Draw, FuzzFailure, draw_bytes, mutate_bytes, rejected
from tests.fuzzcases.sog import SOG_MUTATIONS, valid_sog
from tests.synthetic import blob_scene

SCENE_FORMATS = [
    "ply-le",
    "ply-le-double",
    "ply-be",
    "ply-ascii",
    "ply-compressed",
    "splat",
    "spz-v1-gzip",
    "spz-v2-gzip",
    "spz-v3-gzip",
    "spz-v3-raw",
    "spz-v4-zstd",
    "sog-bundle",
]
PLY_TYPE_WORDS = ["char", "uchar", "short", "ushort", "int", "uint", "float", "double", "int8", "float64",
                  "list uchar int", "list uchar float", "quad", ""]
BAD_COUNT_WORDS = ["-1", "1e3", "0x10", "ten", "5 5", "", "٣", "9" * 5000, "0" * 30 + "7"]
BAD_TOKENS = ["nan", "inf", "-inf", "1e999", "-1e999", "NaN", "0x10", "1.2.3", "abc", "1e-400", "--1", ""]
SPZ_MAGIC = 0x5053474E
SPZ_SH_DIMS = {0: 0, 1: 3, 2: 8, 3: 15, 4: 24}
END_HEADER = b"end_header\n"


@dataclass
class Sample:
    """A valid file before packing: ``payload`` is mutated structurally, then ``pack`` makes the file."""

    kind: str  # "ply", "ply-ascii", "splat", "spz-legacy", "spz-v4", "sog"
    payload: bytes
    suffix: str
    pack: Callable[[bytes], bytes] = field(default=lambda b: b)
    compressed: bool = False
    floats: list[tuple[int, str]] = field(default_factory=list)  # (offset after the header, struct code)
    count: int = 0


def _scene(draw: Draw, max_degree: int = 3) -> GaussianScene:
    return blob_scene(draw.integer(1, 12), seed=draw.integer(0, 2**16), sh_degree=draw.integer(0, max_degree))


def _float_slots(count: int, columns: int, code: str, start: int = 0, stride: int | None = None) -> list:
    size = struct.calcsize(code)
    stride = stride or columns * size
    return [(start + i * stride + j * size, code) for i in range(count) for j in range(columns)]


def _ply_3dgs(draw: Draw, fmt: str) -> Sample:
    """3DGS PLY written by our writer (``ply-le``) or re-encoded from its table (double, big endian, ascii)."""
    scene = _scene(draw)
    n, n_rest = scene.count, rest_field_count(scene, True)
    header, body = encode_3dgs_header(n, n_rest), encode_3dgs_body(scene, True)
    if fmt == "ply-le":
        return Sample("ply", header + body, ".ply", floats=_float_slots(n, len(body) // 4 // n, "<f"), count=n)
    table = np.frombuffer(body, "<f4").reshape(n, -1)
    encoding, dtype, code, word = {
        "ply-le-double": ("binary_little_endian", "<f8", "<d", "double"),
        "ply-be": ("binary_big_endian", ">f4", ">f", "float"),
        "ply-ascii": ("ascii", "", "", "float"),
    }[fmt]
    text = header.decode().replace("binary_little_endian", encoding).replace("property float", f"property {word}")
    if fmt == "ply-ascii":
        rows = "".join(" ".join(f"{v:.9g}" for v in row) + "\n" for row in table.tolist())
        return Sample("ply-ascii", text.encode() + rows.encode(), ".ply", count=n)
    floats = _float_slots(n, table.shape[1], code)
    return Sample("ply", text.encode() + table.astype(dtype).tobytes(), ".ply", floats=floats, count=n)


def _compressed_ply(draw: Draw) -> Sample:
    """A PlayCanvas compressed PLY: per-chunk float bounds, random packed words, optional colour and SH."""
    n = draw.integer(1, 600)
    colour = draw.choice([True, False])
    n_rest = draw.choice([0, 9, 24, 45])
    rng = np.random.default_rng(draw.integer(0, 2**16))
    chunks = -(-n // 256)
    groups = [("", "xyz"), ("scale_", "xyz")] + ([("", "rgb")] if colour else [])
    names, columns = [], []
    for prefix, axes in groups:
        lo = rng.uniform(-2.0, 0.0, (chunks, 3))
        hi = lo + rng.uniform(0.1, 2.0, (chunks, 3))
        names += [f"min_{prefix}{a}" for a in axes] + [f"max_{prefix}{a}" for a in axes]
        columns += [lo, hi]
    chunk_table = np.concatenate(columns, axis=1).astype("<f4")
    lines = ["ply", "format binary_little_endian 1.0", f"element chunk {chunks}"]
    lines += [f"property float {p}" for p in names]
    lines += [f"element vertex {n}"] + [f"property uint packed_{p}" for p in ("position", "rotation", "scale",
                                                                              "color")]
    packed = rng.integers(0, 2**32, (n, 4), dtype=np.uint64).astype("<u4")
    body = chunk_table.tobytes() + packed.tobytes()
    if n_rest:
        lines += [f"element sh {n}"] + [f"property uchar f_rest_{i}" for i in range(n_rest)]
        body += rng.integers(0, 256, (n, n_rest), dtype=np.uint8).tobytes()
    head = ("\n".join(lines + ["end_header"]) + "\n").encode()
    return Sample("ply", head + body, ".ply", floats=_float_slots(chunks, len(names), "<f"), count=n)


def _splat(draw: Draw) -> Sample:
    scene = _scene(draw, max_degree=0)
    return Sample("splat", encode_splat(scene), ".splat", floats=_float_slots(scene.count, 6, "<f", 0, 32),
                  count=scene.count)


def _spz_streams(draw: Draw, version: int, n: int, degree: int) -> list[bytes]:
    rng = np.random.default_rng(draw.integer(0, 2**16))

    def raw(size: int) -> bytes:
        return rng.integers(0, 256, size, dtype=np.uint8).tobytes()

    positions = rng.normal(0, 1, (n, 3)).astype("<f2").tobytes() if version == 1 else raw(9 * n)
    return [positions, raw(n), raw(3 * n), raw(3 * n), raw((3 if version < 3 else 4) * n),
            raw(3 * n * SPZ_SH_DIMS[degree])]


def _spz(draw: Draw, version: int, container: str) -> Sample:
    """SPZ v1-v3 as one gzip stream (or raw), v4 as a header, a stream table and zstd frames."""
    n, degree = draw.integer(1, 12), draw.integer(0, 4)
    streams = _spz_streams(draw, version, n, degree)
    if version < 4:
        payload = struct.pack("<IIIBBBB", SPZ_MAGIC, version, n, degree, 12, 0, 0) + b"".join(streams)
        if container == "gzip":
            return Sample("spz-legacy", payload, ".spz", pack=gzip.compress, compressed=True, count=n)
        return Sample("spz-legacy", payload, ".spz", count=n)
    if not streams[5]:
        streams = streams[:5]
    frames = [zstandard.ZstdCompressor().compress(s) for s in streams]
    head = struct.pack("<IIIBBBBI", SPZ_MAGIC, 4, n, degree, 12, 0, len(frames), 32) + bytes(12)
    toc = b"".join(struct.pack("<QQ", len(f), len(s)) for f, s in zip(frames, streams, strict=True))
    return Sample("spz-v4", head + toc + b"".join(frames), ".spz", count=n)


def valid_scene_file(fmt: str, draw: Draw) -> Sample:
    """A small valid file of format ``fmt`` (one of ``SCENE_FORMATS``)."""
    if fmt.startswith("ply-") and fmt != "ply-compressed":
        return _ply_3dgs(draw, fmt)
    if fmt == "ply-compressed":
        return _compressed_ply(draw)
    if fmt == "splat":
        return _splat(draw)
    if fmt == "sog-bundle":
        payload, count = valid_sog(draw)
        return Sample("sog", payload, ".sog", count=count)
    version, container = int(fmt[5]), fmt.rsplit("-", 1)[1]
    return _spz(draw, version, container)


# --- structural mutations ----------------------------------------------------------------------------


def _split_header(payload: bytes) -> tuple[list[str], bytes] | None:
    end = payload.find(END_HEADER)
    if end < 0:
        return None
    return payload[:end].decode("latin-1").split("\n"), payload[end:]


def _edit_header_line(payload: bytes, draw: Draw, prefix: str, edit: Callable[[list[str]], list[str]]) -> bytes:
    parts = _split_header(payload)
    if parts is None:
        return payload
    lines, rest = parts
    indices = [i for i, ln in enumerate(lines) if ln.startswith(prefix)]
    if not indices:
        return payload
    i = draw.choice(indices)
    lines[i] = " ".join(edit(lines[i].split(" ")))
    return "\n".join(lines).encode("utf-8") + rest


def _lie_count(payload: bytes, draw: Draw, sample: Sample) -> bytes:
    def edit(words: list[str]) -> list[str]:
        n = sample.count
        value = draw.choice([str(draw.choice(HUGE_COUNTS)), str(n + 1), str(max(n - 1, 0)), str(2 * n),
                             draw.choice(BAD_COUNT_WORDS)])
        return words[:2] + [value]

    return _edit_header_line(payload, draw, "element ", edit)


def _retype(payload: bytes, draw: Draw, sample: Sample) -> bytes:
    return _edit_header_line(payload, draw, "property ", lambda w: [w[0], draw.choice(PLY_TYPE_WORDS), w[-1]])


def _rename(payload: bytes, draw: Draw, sample: Sample) -> bytes:
    names = ["x", "f_rest_99", "f_dc_0", "opacity", "packed_position", "rot_3", "X", ""]
    return _edit_header_line(payload, draw, "property ", lambda w: w[:-1] + [draw.choice(names)])


def _other_format(payload: bytes, draw: Draw, sample: Sample) -> bytes:
    formats = ["ascii", "binary_little_endian", "binary_big_endian", "binary_middle_endian"]
    return _edit_header_line(payload, draw, "format ",
                             lambda w: [w[0], draw.choice(formats), draw.choice(["1.0", "2.0", ""])])


def _drop_or_repeat_line(payload: bytes, draw: Draw, sample: Sample) -> bytes:
    parts = _split_header(payload)
    if parts is None:
        return payload
    lines, rest = parts
    i = draw.integer(0, len(lines) - 1)
    lines[i:i + 1] = draw.choice([[], [lines[i], lines[i]], [lines[i], "comment ☃"], ["bogus line"]])
    return "\n".join(lines).encode("utf-8", "replace") + rest


def _body_start(payload: bytes, sample: Sample) -> int | None:
    if sample.kind not in ("ply", "ply-ascii"):
        return 0
    end = payload.find(END_HEADER)
    return None if end < 0 else end + len(END_HEADER)


def _nonfinite(payload: bytes, draw: Draw, sample: Sample) -> bytes:
    """Put NaN/inf/huge/denormal values into float fields (binary) or bad tokens into an ASCII body."""
    start = _body_start(payload, sample)
    if start is None:
        return payload
    if sample.kind == "ply-ascii":
        body = payload[start:].decode("latin-1")
        spans = [m.span() for m in re.finditer(r"\S+", body)]
        if not spans:
            return payload
        a, b = draw.choice(spans)
        token = draw.choice(BAD_TOKENS + [repr(draw.choice(NASTY_FLOATS))])
        return payload[:start] + (body[:a] + token + body[b:]).encode("latin-1")
    if not sample.floats:
        return payload
    out = bytearray(payload)
    for _ in range(draw.integer(1, 6)):
        offset, code = draw.choice(sample.floats)
        if start + offset + struct.calcsize(code) <= len(out):
            struct.pack_into(code, out, start + offset, draw.choice(NASTY_FLOATS))
    return bytes(out)


def _spz_field(payload: bytes, draw: Draw, sample: Sample) -> bytes:
    """Overwrite one SPZ header field (or, in v4, the stream table) with a lie."""
    fields = [(4, "<I"), (8, "<I"), (12, "B"), (13, "B"), (14, "B")]
    if sample.kind == "spz-v4":
        fields += [(15, "B"), (16, "<I")] + [(32 + 8 * i, "<Q") for i in range(12)]
    offset, code = draw.choice(fields)
    if offset + struct.calcsize(code) > len(payload):
        return payload
    limit = 2 ** (8 * struct.calcsize(code))
    (current,) = struct.unpack_from(code, payload, offset)
    value = draw.choice([current + 1, current - 1, current * 2, draw.choice(HUGE_COUNTS), draw.integer(0, 255)])
    out = bytearray(payload)
    struct.pack_into(code, out, offset, value % limit)
    return bytes(out)


STRUCTURAL = {
    "ply": [_lie_count, _retype, _rename, _other_format, _drop_or_repeat_line, _nonfinite],
    "ply-ascii": [_lie_count, _retype, _rename, _other_format, _drop_or_repeat_line, _nonfinite],
    "splat": [_nonfinite],
    "spz-legacy": [_spz_field],
    "spz-v4": [_spz_field],
    "sog": SOG_MUTATIONS,
}


def _mutate_payload(payload: bytes, draw: Draw, sample: Sample) -> bytes:
    ops = STRUCTURAL[sample.kind]
    if draw.integer(0, 1):
        return draw.choice(ops)(payload, draw, sample)
    return mutate_bytes(payload, draw)


def scene_case(fmt: str, draw: Draw) -> tuple[bytes, str]:
    """A mutated file of format ``fmt``: (bytes, file suffix)."""
    sample = valid_scene_file(fmt, draw)
    payload = sample.payload
    structural = draw.integer(0 if sample.compressed else 1, 3)
    for _ in range(structural):
        payload = _mutate_payload(payload, draw, sample)
    data = sample.pack(payload)
    if sample.compressed:
        for _ in range(draw.integer(0 if structural else 1, 2)):
            data = mutate_bytes(data, draw)
    if draw.integer(0, 19) == 0:
        data = draw.choice([b"", b"\n", data[:4], draw_bytes(draw, draw.integer(1, 200))])
    return data, draw.choice([sample.suffix, sample.suffix, ".bin"])


# --- the property ------------------------------------------------------------------------------------

SCENE_FIELDS = {"means": 3, "log_scales": 3, "quats": 4, "sh_dc": 3}


def check_scene(scene: GaussianScene) -> None:
    """Raise FuzzFailure unless the scene is what ``validate_and_repair`` promises."""
    n = scene.count
    for name, width in SCENE_FIELDS.items():
        arr = getattr(scene, name)
        if arr.shape != (n, width) or arr.dtype != np.float32 or not np.isfinite(arr).all():
            raise FuzzFailure(f"{name}: shape {arr.shape}, dtype {arr.dtype}, finite {np.isfinite(arr).all()}")
    op, rest = scene.opacity_logits, scene.sh_rest
    if op.shape != (n,) or op.dtype != np.float32 or not np.isfinite(op).all():
        raise FuzzFailure(f"opacity_logits: shape {op.shape}, dtype {op.dtype}")
    if rest.ndim != 3 or rest.shape[0] != n or rest.shape[1] not in (0, 3, 8, 15) or rest.shape[2] != 3:
        raise FuzzFailure(f"sh_rest: shape {rest.shape}")
    if rest.dtype != np.float32 or not np.isfinite(rest).all():
        raise FuzzFailure("sh_rest is not finite float32")
    if n and np.abs(np.linalg.norm(scene.quats.astype(np.float64), axis=1) - 1.0).max() > 1e-4:
        raise FuzzFailure("quaternions are not unit length")
    if n and (scene.log_scales.min() < LOG_SCALE_MIN or scene.log_scales.max() > LOG_SCALE_MAX):
        raise FuzzFailure("log-scales outside the documented clamp")
    if n and np.abs(op).max() > OPACITY_LOGIT_LIMIT:
        raise FuzzFailure("opacity logits outside the documented clamp")


def check_scene_file(path: Path) -> str:
    """Load ``path``: "ok" for a valid scene and a consistent report, "error" for a one-line SceneFormatError.

    A MemoryError turned into a SceneFormatError counts as a failure: the claimed size must be checked
    against the file before allocating.
    """
    try:
        scene, report = load_scene(path)
    except SceneFormatError as exc:
        return rejected(exc)
    check_scene(scene)
    if report.count_loaded != scene.count or report.sh_degree != scene.sh_degree:
        raise FuzzFailure(f"report disagrees with the scene: {report}")
    if report.count_in_file - report.dropped != scene.count:
        raise FuzzFailure(f"count_in_file {report.count_in_file} - dropped {report.dropped} != {scene.count}")
    report.summary()
    return "ok"
