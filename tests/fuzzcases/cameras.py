"""Fuzz cases for ``load_cameras``: cameras.json, COLMAP text and binary, LLFF poses_bounds.npy, gsplat .npz.

Each case writes a small valid camera source into an empty folder (our ``save_cameras_json`` or small
encoders here), then mutates it: bytes, tokens and lines of text files, lying counts in binary files,
re-saved arrays of the wrong shape, type or value, deleted files and directories in place of files.
"""

from __future__ import annotations

import io
import json
import re
import shutil
import struct
import warnings
import zipfile
from pathlib import Path

import numpy as np

from gstyle_core.cameras import load_cameras, save_cameras_json
from gstyle_core.cameras.cameraset import SCENE_KINDS, CameraSet
from gstyle_core.errors import CameraFormatError
from tests.fuzzcases.common import HUGE_COUNTS, NASTY_FLOATS, Draw, FuzzFailure, mutate_bytes, rejected
from tests.synthetic import ring_cameras

CAMERA_FORMATS = ["cameras-json", "colmap-txt", "colmap-bin", "llff-npy", "gsplat-npz"]
JSON_TOKENS = ["NaN", "Infinity", "-Infinity", "1e400", "null", "true", '"x"', "[]", "{}", "-1", "0", "1e-320",
               "99999999999999999999999", "1" * 5000, "[" * 5000 + "]" * 5000, '"\\ud800"', "[1, 2]"]
TEXT_TOKENS = ["nan", "inf", "-1", "0", "1e400", "abc", "PINHOLE", "OPENCV", "99999999999999999999", "", "1.5",
               "#", "-0", "1e-320", "4294967296"]
COLMAP_MODELS = {"SIMPLE_PINHOLE": 3, "PINHOLE": 4, "SIMPLE_RADIAL": 4, "OPENCV": 8, "FULL_OPENCV": 12}
MODEL_IDS = {"SIMPLE_PINHOLE": 0, "PINHOLE": 1, "SIMPLE_RADIAL": 2, "OPENCV": 4, "FULL_OPENCV": 6}


def _rng(draw: Draw) -> np.random.Generator:
    return np.random.default_rng(draw.integer(0, 2**16))


def _colmap_model(draw: Draw) -> tuple[list, list, list]:
    """(cameras, images, points) of a small random COLMAP model."""
    rng = _rng(draw)
    cameras = []
    for cam_id in range(1, draw.integer(1, 2) + 1):
        model = draw.choice(sorted(COLMAP_MODELS))
        w, h = draw.integer(8, 64), draw.integer(8, 64)
        f = float(rng.uniform(20, 200))
        single = model.startswith("SIMPLE")
        params = ([f] if single else [f, f * 1.1]) + [w / 2, h / 2]
        params += list(rng.normal(0, 0.01, COLMAP_MODELS[model] - len(params)))
        cameras.append((cam_id, model, w, h, params))
    images = []
    for image_id in range(1, draw.integer(1, 4) + 1):
        q = rng.normal(size=4)
        images.append((image_id, q / np.linalg.norm(q), rng.normal(size=3), draw.integer(1, len(cameras)),
                       f"img_{image_id}.png", draw.integer(0, 3)))
    points = [(j + 1, rng.normal(size=3), rng.integers(0, 256, 3), draw.integer(0, 3))
              for j in range(draw.integer(0, 5))]
    return cameras, images, points


def _write_colmap_text(folder: Path, model: tuple[list, list, list]) -> None:
    cameras, images, points = model
    (folder / "cameras.txt").write_text("# cameras\n" + "".join(
        f"{c} {m} {w} {h} {' '.join(repr(float(v)) for v in p)}\n" for c, m, w, h, p in cameras))
    lines = ["# images"]
    for image_id, q, t, cam, name, n2d in images:
        lines.append(" ".join(map(str, [image_id, *q, *t, cam, name])))
        lines.append(" ".join(f"{1.5 * k} {2.5 * k} {k - 1}" for k in range(n2d)))
    (folder / "images.txt").write_text("\n".join(lines) + "\n")
    (folder / "points3D.txt").write_text("# points\n" + "".join(
        f"{j} {x} {y} {z} {r} {g} {b} 0.5" + " 1 0" * track + "\n" for j, (x, y, z), (r, g, b), track in points))


