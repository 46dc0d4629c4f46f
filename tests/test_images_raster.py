"""PNG, TIFF, JPEG and NumPy intake, runs (multi-page TIFF, (n, H, W) arrays, directories)
and formats found by content (ftrac_design.images)."""

from __future__ import annotations

import numpy as np
import pytest
import tifffile
from images_support import CAM
from PIL import Image

from ftrac_design.errors import InputError
from ftrac_design.images import frame_count, read_frame, read_frames, read_image, write_image

REC709 = np.array([0.2126, 0.7152, 0.0722])


def _only(path, **kw):
    frames = list(read_frames(path, **kw))
    assert len(frames) == 1
    return frames[0]


@pytest.mark.parametrize(
    "dtype,suffix", [(np.uint8, ".png"), (np.uint16, ".png"), (np.uint8, ".tif"), (np.uint16, ".tif")]
)
def test_integer_png_and_tiff_keep_values_camera_and_polarity(tmp_path, dtype, suffix):
    a = np.random.default_rng(0).integers(0, np.iinfo(dtype).max, (30, 41)).astype(dtype)
    f = _only(write_image(tmp_path / f"a{suffix}", a, CAM, polarity="dense_bright", quantity="log"))
    assert np.array_equal(f.pixels, a) and f.meta["bits"] == 8 * a.itemsize
    assert f.camera == CAM and set(f.camera_source.values()) == {"ftrac note"}
    assert (f.polarity, f.formation) == ("dense-bright", "log")


def test_a_file_without_a_camera_needs_one(tmp_path):
    p = tmp_path / "a.png"
    Image.fromarray(np.zeros((8, 9), np.uint8)).save(p)
    with pytest.raises(InputError, match=r"a\.png: camera: .*--camera C\.json.*fiducial"):
        list(read_frames(p))
    f = _only(p, need_camera=False)
    assert f.camera is None and f.polarity is None and f.formation is None
    assert _only(p, camera=CAM).camera == CAM


@pytest.mark.parametrize("mode,channels", [("RGB", 3), ("RGBA", 4)])
def test_a_grabbers_rgb_png_becomes_rec709_grey(tmp_path, mode, channels):
    rgb = np.random.default_rng(1).integers(0, 256, (20, 30, channels)).astype(np.uint8)
    Image.fromarray(rgb, mode).save(tmp_path / "a.png")
    f = _only(tmp_path / "a.png", need_camera=False)
    np.testing.assert_allclose(f.pixels, rgb[..., :3] @ REC709, rtol=1e-6)
    assert any("Rec. 709" in n for n in f.notes)
    assert any("alpha" in n for n in f.notes) == (channels == 4)


def test_jpeg_is_read_with_a_note_on_lossy_compression(tmp_path):
    a = np.tile(np.linspace(0, 255, 64).astype(np.uint8), (48, 1))
    Image.fromarray(a).save(tmp_path / "a.jpg", quality=95)
    f = _only(tmp_path / "a.jpg", need_camera=False)
    assert f.meta["format"] == "jpeg" and np.abs(f.pixels - a).max() < 8
    assert any("lossy" in n for n in f.notes)


def test_multi_page_tiff_is_a_run_and_pages_of_other_shapes_are_named(tmp_path):
    a = np.random.default_rng(2).integers(0, 4096, (3, 20, 24)).astype(np.uint16)
    with tifffile.TiffWriter(tmp_path / "run.tif") as tw:
        for page in a:
            tw.write(page)
    frames = list(read_frames(tmp_path / "run.tif", need_camera=False))
    assert frame_count(tmp_path / "run.tif") == 3 and [f.index for f in frames] == [0, 1, 2]
    assert all(np.array_equal(f.pixels, a[i]) for i, f in enumerate(frames))
    with tifffile.TiffWriter(tmp_path / "two.tif") as tw:
        tw.write(a[0])
        tw.write(a[1, :10])
    with pytest.raises(InputError, match=r"two\.tif: page 1: pages of one shape"):
        list(read_frames(tmp_path / "two.tif", need_camera=False))


@pytest.mark.parametrize("dtype", [np.int32, np.float32, np.float64, np.int16])
def test_tiff_of_wide_and_float_types(tmp_path, dtype):
    a = (np.random.default_rng(3).normal(0, 1000, (16, 18))).astype(dtype)
    tifffile.imwrite(tmp_path / "a.tif", a)
    f = _only(tmp_path / "a.tif", need_camera=False)
    np.testing.assert_allclose(f.pixels, a.astype(np.float32))


