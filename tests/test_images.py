"""Style image loading: modes, orientation, sizes, guards and errors."""

from __future__ import annotations

import struct
import tracemalloc
import warnings
import zlib
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from gstyle_core.errors import StyleImageError
from gstyle_core.images import UniformStyleWarning, load_style_image

SHARED_STYLES = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "styles"


def _gradient_rgb(w: int = 96, h: int = 72) -> np.ndarray:
    x = np.linspace(0, 255, w, dtype=np.float32)[None, :].repeat(h, 0)
    y = np.linspace(0, 255, h, dtype=np.float32)[:, None].repeat(w, 1)
    return np.stack([x, y, 255 - x], axis=2).astype(np.uint8)


def _load_quiet(path: Path, **kwargs) -> np.ndarray:
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no spurious warnings for ordinary images
        return load_style_image(path, **kwargs)


def test_rgb_png_roundtrip(tmp_path):
    pixels = _gradient_rgb()
    Image.fromarray(pixels).save(tmp_path / "a.png")
    img = _load_quiet(tmp_path / "a.png")
    assert img.dtype == np.float32 and img.shape == (72, 96, 3) and img.flags.c_contiguous
    np.testing.assert_allclose(img, pixels / 255.0, atol=1e-6)


def test_greyscale_and_palette(tmp_path):
    grey = _gradient_rgb()[..., 0]
    Image.fromarray(grey, mode="L").save(tmp_path / "g.png")
    img = _load_quiet(tmp_path / "g.png")
    assert img.shape == (72, 96, 3)
    np.testing.assert_allclose(img[..., 1], grey / 255.0, atol=1e-6)
    Image.fromarray(_gradient_rgb()).convert("P", palette=Image.Palette.ADAPTIVE, colors=16).save(tmp_path / "p.png")
    pal = _load_quiet(tmp_path / "p.png")
    assert pal.shape == (72, 96, 3) and np.abs(pal - _gradient_rgb() / 255.0).mean() < 0.1


def test_rgba_is_composited_on_white(tmp_path):
    rgba = np.zeros((70, 70, 4), np.uint8)
    rgba[..., 0] = 255  # red
    rgba[:, :35, 3] = 255  # left half opaque, right half fully transparent
    rgba[:, 35:, 3] = 0
    Image.fromarray(rgba, mode="RGBA").save(tmp_path / "t.png")
    img = _load_quiet(tmp_path / "t.png")
    np.testing.assert_allclose(img[10, 10], [1, 0, 0], atol=1e-6)
    np.testing.assert_allclose(img[10, 60], [1, 1, 1], atol=1e-6)


def test_palette_with_transparency(tmp_path):
    image = Image.new("P", (64, 64), 0)
    image.putpalette([0, 0, 255] + [0, 0, 0] * 255)
    image.paste(1, (0, 0, 32, 64))
    image.info["transparency"] = 1
    image.save(tmp_path / "pt.png", transparency=1)
    img = _load_quiet(tmp_path / "pt.png")
    np.testing.assert_allclose(img[5, 5], [1, 1, 1], atol=1e-6)
    np.testing.assert_allclose(img[5, 50], [0, 0, 1], atol=1e-6)


def test_16_bit_greyscale_keeps_precision(tmp_path):
    values = np.linspace(0, 65535, 64 * 64).reshape(64, 64).astype(np.uint16)
    Image.fromarray(values).save(tmp_path / "g16.png")
    img = _load_quiet(tmp_path / "g16.png")
    np.testing.assert_allclose(img[..., 0], values / 65535.0, atol=1e-6)
    assert len(np.unique(img[..., 0])) > 256  # more than 8 bits survived


def test_cmyk_jpeg(tmp_path):
    Image.new("CMYK", (80, 64), (0, 255, 255, 0)).save(tmp_path / "c.jpg", quality=95)  # pure red in CMYK
    with pytest.warns(UniformStyleWarning):
        img = load_style_image(tmp_path / "c.jpg")
    assert img.shape == (64, 80, 3)
    assert img[..., 0].mean() > 0.9 and img[..., 1].mean() < 0.1 and img[..., 2].mean() < 0.1


def test_exif_rotation_is_applied(tmp_path):
    pixels = _gradient_rgb(96, 64)
    exif = Image.Exif()
    exif[0x0112] = 6  # rotate 90° clockwise to display
    Image.fromarray(pixels).save(tmp_path / "r.jpg", exif=exif, quality=95)
    img = _load_quiet(tmp_path / "r.jpg")
    assert img.shape == (96, 64, 3)
    expected = np.rot90(pixels, k=-1) / 255.0
    assert np.abs(img - expected).mean() < 0.03