def _write_colmap_binary(folder: Path, model: tuple[list, list, list]) -> None:
    cameras, images, points = model
    data = struct.pack("<Q", len(cameras))
    for c, m, w, h, p in cameras:
        data += struct.pack("<iiQQ", c, MODEL_IDS[m], w, h) + struct.pack(f"<{len(p)}d", *p)
    (folder / "cameras.bin").write_bytes(data)
    data = struct.pack("<Q", len(images))
    for image_id, q, t, cam, name, n2d in images:
        data += struct.pack("<i7di", image_id, *q, *t, cam) + name.encode() + b"\0" + struct.pack("<Q", n2d)
        data += b"".join(struct.pack("<ddq", 1.5 * k, 2.5 * k, k - 1) for k in range(n2d))
    (folder / "images.bin").write_bytes(data)
    data = struct.pack("<Q", len(points))
    for j, xyz, rgb, track in points:
        data += struct.pack("<Q3d3BdQ", j, *xyz, *rgb, 0.5, track) + struct.pack("<ii", 1, 0) * track
    (folder / "points3D.bin").write_bytes(data)


def _llff_array(draw: Draw) -> np.ndarray:
    cams = ring_cameras(draw.integer(1, 5), width=draw.integer(8, 64), height=draw.integer(8, 64))
    rows = []
    for cam in cams:
        c2w = cam.cam_to_world
        right, down, forward, centre = c2w[:3, 0], c2w[:3, 1], c2w[:3, 2], c2w[:3, 3]
        pose = np.stack([down, right, -forward, centre, [cam.height, cam.width, cam.fx]], axis=1)
        rows.append(np.concatenate([pose.ravel(), [0.5, 20.0]]))
    return np.array(rows)


def _npz_arrays(draw: Draw) -> dict[str, np.ndarray]:
    width, height = draw.integer(8, 64), draw.integer(8, 64)
    cams = ring_cameras(draw.integer(1, 5), width=width, height=height)
    rng = _rng(draw)
    m = draw.integer(0, 6)
    return {"viewmats": np.stack([c.world_to_cam for c in cams]).astype(np.float32),
            "Ks": np.stack([c.K for c in cams]).astype(np.float32), "width": np.array(width),
            "height": np.array(height), "means3d": rng.normal(size=(m, 3)).astype(np.float32),
            "colors": rng.integers(0, 256, (m, 3), dtype=np.uint8)}


def _save_npz(path: Path, members: dict[str, np.ndarray | bytes], compressed: bool) -> None:
    """An .npz of arrays (or of raw .npy bytes, to keep a lying header)."""
    method = zipfile.ZIP_DEFLATED if compressed else zipfile.ZIP_STORED
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", method) as archive:
        for key, value in members.items():
            archive.writestr(key + ".npy", value if isinstance(value, bytes) else npy_bytes(value))
    path.write_bytes(buffer.getvalue())


def npy_bytes(array: np.ndarray) -> bytes:
    buffer = io.BytesIO()
    np.save(buffer, array, allow_pickle=array.dtype == object)
    return buffer.getvalue()


def npy_with_shape(data: bytes, shape: str) -> bytes:
    """.npy bytes whose header claims ``shape`` (e.g. "(100000000, 17)"); the data stays as it was."""
    start, end = data.find(b"'shape': ("), data.find(b")", data.find(b"'shape': ("))
    if start < 0 or end < 0 or data[6:8] != b"\x01\x00":
        return data
    (header_len,) = struct.unpack_from("<H", data, 8)
    opening = start + len(b"'shape': ")
    header = (data[10:opening] + shape.encode() + data[end + 1:10 + header_len]).rstrip(b" \n")
    if len(header) + 1 > header_len:
        return data
    return data[:10] + header.ljust(header_len - 1) + b"\n" + data[10 + header_len:]


def _lie_about_shape(data: bytes, draw: Draw) -> bytes:
    """A .npy whose header claims another (mostly much larger) shape."""
    rows = draw.choice([n for n in HUGE_COUNTS if n < 2**63] + [-1])
    return npy_with_shape(data, draw.choice([f"({rows}, 17)", f"({rows}, 4, 4)", f"({rows},)", "()",
                                             f"({rows}, {rows})"]))