def test_npy_runs_and_refusals(tmp_path):
    a = np.random.default_rng(4).normal(size=(4, 10, 12)).astype(np.float32)
    np.save(tmp_path / "run.npy", a)
    frames = list(read_frames(tmp_path / "run.npy", need_camera=False))
    assert frame_count(tmp_path / "run.npy") == 4 and all(np.array_equal(f.pixels, a[i]) for i, f in enumerate(frames))
    assert np.array_equal(read_frame(tmp_path / "run.npy", 2, need_camera=False).pixels, a[2])
    np.savez(tmp_path / "z.npz", a=a)
    (tmp_path / "z.npz").rename(tmp_path / "z.npy")
    with pytest.raises(InputError, match=r"z\.npy: .*\.npz"):
        list(read_frames(tmp_path / "z.npy", need_camera=False))
    np.save(tmp_path / "o.npy", np.array([[1, 2], [3, 4]], dtype=object), allow_pickle=True)
    with pytest.raises(InputError, match="dtype"):
        list(read_frames(tmp_path / "o.npy", need_camera=False))
    np.save(tmp_path / "c.npy", np.zeros((4, 4), np.complex64))
    with pytest.raises(InputError, match="dtype"):
        list(read_frames(tmp_path / "c.npy", need_camera=False))


def test_the_content_decides_when_the_suffix_lies(tmp_path):
    a = np.arange(12 * 10, dtype=np.uint8).reshape(12, 10)
    Image.fromarray(a).save(tmp_path / "a.tif", format="PNG")
    f = _only(tmp_path / "a.tif", need_camera=False)
    assert f.meta["format"] == "png" and np.array_equal(f.pixels, a) and "content is PNG" in f.notes[0]
    (tmp_path / "noext").write_bytes((tmp_path / "a.tif").read_bytes())
    assert np.array_equal(_only(tmp_path / "noext", need_camera=False).pixels, a)
    (tmp_path / "x.png").write_bytes(b"\0" * 200)
    with pytest.raises(InputError, match=r"x\.png"):
        list(read_frames(tmp_path / "x.png"))


def test_a_directory_is_a_run_in_natural_order(tmp_path):
    frames = {}
    for k in (10, 2, 1):
        frames[k] = np.full((6, 7), k, np.uint16)
        write_image(tmp_path / f"img_{k}.png", frames[k], CAM)
    np.save(tmp_path / "img_11.npy", np.full((2, 6, 7), 11.0))  # a 2-frame file inside the run
    (tmp_path / "truth.json").write_text("{}")
    (tmp_path / ".hidden.png").write_bytes(b"junk")
    got = list(read_frames(tmp_path, camera=CAM))
    assert [f.pixels[0, 0] for f in got] == [1, 2, 10, 11, 11] and [f.index for f in got] == [0, 1, 2, 3, 4]
    assert frame_count(tmp_path) == 5 and read_frame(tmp_path, 4, camera=CAM).source.endswith("img_11.npy")
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputError, match="directory holding image files"):
        frame_count(tmp_path / "empty")


def test_read_image_keeps_the_old_tuple(tmp_path):
    a = np.random.default_rng(5).integers(0, 255, (9, 11)).astype(np.uint8)
    img, cam, meta = read_image(write_image(tmp_path / "a.png", a, CAM, polarity="dense_dark"))
    assert img.dtype == np.float64 and np.array_equal(img, a) and cam is None
    assert meta["format"] == "png" and meta["bits"] == 8 and meta["polarity_hint"] == "dense_dark"
    assert meta["camera"] == CAM.to_dict()


def test_float_images_are_quantised_with_their_map_applied_on_reading(tmp_path):
    a = np.random.default_rng(6).normal(1.0, 0.3, (20, 20))
    f = _only(write_image(tmp_path / "a.png", a, CAM, value_range=(0.0, 2.0)))
    assert np.abs(f.pixels - np.clip(a, 0, 2)).max() <= 2 / 65535 + 1e-6


def test_the_old_names_in_xray_still_work(tmp_path):
    """``ftrac-design track`` still imports the reader and the note's camera parser from xray."""
    from ftrac_design.xray import read_image as old_read_image
    from ftrac_design.xray.imagefiles import _camera_from_dict
    from ftrac_design.xray.imagefiles import write_image as old_write_image

    p = old_write_image(tmp_path / "a.png", np.zeros((6, 8), np.uint8), CAM)
    img, cam, meta = old_read_image(p)
    assert img.shape == (6, 8) and cam is None and _camera_from_dict(meta["camera"]) == CAM
    assert _camera_from_dict({"focal_length_mm": "x"}) is None
