"""Fuzz cases for the SOG reader: a small ``.sog`` bundle written by our writer, mutated inside the ZIP (so the
reader, not the ZIP checksum, meets the damage) or as bytes; and a SOG folder whose meta.json is mutated.

Structural mutations: a ``meta.json`` field set to a lie (a huge or negative count, another version, wrong types,
NaN, short or empty lists, names outside the folder) or removed; an image's bytes mutated; an image dropped, or
replaced by a lossy WebP, a PNG, an image of another size; the members stored under a lying size (a bomb).
"""

from __future__ import annotations

import io
import json
import zipfile
from pathlib import Path

import numpy as np
from PIL import Image

from gstyle_core.io import save_scene
from gstyle_core.io.sog_write import write_sog_bundle
from tests.fuzzcases.common import HUGE_COUNTS, NASTY_FLOATS, Draw, mutate_bytes
from tests.synthetic import blob_scene

META_PATHS = ["version", "count", "means.mins", "means.maxs", "means.files", "scales.codebook", "scales.files",
              "quats.files", "sh0.codebook", "sh0.files", "shN.count", "shN.bands", "shN.codebook", "shN.files",
              "means.shape", "antialias"]
LIES = [None, True, "x", "two\nlines\x1b[2J", [], {}, [1.0], ["../../etc/passwd", "/dev/zero"], ["a\nb.webp", "c"],
        ["means_l.webp"] * 2, 3, -1, 1.5, 1e308]


def valid_sog(draw: Draw) -> tuple[bytes, int]:
    """A small valid bundle (1-40 Gaussians, SH degree 0-3) and its count."""
    scene = blob_scene(draw.integer(1, 40), seed=draw.integer(0, 2**16), sh_degree=draw.integer(0, 3))
    buffer = io.BytesIO()
    write_sog_bundle(buffer, scene)
    return buffer.getvalue(), scene.count


def _members(payload: bytes) -> dict[str, bytes] | None:
    try:
        with zipfile.ZipFile(io.BytesIO(payload)) as archive:
            return {name: archive.read(name) for name in archive.namelist()}
    except Exception:  # noqa: BLE001 - an earlier byte mutation broke the ZIP: leave the payload as it is
        return None


def _zip(members: dict[str, bytes]) -> bytes:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, data in members.items():
            archive.writestr(name, data)
    return buffer.getvalue()


def _lie(draw: Draw, count: int) -> object:
    return draw.choice([*LIES, draw.choice(HUGE_COUNTS), count + 1, 2 * count, draw.choice(NASTY_FLOATS),
                        [draw.choice(NASTY_FLOATS)] * 3, list(range(300)), "absent"])


def mutate_meta(raw: bytes, draw: Draw) -> bytes:
    """``meta.json`` with one field set to a lie or removed (or its bytes mutated); unchanged if it does not parse."""
    try:
        meta = json.loads(raw)
    except ValueError:  # an earlier mutation broke the JSON
        return mutate_bytes(raw, draw)
    if not isinstance(meta, dict) or draw.integer(0, 5) == 0:
        return mutate_bytes(raw, draw)
    path = draw.choice(META_PATHS).split(".")
    node = meta
    for key in path[:-1]:
        node = node.setdefault(key, {}) if isinstance(node, dict) else {}
    if isinstance(node, dict):
        value = _lie(draw, meta["count"] if isinstance(meta.get("count"), int) else 1)
        if value == "absent":
            node.pop(path[-1], None)
        else:
            node[path[-1]] = value
    return json.dumps(meta).encode()


def write_sog_folder_case(draw: Draw, folder: Path) -> Path:
    """A valid SOG folder from our writer with its meta.json mutated (``mutate_meta``); returns the folder."""
    scene = blob_scene(draw.integer(1, 40), seed=draw.integer(0, 2**16), sh_degree=draw.integer(0, 3))
    save_scene(scene, folder / "meta.json")
    for _ in range(draw.integer(1, 2)):
        (folder / "meta.json").write_bytes(mutate_meta((folder / "meta.json").read_bytes(), draw))
    return folder


def _edit_meta(payload: bytes, draw: Draw, sample: object) -> bytes:
    members = _members(payload)
    if members is None or "meta.json" not in members:
        return payload
    members["meta.json"] = mutate_meta(members["meta.json"], draw)
    return _zip(members)


def _other_image(draw: Draw) -> bytes:
    rng = np.random.default_rng(draw.integer(0, 2**16))
    side = draw.choice([1, 3, 4, 8, 64])
    pixels = rng.integers(0, 256, (side, draw.choice([1, 4, 8, 64]), 4), dtype=np.uint8)
    buffer = io.BytesIO()
    kind = draw.choice(["lossy", "lossless", "png", "gif"])
    if kind == "lossy":
        Image.fromarray(pixels, "RGBA").save(buffer, format="WEBP", quality=80)
    elif kind == "lossless":
        Image.fromarray(pixels, "RGBA").save(buffer, format="WEBP", lossless=True)
    else:
        Image.fromarray(pixels, "RGBA").save(buffer, format=kind.upper())
    return buffer.getvalue()


def _edit_member(payload: bytes, draw: Draw, sample: object) -> bytes:
    members = _members(payload)
    if not members:
        return payload
    name = draw.choice(sorted(members))
    action = draw.choice(["mutate", "mutate", "drop", "replace"])
    if action == "drop":
        del members[name]
    elif action == "replace":
        members[name] = _other_image(draw)
    else:
        members[name] = mutate_bytes(members[name], draw)
    return _zip(members)


def _lying_sizes(payload: bytes, draw: Draw, sample: object) -> bytes:
    """Patch a central-directory entry's uncompressed size (the CRC and the data stay): a bomb's claim."""
    at = payload.rfind(b"PK\x01\x02")
    if at < 0 or at + 28 > len(payload):
        return payload
    out = bytearray(payload)
    out[at + 24 : at + 28] = (draw.choice(HUGE_COUNTS) % 2**32).to_bytes(4, "little")
    return bytes(out)


SOG_MUTATIONS = [_edit_meta, _edit_meta, _edit_member, _lying_sizes]
