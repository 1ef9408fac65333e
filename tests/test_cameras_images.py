"""Ground-truth image loading and CameraSet helpers (split, scaling, loading images with cameras)."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from gstyle_core.cameras import Camera, CameraSet, image_size, load_image, resize_image
from gstyle_core.errors import CameraFormatError, StyleImageError


def test_rgb_png_exact(tmp_path):
    arr = np.random.default_rng(0).integers(0, 256, size=(7, 9, 3), dtype=np.uint8)
    Image.fromarray(arr).save(tmp_path / "a.png")
    img = load_image(tmp_path / "a.png")
    assert img.dtype == np.float32 and img.shape == (7, 9, 3)
    np.testing.assert_allclose(img, arr / 255.0, atol=1e-7)
    assert image_size(tmp_path / "a.png") == (9, 7)


def test_rgba_composited_on_black_by_default_or_white(tmp_path):
    rgba = np.zeros((2, 2, 4), np.uint8)
    rgba[..., 0] = 200
    rgba[..., 3] = [[255, 0], [51, 255]]
    Image.fromarray(rgba, "RGBA").save(tmp_path / "a.png")
    black = load_image(tmp_path / "a.png")
    np.testing.assert_allclose(black[..., 0], [[200 / 255, 0], [200 / 255 * 0.2, 200 / 255]], atol=1e-6)
    white = load_image(tmp_path / "a.png", background=1.0)
    np.testing.assert_allclose(white[0, 1], [1, 1, 1], atol=1e-6)
    np.testing.assert_allclose(white[1, 0, 1], 0.8, atol=1e-6)
    Image.fromarray(rgba[..., [0, 3]], "LA").save(tmp_path / "la.png")
    np.testing.assert_allclose(load_image(tmp_path / "la.png")[0, 1], [0, 0, 0], atol=1e-6)


def test_grey_and_16_bit(tmp_path):
    Image.fromarray(np.full((3, 4), 51, np.uint8), "L").save(tmp_path / "g.png")
    np.testing.assert_allclose(load_image(tmp_path / "g.png"), np.full((3, 4, 3), 0.2), atol=1e-6)
    grey16 = np.array([[0, 65535], [32768, 1000]], np.uint16)
    Image.fromarray(grey16).save(tmp_path / "g16.png")
    img = load_image(tmp_path / "g16.png")
    np.testing.assert_allclose(img[..., 2], grey16 / 65535.0, atol=1e-6)
    Image.fromarray(np.array([[0.25, 2.0]], np.float32), "F").save(tmp_path / "f.tif")
    np.testing.assert_allclose(load_image(tmp_path / "f.tif")[0, :, 0], [0.25, 1.0], atol=1e-6)
    pal = Image.new("P", (2, 1))
    pal.putpalette([0, 0, 0, 255, 128, 0] + [0] * 762)
    pal.putdata([0, 1])
    pal.save(tmp_path / "p.png")
    np.testing.assert_allclose(load_image(tmp_path / "p.png")[0, 1], [1, 128 / 255, 0], atol=1e-6)


def test_exif_orientation(tmp_path):
    arr = np.zeros((2, 4, 3), np.uint8)
    arr[0, 0] = 255  # top-left red marker of a 4x2 image
    img = Image.fromarray(arr)
    exif = img.getexif()
    exif[0x0112] = 6  # "rotate 90° clockwise to display"
    img.save(tmp_path / "r.jpg", exif=exif, quality=100)
    upright = load_image(tmp_path / "r.jpg")
    assert upright.shape == (4, 2, 3)
    assert upright[0, 1, 0] > 0.5  # the marker moved to the top-right corner
    raw = load_image(tmp_path / "r.jpg", exif_orientation=False)
    assert raw.shape == (2, 4, 3) and raw[0, 0, 0] > 0.5
    assert image_size(tmp_path / "r.jpg") == (4, 2)
    assert image_size(tmp_path / "r.jpg", exif_orientation=True) == (2, 4)


def test_resize_and_errors(tmp_path):
    Image.new("RGB", (40, 20), (255, 0, 0)).save(tmp_path / "a.png")
    small = load_image(tmp_path / "a.png", size=(10, 5))
    assert small.shape == (5, 10, 3)
    np.testing.assert_allclose(small[..., 0], 1.0, atol=1e-5)
    np.testing.assert_allclose(small[..., 1:], 0.0, atol=1e-5)
    with pytest.raises(ValueError, match="positive"):
        resize_image(small, (0, 3))
    (tmp_path / "bad.png").write_bytes(b"\x89PNG not really")
    with pytest.raises(CameraFormatError, match="cannot read image bad.png") as info:
        load_image(tmp_path / "bad.png")
    assert "\n" not in str(info.value)
    with pytest.raises(StyleImageError, match="cannot read image missing.jpg"):
        load_image(tmp_path / "missing.jpg", error=StyleImageError)
    with pytest.raises(CameraFormatError):
        image_size(tmp_path / "bad.png")
    data = (tmp_path / "a.png").read_bytes()
    (tmp_path / "cut.png").write_bytes(data[: len(data) // 2])
    with pytest.raises(CameraFormatError, match="cut.png"):
        load_image(tmp_path / "cut.png")


def make_set(tmp_path, n=10, width=64, height=48) -> CameraSet:
    cams = []
    for i in range(n):
        path = tmp_path / f"{i:02d}.png"
        Image.new("RGB", (width, height), (i * 20, 0, 0)).save(path)
        w2c = np.eye(4)
        w2c[0, 3] = i
        cams.append(Camera(width, height, 60.0, 60.0, 32.0, 24.0, w2c, f"{i:02d}", path))
    return CameraSet(cams, "forward", str(tmp_path), points=np.zeros((1, 3), np.float32), near=1.0, far=9.0)


def test_split_train_test(tmp_path):
    cs = make_set(tmp_path, n=17)
    train, test = cs.split_train_test()
    assert [c.name for c in test] == ["00", "08", "16"]
    assert len(train) == 14 and "08" not in [c.name for c in train]
    assert train.kind == test.kind == "forward" and test.near == 1.0 and test.points is cs.points
    train3, test3 = cs.split_train_test(every=3)
    assert len(test3) == 6 and len(train3) == 11
    lone_train, lone_test = cs.with_cameras(cs.cameras[:1]).split_train_test()
    assert len(lone_train) == 1 and len(lone_test) == 0
    with pytest.raises(ValueError, match="every must be >= 2"):
        cs.split_train_test(every=1)


def test_scaling_and_loading_images_match(tmp_path):
    cs = make_set(tmp_path, n=3)
    assert cs.has_images and len(cs) == 3 and cs[1].name == "01"
    half = cs.scaled_to_width(32)
    assert (half[0].width, half[0].height, half[0].fx, half[0].cx, half[0].cy) == (32, 24, 30.0, 16.0, 12.0)
    np.testing.assert_allclose(half[2].world_to_cam, cs[2].world_to_cam)
    assert cs.scaled_to_width(128, only_shrink=True)[0].width == 64
    assert cs.scaled_to_width(128)[0].width == 128
    full = cs.load_images()
    assert full[2].shape == (48, 64, 3) and full[2][0, 0, 0] == pytest.approx(40 / 255)
    small_cams, small_imgs = cs.with_images(max_width=16)
    assert [im.shape for im in small_imgs] == [(c.height, c.width, 3) for c in small_cams]
    assert [im.shape for im in small_imgs] == [(12, 16, 3)] * 3
    assert [im.shape for im in cs.load_images(max_width=16)] == [(12, 16, 3)] * 3
    cs.cameras[1].image_path = None
    assert not cs.has_images
    with pytest.raises(CameraFormatError, match="camera 01 has no ground-truth image"):
        cs.load_images()
    with pytest.raises(ValueError, match="scene kind"):
        CameraSet([], "sideways", "x")
    assert not CameraSet([], "360", "x").has_images