def test_tiny_images_are_upscaled(tmp_path):
    Image.new("RGB", (1, 1), (10, 200, 30)).save(tmp_path / "one.png")
    with pytest.warns(UniformStyleWarning, match="single colour"):
        img = load_style_image(tmp_path / "one.png", min_side=64)
    assert img.shape == (64, 64, 3)
    np.testing.assert_allclose(img[0, 0], np.array([10, 200, 30]) / 255.0, atol=1e-5)
    Image.fromarray(_gradient_rgb(40, 3)).save(tmp_path / "thin.png")
    thin = _load_quiet(tmp_path / "thin.png", min_side=64, max_side=512)
    assert min(thin.shape[:2]) == 64 and max(thin.shape[:2]) <= 512
    assert np.isfinite(thin).all() and thin.min() >= 0 and thin.max() <= 1


def test_extreme_aspect_is_centre_cropped(tmp_path):
    Image.fromarray(_gradient_rgb(2000, 2)).save(tmp_path / "line.png")
    img = _load_quiet(tmp_path / "line.png", min_side=64, max_side=256)
    assert img.shape == (64, 256, 3)


def test_large_images_are_downscaled(tmp_path):
    Image.fromarray(_gradient_rgb(900, 300)).save(tmp_path / "big.png")
    img = _load_quiet(tmp_path / "big.png", max_side=300)
    assert img.shape == (100, 300, 3)
    np.testing.assert_allclose(img[50, 150], _gradient_rgb(900, 300)[150, 450] / 255.0, atol=0.02)


def _png_header_only(width: int, height: int) -> bytes:
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(b"\0" * 16)) + chunk(b"IEND", b"")


def test_decompression_bomb_is_refused(tmp_path):
    (tmp_path / "bomb.png").write_bytes(_png_header_only(60000, 60000))
    with pytest.raises(StyleImageError) as info:
        load_style_image(tmp_path / "bomb.png")
    assert "\n" not in str(info.value)
    Image.fromarray(_gradient_rgb(100, 100)).save(tmp_path / "small.png")
    with pytest.raises(StyleImageError, match="decompression-bomb"):
        load_style_image(tmp_path / "small.png", max_pixels=5000)