def _array_variant(arr: np.ndarray, draw: Draw) -> np.ndarray:
    """The same array with a wrong shape, type or value."""
    rng = _rng(draw)
    kind = draw.choice(["nan", "scale", "garbage", "shape", "dtype", "empty", "object", "zero"])
    out = np.array(arr, copy=True)
    if kind == "nan" and out.size:
        out = out.astype(np.float64)
        out.flat[draw.integer(0, out.size - 1)] = draw.choice(NASTY_FLOATS)
    elif kind == "scale" and out.dtype.kind in "fiu":
        with np.errstate(all="ignore"):
            out = out.astype(np.float64) * draw.choice([0, -1, 1e-300, 1e300, 2**31])
    elif kind == "garbage" and out.dtype.kind == "f":
        out = rng.normal(0, draw.choice([1.0, 1e6]), out.shape).astype(out.dtype)
    elif kind == "shape":
        out = out.reshape(-1) if out.ndim > 1 else np.stack([out, out])
    elif kind == "dtype":
        with np.errstate(all="ignore"):
            out = out.astype(draw.choice([np.int32, np.bool_, np.complex64, "<U3", "S2", np.float16]))
    elif kind == "empty":
        out = out[:0] if out.ndim else np.zeros(0)
    elif kind == "object":
        out = np.array([None, "x"], dtype=object)
    elif kind == "zero" and out.size:
        out.flat[draw.integer(0, out.size - 1)] = 0
    return out


def write_valid_cameras(fmt: str, draw: Draw, folder: Path) -> Path:
    """Write a valid source of format ``fmt`` into ``folder``; return the path to load."""
    if fmt == "cameras-json":
        cams = ring_cameras(draw.integer(1, 5), width=draw.integer(8, 64), height=draw.integer(8, 64))
        save_cameras_json(cams, folder / "cameras.json")
        return draw.choice([folder / "cameras.json", folder])
    if fmt in ("colmap-txt", "colmap-bin"):
        model_dir = folder / "sparse" / "0"
        model_dir.mkdir(parents=True)
        (_write_colmap_text if fmt == "colmap-txt" else _write_colmap_binary)(model_dir, _colmap_model(draw))
        ext = ".txt" if fmt == "colmap-txt" else ".bin"
        return draw.choice([folder, folder / "sparse", model_dir, model_dir / f"images{ext}"])
    if fmt == "llff-npy":
        (folder / "poses_bounds.npy").write_bytes(npy_bytes(_llff_array(draw)))
        return draw.choice([folder, folder / "poses_bounds.npy"])
    _save_npz(folder / "scene.npz", _npz_arrays(draw), draw.choice([False, True]))
    return folder / "scene.npz"


# --- mutations ---------------------------------------------------------------------------------------


def _replace_token(path: Path, draw: Draw) -> None:
    text = path.read_bytes().decode("utf-8", "replace")
    spans = [m.span() for m in re.finditer(r"[^\s,\[\]{}:]+", text)]
    if spans:
        a, b = draw.choice(spans)
        token = draw.choice(JSON_TOKENS if path.suffix == ".json" else TEXT_TOKENS)
        path.write_text(text[:a] + token + text[b:], encoding="utf-8", errors="replace")


