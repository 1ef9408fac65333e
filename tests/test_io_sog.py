"""PlayCanvas SOG: hand-made files decoded to values worked out from the specification, our writer's round trip
within the format's quantisation (bundle and folder), the CLI, and hostile files (each one line)."""

from __future__ import annotations

import io
import json
import zipfile
from pathlib import Path

import numpy as np
import pytest

from gstyle_core.cli import run
from gstyle_core.errors import SceneFormatError
from gstyle_core.io import load_scene, save_scene
from gstyle_core.io.lossless_image import encode_lossless_webp
from gstyle_core.io.ply_compressed_write import morton_order
from gstyle_core.io.sog_write import texture_size
from gstyle_core.scene import sigmoid
from tests.test_io_web_export import aligned, random_scene

S2 = np.sqrt(2.0)


def image(rows: list[list[int]], width: int = 2) -> np.ndarray:
    """uint8 [H, width, 4] from RGBA pixels in row-major order (zero padding)."""
    pixels = np.zeros((-(-len(rows) // width) * width, 4), np.uint8)
    pixels[: len(rows)] = rows
    return pixels.reshape(-1, width, 4)


def bundle(meta: object, images: dict[str, np.ndarray | bytes]) -> bytes:
    """A .sog of ``meta`` (JSON-encoded unless bytes) and ``images`` (pixels, or file bytes as they are)."""
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as archive:
        archive.writestr("meta.json", meta if isinstance(meta, bytes) else json.dumps(meta))
        for name, pixels in images.items():
            archive.writestr(name, pixels if isinstance(pixels, bytes) else encode_lossless_webp(pixels))
    return buffer.getvalue()


def write(tmp_path: Path, data: bytes, name: str = "s.sog") -> Path:
    (tmp_path / name).write_bytes(data)
    return tmp_path / name


# three Gaussians in 2 x 2 images (the fourth pixel is padding)
MEANS_L = image([[0, 255, 0, 255], [0x34, 0, 0xFF, 255], [0, 0, 0, 255]])
MEANS_U = image([[0, 255, 0x80, 255], [0x12, 0, 0xFF, 255], [0, 0, 0, 255]])
QUATS = image([[128, 128, 128, 253], [255, 128, 128, 255], [9, 9, 9, 7]])  # the last mode is reserved
SCALES = image([[0, 1, 2, 255], [2, 2, 2, 255], [1, 0, 1, 255]])
SH0 = image([[0, 1, 2, 0], [2, 1, 0, 128], [1, 1, 1, 255]])
LABELS = image([[1, 0, 0, 255], [0, 0, 0, 255], [5, 0, 0, 255]])  # 5 is past the palette of 2
CENTROIDS = np.zeros((1, 192, 4), np.uint8)  # 64 entries of 3 coefficients; entries 0 and 1 used
CENTROIDS[0, 0:3, :3] = [[0, 1, 2], [2, 1, 0], [1, 1, 1]]
CENTROIDS[0, 3:6, :3] = [[2, 2, 2], [0, 0, 0], [1, 2, 0]]
V2_META = {
    "version": 2, "count": 3, "antialias": False,
    "means": {"mins": [-1.0, 0.0, -2.0], "maxs": [2.0, 1.0, 2.0], "files": ["means_l.webp", "means_u.webp"]},
    "scales": {"codebook": [-5.0, -4.5, -3.25], "files": ["scales.webp"]},
    "quats": {"files": ["quats.webp"]},
    "sh0": {"codebook": [-1.5, 0.25, 2.0], "files": ["sh0.webp"]},
    "shN": {"count": 2, "bands": 1, "codebook": [-0.5, 0.125, 0.75],
            "files": ["shN_centroids.webp", "shN_labels.webp"]},
}
V2_IMAGES = {"means_l.webp": MEANS_L, "means_u.webp": MEANS_U, "quats.webp": QUATS, "scales.webp": SCALES,
             "sh0.webp": SH0, "shN_centroids.webp": CENTROIDS, "shN_labels.webp": LABELS}


def unlog(n: float) -> float:
    return float(np.sign(n) * (np.exp(abs(n)) - 1.0))


def test_version_2_decodes_every_field_as_specified(tmp_path):
    scene, report = load_scene(write(tmp_path, bundle(V2_META, V2_IMAGES)))
    assert report.format == "sog-v2 (bundle)" and scene.count == 3 and scene.sh_degree == 1
    # positions: q = low | high << 8 per axis, n = min + (max - min) q / 65535, x = sign(n) (e^|n| - 1)
    expected = [[unlog(-1.0), unlog(1.0), unlog(-2.0 + 4.0 * 0x8000 / 65535)],
                [unlog(-1.0 + 3.0 * 0x1234 / 65535), unlog(0.0), unlog(2.0)],
                [unlog(-1.0), 0.0, unlog(-2.0)]]
    np.testing.assert_allclose(scene.means, expected, rtol=1e-6)
    # rotations (w, x, y, z): mode 253 drops x; 255 drops z; stored components (v / 255 - 0.5) sqrt(2)
    c = (128 / 255 - 0.5) * S2
    hi = (1.0 - 0.5) * S2
    np.testing.assert_allclose(scene.quats[0], [c, np.sqrt(1 - 3 * c * c), c, c], atol=1e-7)
    np.testing.assert_allclose(scene.quats[1], [hi, c, c, np.sqrt(1 - hi**2 - 2 * c * c)], atol=1e-6)
    np.testing.assert_array_equal(scene.quats[2], [1, 0, 0, 0])  # reserved mode: identity, with a warning
    assert any("reserved mode" in w for w in report.warnings)
    np.testing.assert_array_equal(scene.log_scales, [[-5, -4.5, -3.25], [-3.25] * 3, [-4.5, -5, -4.5]])
    np.testing.assert_array_equal(scene.sh_dc, [[-1.5, 0.25, 2.0], [2.0, 0.25, -1.5], [0.25] * 3])
    np.testing.assert_allclose(scene.opacity_logits, [-40.0, np.log(128 / 127), 40.0], rtol=1e-6)
    # SH: label 1 -> entry 1 (pixels 3..5), label 0 -> entry 0; coefficient j of R, G, B in pixel j
    cb = np.array([-0.5, 0.125, 0.75], np.float32)
    np.testing.assert_array_equal(scene.sh_rest[0], cb[CENTROIDS[0, 3:6, :3]])
    np.testing.assert_array_equal(scene.sh_rest[1], cb[CENTROIDS[0, 0:3, :3]])
    np.testing.assert_array_equal(scene.sh_rest[2], 0.0)  # label past the palette: zeros, with a warning
    assert any("past the palette" in w for w in report.warnings)


def test_version_1_layout_decodes_its_lerps(tmp_path):
    meta = {
        "means": {"shape": [3, 3], "mins": V2_META["means"]["mins"], "maxs": V2_META["means"]["maxs"],
                  "files": ["means_l.webp", "means_u.webp"]},
        "scales": {"mins": [-6.0, -5.0, -4.0], "maxs": [-2.0, -1.0, 0.0], "files": ["scales.webp"]},
        "quats": {"files": ["quats.webp"]},
        "sh0": {"mins": [-1.0, -2.0, -3.0, -4.0], "maxs": [1.0, 2.0, 3.0, 4.0], "files": ["sh0.webp"]},
        "shN": {"mins": -1.0, "maxs": 1.0, "files": ["shN_centroids.webp", "shN_labels.webp"]},
    }
    scene, report = load_scene(write(tmp_path, bundle(meta, V2_IMAGES)))
    assert report.format == "sog-v1 (bundle)" and scene.count == 3 and scene.sh_degree == 1
    t = SCALES[..., :3].reshape(-1, 3)[:3] / 255.0
    np.testing.assert_allclose(scene.log_scales, np.array([-6.0, -5, -4]) + 4.0 * t, rtol=1e-6)
    rgba = SH0.reshape(-1, 4)[:3] / 255.0
    np.testing.assert_allclose(scene.sh_dc, np.array([-1.0, -2, -3]) + np.array([2.0, 4, 6]) * rgba[:, :3],
                               rtol=1e-6)
    np.testing.assert_allclose(scene.opacity_logits, -4.0 + 8.0 * rgba[:, 3], rtol=1e-6)  # a lerped logit
    np.testing.assert_allclose(scene.sh_rest[0], -1.0 + 2.0 * CENTROIDS[0, 3:6, :3] / 255.0, rtol=1e-6)


@pytest.mark.parametrize("degree", [0, 1, 3])
def test_round_trip_within_the_quantisation(tmp_path, degree):
    scene = random_scene(n=700, degree=degree)
    save_scene(scene, tmp_path / "s.sog")
    loaded, report = load_scene(tmp_path / "s.sog")
    assert report.format == "sog-v2 (bundle)" and loaded.count == 700 and loaded.sh_degree == degree
    ref = scene.subset(morton_order(scene.means))  # the writer stores Gaussians in Morton order
    meta = json.loads(zipfile.ZipFile(tmp_path / "s.sog").read("meta.json"))
    step = (np.array(meta["means"]["maxs"]) - np.array(meta["means"]["mins"])) / 65535  # log-domain step per axis
    bound = 0.5 * step * (np.abs(ref.means) + 1) * (1 + 1e-3) + 1e-6  # |dx| <= e^|n| dn = (|x| + 1) dn
    assert np.all(np.abs(loaded.means - ref.means) <= bound)
    q_loaded, q = aligned(loaded.quats, ref.quats)
    assert np.abs(q_loaded - q).max() <= 3 * 0.5 * S2 / 255 + 1e-6  # three stored within half a step, the rest
    for name, book in (("log_scales", "scales"), ("sh_dc", "sh0")):
        codebook = np.array(meta[book]["codebook"], np.float32)
        values = getattr(loaded, name)
        assert np.isin(values, codebook).all() and len(codebook) <= 256
        nearest = np.abs(getattr(ref, name)[..., None] - codebook).min(axis=-1)
        np.testing.assert_allclose(np.abs(values - getattr(ref, name)), nearest, atol=1e-6)  # the nearest entry
    assert np.abs(loaded.opacities - sigmoid(ref.opacity_logits)).max() <= 0.5 / 255 + 1e-6
    if degree:
        codebook = np.array(meta["shN"]["codebook"], np.float32)  # 700 distinct vectors: each its own entry
        assert meta["shN"]["count"] == 700 and meta["shN"]["bands"] == degree
        nearest = np.abs(ref.sh_rest[..., None] - codebook).min(axis=-1)
        np.testing.assert_allclose(np.abs(loaded.sh_rest - ref.sh_rest), nearest, atol=1e-6)


def test_few_distinct_values_are_kept_exactly(tmp_path):
    scene = random_scene(n=300, degree=2)
    scene.log_scales[:] = np.round(scene.log_scales * 8) / 8  # at most 49 distinct values
    scene.sh_dc[:] = np.round(scene.sh_dc * 16) / 16
    save_scene(scene, tmp_path / "s.sog")
    loaded, _ = load_scene(tmp_path / "s.sog")
    ref = scene.subset(morton_order(scene.means))
    np.testing.assert_array_equal(loaded.log_scales, ref.log_scales)
    np.testing.assert_array_equal(loaded.sh_dc, ref.sh_dc)


def test_folder_form_and_its_meta_json_load_alike(tmp_path):
    scene = random_scene(n=250, degree=1)
    save_scene(scene, tmp_path / "bundle.sog")
    save_scene(scene, tmp_path / "folder" / "meta.json")
    names = sorted(p.name for p in (tmp_path / "folder").iterdir())
    assert names == sorted(["meta.json", "means_l.webp", "means_u.webp", "quats.webp", "scales.webp", "sh0.webp",
                            "shN_centroids.webp", "shN_labels.webp"])
    packed, _ = load_scene(tmp_path / "bundle.sog")
    for target in (tmp_path / "folder", tmp_path / "folder" / "meta.json"):
        loaded, report = load_scene(target)
        assert report.format == "sog-v2 (folder)"
        for field in ("means", "quats", "log_scales", "opacity_logits", "sh_dc", "sh_rest"):
            np.testing.assert_array_equal(getattr(loaded, field), getattr(packed, field))


def test_a_png_image_is_read_and_any_member_order_works(tmp_path):
    images = dict(V2_IMAGES)
    from PIL import Image

    buffer = io.BytesIO()
    Image.fromarray(SCALES, "RGBA").save(buffer, format="PNG")
    images["scales.webp"] = buffer.getvalue()  # the names are arbitrary; any 8-bit RGBA-capable lossless format
    reordered = dict(reversed(list(images.items())))
    scene, _ = load_scene(write(tmp_path, bundle(V2_META, reordered)))
    np.testing.assert_array_equal(scene.log_scales[0], [-5, -4.5, -3.25])


def test_an_antialiased_scene_is_read_with_a_warning(tmp_path):
    for changes, word in (({"antialias": True}, "antialiased"), ({"model": "2dgs"}, "model '2dgs'")):
        _, report = load_scene(write(tmp_path, bundle({**V2_META, **changes}, V2_IMAGES), "aa.sog"))
        assert any(word in w and "plain 3DGS" in w for w in report.warnings), report.warnings


def test_sh_and_empty_scenes(tmp_path):
    save_scene(random_scene(n=40, degree=3), tmp_path / "nosh.sog", keep_sh=False)
    assert "shN" not in json.loads(zipfile.ZipFile(tmp_path / "nosh.sog").read("meta.json"))
    assert load_scene(tmp_path / "nosh.sog")[0].sh_degree == 0
    save_scene(random_scene(n=0, degree=0), tmp_path / "empty.sog")
    loaded, _ = load_scene(tmp_path / "empty.sog")
    assert loaded.count == 0 and texture_size(0) == (4, 4) and texture_size(1000) == (32, 32)


def test_a_scene_that_cannot_be_written_leaves_no_file(tmp_path):
    scene = random_scene(n=20, degree=0)
    scene.means[3] = np.nan
    with pytest.raises(SceneFormatError, match="not finite"):
        save_scene(scene, tmp_path / "bad.sog")
    with pytest.raises(SceneFormatError, match="not finite"):
        save_scene(scene, tmp_path / "folder" / "meta.json")
    assert list(tmp_path.rglob("*.*")) == []


# ---------------------------------------------------------------------------------------------------- CLI
def test_gstyle_info_and_convert(tmp_path, capsys):
    scene = random_scene(n=300, degree=1)
    save_scene(scene, tmp_path / "in.ply")
    assert run(["convert", str(tmp_path / "in.ply"), str(tmp_path / "out.sog")]) == 0
    assert run(["convert", str(tmp_path / "in.ply"), str(tmp_path / "web" / "meta.json")]) == 0
    assert run(["convert", str(tmp_path / "out.sog"), str(tmp_path / "back.ply")]) == 0
    capsys.readouterr()
    assert run(["info", str(tmp_path / "out.sog")]) == 0
    out = capsys.readouterr().out
    assert "sog-v2 (bundle)" in out and "300 loaded of 300" in out and "SH degree: 1" in out
    assert run(["info", str(tmp_path / "web")]) == 0 and "sog-v2 (folder)" in capsys.readouterr().out
    assert load_scene(tmp_path / "back.ply")[0].count == 300


# ------------------------------------------------------------------------------------------------ hostile
def _lossy(pixels: np.ndarray) -> bytes:
    from PIL import Image

    buffer = io.BytesIO()
    Image.fromarray(pixels, "RGBA").save(buffer, format="WEBP", quality=90)
    return buffer.getvalue()


def _zip_bomb(tmp_path: Path, mib: int) -> bytes:
    """meta.json and a means_l.webp member that inflates to ``mib`` MiB of zeros (about ``mib`` KiB in the file)."""
    path = tmp_path / "bomb.zip"
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as archive:
        archive.writestr("meta.json", json.dumps(V2_META))
        with archive.open("means_l.webp", "w", force_zip64=True) as member:
            chunk = bytes(1 << 20)
            for _ in range(mib):
                member.write(chunk)
    return path.read_bytes()


def _without(name: str) -> dict:
    return {k: v for k, v in V2_IMAGES.items() if k != name}


def _meta(**changes) -> dict:
    meta = json.loads(json.dumps(V2_META))
    for dotted, value in changes.items():
        node = meta
        *parents, last = dotted.split("__")
        for key in parents:
            node = node[key]
        node[last] = value
    return meta


HOSTILE = {
    "missing image": (lambda t: bundle(V2_META, _without("sh0.webp")), "sh0 (sh0.webp) is missing"),
    "count above the images": (lambda t: bundle(_meta(count=5), V2_IMAGES), "claims 5 Gaussians but means_l"),
    "lossy webp": (lambda t: bundle(V2_META, {**V2_IMAGES, "quats.webp": _lossy(QUATS)}), "lossy WebP"),
    "zip bomb past the size limit": (lambda t: _zip_bomb(t, 256), "unpacks to 268,435,456 bytes, more than"),
    "zip bomb by its ratio": (lambda t: _zip_bomb(t, 4), "a zip bomb"),
    "truncated zip": (lambda t: bundle(V2_META, V2_IMAGES)[:700], "not a readable .sog"),
    "meta not json": (lambda t: bundle(b'{"version": 2,', V2_IMAGES), "not JSON"),
    "meta not an object": (lambda t: bundle([1, 2], V2_IMAGES), "not a JSON object"),
    "meta lacks a field": (lambda t: bundle(_meta(means={"files": ["means_l.webp", "means_u.webp"]}), V2_IMAGES),
                           "lacks means.mins"),
    "codebook too short": (lambda t: bundle(_meta(scales__codebook=[1.0]), V2_IMAGES), "codebook has 1 entries"),
    "version 3": (lambda t: bundle(_meta(version=3), V2_IMAGES), "SOG version 3 is not supported"),
    "negative count": (lambda t: bundle(_meta(count=-1), V2_IMAGES), "not a whole number"),
    "name outside": (lambda t: bundle(_meta(sh0__files=["../sh0.webp"]), V2_IMAGES), "outside the scene's folder"),
    "images of two sizes": (lambda t: bundle(V2_META, {**V2_IMAGES, "scales.webp": image([[0, 0, 0, 0]] * 4, 4)}),
                            "the other images 2x2"),
    "image far larger than the scene": (lambda t: bundle(V2_META, {**V2_IMAGES,
                                                                    "means_l.webp": np.zeros((1100, 1024, 4),
                                                                                             np.uint8)}),
                                        "more than the"),
    "jpeg image": (lambda t: bundle(V2_META, {**V2_IMAGES, "sh0.webp": b"\xff\xd8\xff\xe0" + bytes(100)}),
                   "not a lossless WebP or PNG"),
    "centroids of the wrong width": (lambda t: bundle(V2_META, {**V2_IMAGES, "shN_centroids.webp": image([[0] * 4])}),
                                     "expected 192"),
}


@pytest.mark.parametrize("case", sorted(HOSTILE))
def test_hostile_files_get_one_line(tmp_path, capsys, case):
    make, message = HOSTILE[case]
    path = write(tmp_path, make(tmp_path), "hostile.sog")
    with pytest.raises(SceneFormatError, match=message.replace("(", r"\(").replace(")", r"\)")) as info:
        load_scene(path)
    assert "\n" not in str(info.value)
    assert run(["info", str(path)]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1 and err.startswith("gstyle info: error:"), err


def test_hostile_folder_forms(tmp_path):
    folder = tmp_path / "scene"
    folder.mkdir()
    (folder / "meta.json").write_text(json.dumps(V2_META))
    for name, pixels in _without("quats.webp").items():
        (folder / name).write_bytes(encode_lossless_webp(pixels))
    with pytest.raises(SceneFormatError, match=r"quats \(quats.webp\) is missing from"):
        load_scene(folder)
    (folder / "quats.webp").mkdir()  # a folder in an image's place
    with pytest.raises(SceneFormatError, match="is missing"):
        load_scene(folder / "meta.json")
    (tmp_path / "plain").mkdir()  # a folder without meta.json is not a scene
    with pytest.raises(SceneFormatError, match="is a directory"):
        load_scene(tmp_path / "plain")