def test_corrupt_truncated_and_non_images(tmp_path):
    Image.fromarray(_gradient_rgb(200, 200)).save(tmp_path / "full.jpg", quality=90)
    data = (tmp_path / "full.jpg").read_bytes()
    (tmp_path / "cut.jpg").write_bytes(data[: len(data) // 3])
    (tmp_path / "text.png").write_text("hello, not an image")
    (tmp_path / "empty.png").write_bytes(b"")
    png = (tmp_path / "full.png")
    Image.fromarray(_gradient_rgb(200, 200)).save(png)
    (tmp_path / "cut.png").write_bytes(png.read_bytes()[:300])
    for name in ("cut.jpg", "text.png", "empty.png", "cut.png", "missing.png"):
        with pytest.raises(StyleImageError) as info:
            load_style_image(tmp_path / name)
        assert "\n" not in str(info.value), name
    with pytest.raises(StyleImageError, match="not a file"):
        load_style_image(tmp_path)


def test_uniform_colour_warns_but_works(tmp_path):
    Image.new("RGB", (100, 80), (128, 64, 32)).save(tmp_path / "u.png")
    with pytest.warns(UniformStyleWarning):
        img = load_style_image(tmp_path / "u.png")
    np.testing.assert_allclose(img.reshape(-1, 3).mean(0, dtype=np.float64), [128 / 255, 64 / 255, 32 / 255], atol=1e-6)


def test_shared_styles_load():
    if not SHARED_STYLES.is_dir():
        pytest.skip(f"shared test data not found at {SHARED_STYLES}")
    files = sorted(p for p in SHARED_STYLES.iterdir() if p.suffix.lower() in (".jpg", ".png"))[:3]
    for file in files:
        img = _load_quiet(file, max_side=256)
        assert max(img.shape[:2]) == 256 and img.min() >= 0 and img.max() <= 1


def test_more_modes_la_one_bit_float_and_48_bit(tmp_path):
    grey = _gradient_rgb()[..., 0]
    Image.fromarray(np.stack([grey, np.full_like(grey, 255)], axis=2), mode="LA").save(tmp_path / "la.png")
    np.testing.assert_allclose(_load_quiet(tmp_path / "la.png")[..., 2], grey / 255.0, atol=1e-6)
    Image.fromarray(grey > 127).save(tmp_path / "bit.png")  # mode "1"
    assert set(np.unique(_load_quiet(tmp_path / "bit.png"))) == {0.0, 1.0}
    ramp = np.linspace(-0.5, 1.5, 72 * 96, dtype=np.float32).reshape(72, 96)
    Image.fromarray(ramp, mode="F").save(tmp_path / "f.tif")
    np.testing.assert_allclose(_load_quiet(tmp_path / "f.tif")[..., 0], np.clip(ramp, 0, 1), atol=1e-6)
    Image.fromarray(grey.astype(np.uint16) * 257).save(tmp_path / "g16.tif")  # 16-bit TIFF
    np.testing.assert_allclose(_load_quiet(tmp_path / "g16.tif")[..., 0], grey / 255.0, atol=1e-6)
    rows = np.zeros((64, 64, 3), ">u2")
    rows[..., 0] = np.linspace(0, 65535, 64, dtype=np.uint16)[None]
    raw = b"".join(b"\0" + row.tobytes() for row in rows)  # 48-bit RGB PNG (Pillow reads it as 8-bit RGB)

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    ihdr = chunk(b"IHDR", struct.pack(">IIBBBBB", 64, 64, 16, 2, 0, 0, 0))
    png = b"\x89PNG\r\n\x1a\n" + ihdr + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b"")
    (tmp_path / "rgb48.png").write_bytes(png)
    img = _load_quiet(tmp_path / "rgb48.png")
    np.testing.assert_allclose(img[0, :, 0], np.linspace(0, 1, 64), atol=1 / 255)


def test_animated_gif_uses_the_first_frame(tmp_path):
    frames = [Image.fromarray(_gradient_rgb()), Image.new("RGB", (96, 72), (0, 0, 255))]
    frames[0].save(tmp_path / "anim.gif", save_all=True, append_images=frames[1:])
    img = _load_quiet(tmp_path / "anim.gif")
    assert img.shape == (72, 96, 3) and np.abs(img - _gradient_rgb() / 255.0).mean() < 0.05


@pytest.mark.parametrize("orientation, turns", [(1, 0), (3, 2), (8, 1), (0, 0), (9, 0)])
def test_exif_orientations_including_invalid_values(tmp_path, orientation, turns):
    pixels = _gradient_rgb(96, 64)
    exif = Image.Exif()
    exif[0x0112] = orientation  # 0 and 9 are not valid orientations: the image is used as stored
    Image.fromarray(pixels).save(tmp_path / "o.jpg", exif=exif, quality=95)
    img = _load_quiet(tmp_path / "o.jpg")
    expected = np.rot90(pixels, k=turns) / 255.0
    assert img.shape == expected.shape and np.abs(img - expected).mean() < 0.03


def test_our_pixel_limit_governs_not_pillows_warning(tmp_path, monkeypatch):
    Image.fromarray(_gradient_rgb(40, 40)).save(tmp_path / "a.png")  # 1,600 pixels
    monkeypatch.setattr(Image, "MAX_IMAGE_PIXELS", 1000)  # Pillow warns above 1,000 and refuses above 2,000
    assert _load_quiet(tmp_path / "a.png", min_side=8).shape == (40, 40, 3)
    with pytest.raises(StyleImageError, match="decompression-bomb"):
        load_style_image(tmp_path / "a.png", max_pixels=1500)
    Image.fromarray(_gradient_rgb(50, 50)).save(tmp_path / "b.png")  # 2,500 pixels: Pillow's hard limit
    with pytest.raises(StyleImageError, match="too large"):
        load_style_image(tmp_path / "b.png")


def test_png_chunk_claiming_gigabytes_is_not_allocated(tmp_path):
    Image.fromarray(_gradient_rgb(20, 20)).save(tmp_path / "ok.png")
    data = bytearray((tmp_path / "ok.png").read_bytes())
    idat = data.index(b"IDAT")
    struct.pack_into(">I", data, idat - 4, 3_858_759_899)  # Pillow skipped it with fp.read(3.8 GB)
    for cut in (len(data), len(data) - 20):  # complete (decodes) and cut inside IDAT (an error)
        (tmp_path / "lie.png").write_bytes(bytes(data[:cut]))
        tracemalloc.start()
        try:
            try:
                assert load_style_image(tmp_path / "lie.png", min_side=8).shape == (20, 20, 3)
            except StyleImageError:
                assert cut < len(data)
            peak = tracemalloc.get_traced_memory()[1]
        finally:
            tracemalloc.stop()
        assert peak < 16 << 20, f"{peak:,} bytes"


def test_files_larger_than_any_image_of_the_pixel_limit_are_refused(tmp_path):
    (tmp_path / "big.png").write_bytes(b"\x89PNG" + bytes(17 << 20))  # over 8 x 100 + 16 MiB
    with pytest.raises(StyleImageError, match="8 bytes per pixel"):
        load_style_image(tmp_path / "big.png", max_pixels=100)


def test_png_with_a_short_ihdr_chunk(tmp_path):
    Image.fromarray(_gradient_rgb(30, 19)).save(tmp_path / "ok.png")
    data = bytearray((tmp_path / "ok.png").read_bytes())
    data[8:12] = struct.pack(">I", 11)  # IHDR claims 11 bytes: Pillow raised a bare ValueError
    (tmp_path / "short.png").write_bytes(bytes(data))
    with pytest.raises(StyleImageError, match="Truncated IHDR"):
        load_style_image(tmp_path / "short.png")
