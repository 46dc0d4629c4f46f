"""The pictures a C-arm workstation or a frame grabber writes, found by their content: BMP
(8-bit palette and 24-bit screen captures), GIF, WebP (lossless, lossy, animated) and the TIFF
variants Pillow writes (palette, bilevel, CMYK, MinIsWhite, LZW / Deflate / PackBits / JPEG).
A grey picture comes back exactly; a colour one as Rec. 709 grey of the colours Pillow reads;
a screen capture of a radiograph tracks to the pose its PNG gives."""

from __future__ import annotations

import json

import numpy as np
import pytest
import tifffile
from images_support import CAM
from PIL import Image

from ftrac_design.cli.main import main
from ftrac_design.errors import InputError
from ftrac_design.images import frame_count, read_frames
from ftrac_design.images.sniff import content_format

REC709 = np.array([0.2126, 0.7152, 0.0722])
GREY = np.random.default_rng(0).integers(0, 256, (40, 50)).astype(np.uint8)
RGB = np.random.default_rng(1).integers(0, 256, (40, 50, 3)).astype(np.uint8)


def _only(path):
    frames = list(read_frames(path, need_camera=False))
    assert len(frames) == 1
    return frames[0]


GREY_WRITERS = {
    "bmp 8-bit palette": ("bmp", lambda p: Image.fromarray(GREY).convert("P").save(p, format="BMP")),
    "bmp 24-bit": ("bmp", lambda p: Image.fromarray(np.dstack([GREY] * 3)).save(p, format="BMP")),
    "gif": ("gif", lambda p: Image.fromarray(GREY).save(p, format="GIF")),
    "webp lossless": ("webp", lambda p: Image.fromarray(GREY).save(p, format="WEBP", lossless=True)),
    "tiff palette": ("tiff", lambda p: Image.fromarray(GREY).convert("P").save(p, format="TIFF")),
    "tiff lzw": ("tiff", lambda p: Image.fromarray(GREY).save(p, format="TIFF", compression="tiff_lzw")),
    "tiff deflate": ("tiff", lambda p: Image.fromarray(GREY).save(p, format="TIFF", compression="tiff_adobe_deflate")),
    "tiff packbits": ("tiff", lambda p: Image.fromarray(GREY).save(p, format="TIFF", compression="packbits")),
    "tiff miniswhite": ("tiff", lambda p: tifffile.imwrite(p, GREY, photometric="miniswhite")),
}


@pytest.mark.parametrize("kind", list(GREY_WRITERS))
def test_a_grey_picture_comes_back_exactly_found_by_its_content(tmp_path, kind):
    fmt, save = GREY_WRITERS[kind]
    path = tmp_path / "capture"  # no suffix
    save(path)
    assert content_format(path.read_bytes()[:132]) == fmt
    f = _only(path)
    assert f.meta["format"] == fmt and np.array_equal(f.pixels, GREY)
    assert not any("Rec. 709" in n for n in f.notes)
    if kind == "tiff miniswhite":
        assert any("MinIsWhite" in n for n in f.notes)


COLOUR_WRITERS = {
    "bmp 24-bit": ("bmp", lambda p: Image.fromarray(RGB).save(p, format="BMP")),
    "bmp 8-bit palette": ("bmp", lambda p: Image.fromarray(RGB).quantize(200).save(p, format="BMP")),
    "gif": ("gif", lambda p: Image.fromarray(RGB).quantize(256).save(p, format="GIF")),
    "webp lossless": ("webp", lambda p: Image.fromarray(RGB).save(p, format="WEBP", lossless=True)),
    "tiff palette": ("tiff", lambda p: Image.fromarray(RGB).quantize(100).save(p, format="TIFF")),
    "tiff cmyk": ("tiff", lambda p: Image.fromarray(RGB).convert("CMYK").save(p, format="TIFF")),
}


@pytest.mark.parametrize("kind", list(COLOUR_WRITERS))
def test_a_colour_capture_becomes_rec709_grey_of_the_colours_pillow_reads(tmp_path, kind):
    fmt, save = COLOUR_WRITERS[kind]
    path = tmp_path / f"capture.{fmt}"
    save(path)
    with Image.open(path) as im:
        shown = np.asarray(im.convert("RGB"), float)
    f = _only(path)
    assert f.meta["format"] == fmt
    np.testing.assert_allclose(f.pixels, shown @ REC709, rtol=1e-6, atol=1e-4)
    assert any("Rec. 709" in n for n in f.notes)