def _edit_lines(path: Path, draw: Draw) -> None:
    lines = path.read_bytes().decode("utf-8", "replace").split("\n")
    i = draw.integer(0, len(lines) - 1)
    lines[i:i + 1] = draw.choice([[], [lines[i], lines[i]], [""], [lines[i][: len(lines[i]) // 2]]])
    path.write_text("\n".join(lines), encoding="utf-8", errors="replace")


def _lie_in_binary(path: Path, draw: Draw) -> None:
    data = bytearray(path.read_bytes())
    if len(data) < 8:
        return
    offset = draw.choice([0, 8 * draw.integer(0, (len(data) - 8) // 8), draw.integer(0, len(data) - 8)])
    code = draw.choice(["<Q", "<i", "<d"])
    value = draw.choice(NASTY_FLOATS) if code == "<d" else draw.choice(HUGE_COUNTS) % (2**64 if code == "<Q" else 2**31)
    struct.pack_into(code, data, offset, value)
    path.write_bytes(bytes(data))


def _resave_array(path: Path, draw: Draw) -> None:
    if path.suffix == ".npy":  # the valid file we wrote (this runs before any byte mutation)
        array = np.load(path)
    else:
        with np.load(path) as data:
            arrays: dict[str, np.ndarray | bytes] = {k: data[k] for k in data.files}
    lie = draw.integer(0, 2) == 0
    if path.suffix == ".npy":
        path.write_bytes(_lie_about_shape(npy_bytes(array), draw) if lie else npy_bytes(_array_variant(array, draw)))
        return
    key = draw.choice(sorted(arrays))
    if draw.integer(0, 3) == 0:
        del arrays[key]
    elif lie:
        arrays[key] = _lie_about_shape(npy_bytes(arrays[key]), draw)
    else:
        arrays[key] = _array_variant(arrays[key], draw)
    _save_npz(path, arrays, draw.choice([False, True]))


def _replace_file(path: Path, draw: Draw) -> None:
    path.unlink()
    what = draw.choice(["missing", "empty", "directory"])
    if what == "empty":
        path.write_bytes(b"")
    elif what == "directory":
        path.mkdir()


def _mutate_file(path: Path, draw: Draw) -> None:
    ops = [lambda p, d: p.write_bytes(mutate_bytes(p.read_bytes(), d)), _replace_file]
    if path.suffix in (".json", ".txt"):
        ops += [_replace_token, _replace_token, _edit_lines]
    if path.suffix == ".bin":
        ops += [_lie_in_binary, _lie_in_binary]
    draw.choice(ops)(path, draw)


def write_camera_case(fmt: str, draw: Draw, folder: Path) -> Path:
    """Write a mutated camera source of format ``fmt`` into the empty ``folder``; return the path to load."""
    target = write_valid_cameras(fmt, draw, folder)
    arrays = sorted(folder.glob("*.np[yz]"))
    resaved = bool(arrays) and draw.integer(0, 2) > 0
    if resaved:
        _resave_array(arrays[0], draw)
    for _ in range(draw.integer(0 if resaved else 1, 3)):
        files = sorted(p for p in folder.rglob("*") if p.is_file())
        if not files:
            break
        _mutate_file(draw.choice(files), draw)
    if draw.integer(0, 29) == 0:
        shutil.rmtree(folder)
        folder.mkdir()
    return target


# --- the property ------------------------------------------------------------------------------------


def check_cameraset(cs: CameraSet) -> None:
    """Raise FuzzFailure unless every camera is usable: sizes, focal lengths, a rigid finite pose."""
    if not len(cs) or cs.kind not in SCENE_KINDS:
        raise FuzzFailure(f"{len(cs)} cameras of kind {cs.kind!r}")
    for cam in cs:
        if not (isinstance(cam.width, int) and isinstance(cam.height, int) and cam.width >= 1 and cam.height >= 1):
            raise FuzzFailure(f"camera {cam.name}: size {cam.width!r}x{cam.height!r}")
        if not (np.isfinite([cam.fx, cam.fy, cam.cx, cam.cy]).all() and cam.fx > 0 and cam.fy > 0):
            raise FuzzFailure(f"camera {cam.name}: intrinsics {cam.fx, cam.fy, cam.cx, cam.cy}")
        w2c = np.asarray(cam.world_to_cam)
        if w2c.shape != (4, 4) or not np.isfinite(w2c).all() or not np.allclose(w2c[3], [0, 0, 0, 1]):
            raise FuzzFailure(f"camera {cam.name}: world_to_cam {w2c.tolist()}")
        rot = w2c[:3, :3]
        if not np.allclose(rot @ rot.T, np.eye(3), atol=1e-2) or np.linalg.det(rot) <= 0:
            raise FuzzFailure(f"camera {cam.name}: not a rotation {rot.tolist()}")
        if not (np.isfinite(cam.position).all() and np.isfinite(cam.forward).all()):
            raise FuzzFailure(f"camera {cam.name}: non-finite centre or direction")
    if cs.points is not None:
        pts, cols = np.asarray(cs.points), cs.point_colors
        if pts.ndim != 2 or pts.shape[1] != 3 or not np.isfinite(pts).all():
            raise FuzzFailure(f"points: shape {pts.shape}")
        if cols is not None and (np.shape(cols) != pts.shape or not (np.min(cols, initial=0) >= 0
                                                                     and np.max(cols, initial=0) <= 1)):
            raise FuzzFailure(f"point colours: shape {np.shape(cols)}")
    for bound in (cs.near, cs.far):
        if bound is not None and not np.isfinite(bound):
            raise FuzzFailure(f"non-finite near/far {cs.near}, {cs.far}")


def check_camera_source(target: Path) -> str:
    """Load cameras from ``target``: "ok" for usable cameras, "error" for a one-line CameraFormatError."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            cs = load_cameras(target)
    except CameraFormatError as exc:
        return rejected(exc)
    check_cameraset(cs)
    json.dumps([c.name for c in cs])  # names are plain strings
    return "ok"