@pytest.mark.parametrize(
    "kind",
    ["webp lossy", "tiff jpeg"],
)
def test_lossy_pictures_are_read_close_and_a_lossy_webp_says_so(tmp_path, kind):
    path = tmp_path / "capture"
    smooth = np.tile(np.linspace(0, 255, 50).astype(np.uint8), (40, 1))
    if kind == "webp lossy":
        Image.fromarray(smooth).save(path, format="WEBP", quality=95)
    else:
        Image.fromarray(smooth).save(path, format="TIFF", compression="jpeg", quality=95)
    f = _only(path)
    assert np.abs(f.pixels - smooth).max() < 12
    assert any("lossy" in n for n in f.notes) == (kind == "webp lossy")


def test_a_bilevel_tiff_is_read_as_two_levels(tmp_path):
    Image.fromarray(GREY > 128).save(tmp_path / "b.tif", compression="group4")
    f = _only(tmp_path / "b.tif")
    levels = np.unique(f.pixels)
    assert len(levels) == 2 and np.array_equal(f.pixels == levels[1], GREY > 128)


@pytest.mark.parametrize("fmt", ["GIF", "WEBP"])
def test_an_animated_gif_or_webp_is_a_run(tmp_path, fmt):
    frames = [np.full((20, 24), v, np.uint8) for v in (10, 200, 90)]
    path = tmp_path / f"run.{fmt.lower()}"
    pics = [Image.fromarray(a) for a in frames]
    extra = {"lossless": True} if fmt == "WEBP" else {}
    pics[0].save(path, format=fmt, save_all=True, append_images=pics[1:], duration=40, **extra)
    got = list(read_frames(path, need_camera=False))
    assert frame_count(path) == 3 and [f.index for f in got] == [0, 1, 2]
    assert [float(f.pixels.mean()) for f in got] == [10.0, 200.0, 90.0]
    assert "one frame per image" in got[0].notes[0] and got[2].meta["page"] == 2


def test_a_damaged_bmp_is_refused_naming_the_file_and_bm_alone_is_no_bmp(tmp_path):
    Image.fromarray(RGB).save(tmp_path / "a.bmp")
    data = (tmp_path / "a.bmp").read_bytes()
    (tmp_path / "cut.bmp").write_bytes(data[:200])
    with pytest.raises(InputError, match=r"cut\.bmp: a readable BMP image"):
        list(read_frames(tmp_path / "cut.bmp", need_camera=False))
    # "BM" followed by no BMP info header is not taken for a bitmap
    assert content_format(b"BM" + bytes(130)) is None


def test_a_screen_capture_of_a_radiograph_tracks_as_its_png_does(tmp_path, capsys):
    """A mobile C-arm's BMP screen capture (8-bit, 24-bit RGB): the pose is the PNG's."""
    from igt_support import rendered_frames

    fr = rendered_frames(tmp_path, 1, shape=(512, 512), seed=3)
    raw = fr.pixels[0].astype(float)
    shown = np.rint(255 * (raw - raw.min()) / (raw.max() - raw.min())).astype(np.uint8)  # the display's 8 bits
    Image.fromarray(shown).save(tmp_path / "shot.png")
    Image.fromarray(np.dstack([shown] * 3)).save(tmp_path / "shot24.bmp")
    Image.fromarray(shown).convert("P").save(tmp_path / "shot8.bmp")
    poses = {}
    for name in ("shot.png", "shot24.bmp", "shot8.bmp"):
        out = tmp_path / f"{name}.pose.json"
        rc = main(
            ["track", "--features", str(fr.features_path), "--camera", str(fr.camera_path), str(tmp_path / name)]
            + ["-o", str(out)]
        )
        assert rc == 0, capsys.readouterr().err
        poses[name] = out.read_text()
    p = {k: json.loads(v) for k, v in poses.items()}
    assert all(d["converged"] for d in p.values())
    for name in ("shot24.bmp", "shot8.bmp"):
        assert p[name]["translation_mm"] == p["shot.png"]["translation_mm"]
        assert p[name]["rotation"] == p["shot.png"]["rotation"]


def test_the_camera_override_applies_to_every_new_format(tmp_path):
    Image.fromarray(GREY).save(tmp_path / "a.gif")
    (f,) = list(read_frames(tmp_path / "a.gif", camera=CAM))
    assert f.camera == CAM
