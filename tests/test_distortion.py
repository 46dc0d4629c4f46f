"""Image-intensifier distortion: the polynomial model and its inverse, the factories, the file,
image resampling, estimation from a rendered bead-grid image and `ftrac-design distortion`."""

from __future__ import annotations

import json

import numpy as np
import pytest

from ftrac_design.calibration.gridcal import estimate_distortion
from ftrac_design.calibration.gridplate import grid_plate, plate_pose, render_grid
from ftrac_design.cli.main import main
from ftrac_design.errors import InputError
from ftrac_design.images.distortion import (
    DistortionModel,
    combine,
    distort_image,
    radial,
    read_distortion,
    s_distortion,
    undistort_image,
    write_distortion,
)
from ftrac_design.xray import write_image

SHAPE = (512, 512)
CENTRE = np.array([255.5, 255.5])
PIXEL_MM = 0.44
#: the intensifier field of the rendered grids (px) and the disc the estimate is checked over
FIELD_PX = 240.0
CHECK_PX = 220.0


@pytest.fixture(scope="module")
def true_model() -> DistortionModel:
    """Pincushion 2 mm at 100 mm (≈ 4.5 px at 227 px) plus a 3 px S-distortion."""
    return combine(radial(SHAPE, (2.0, 100.0), PIXEL_MM), s_distortion(SHAPE, 3.0))


def _field_points(model: DistortionModel, radius: float = CHECK_PX) -> np.ndarray:
    g = model.pixel_grid(4)
    return g[np.hypot(*(g - CENTRE).T) < radius]


def _field_rms(a: DistortionModel, b: DistortionModel) -> float:
    g = _field_points(a)
    return float(np.sqrt(np.mean(np.sum((a.distort(g) - b.distort(g)) ** 2, axis=1))))


# -- the model --------------------------------------------------------------------------


def test_forward_inverse_round_trip(true_model):
    rng = np.random.default_rng(0)
    q = rng.uniform(0, 511, (20000, 2))
    p = true_model.undistort(q)
    assert np.all(np.isfinite(p))
    assert np.max(np.abs(true_model.distort(p) - q)) <= 1e-6
    p2 = rng.uniform(0, 511, (20000, 2))
    assert np.max(np.abs(true_model.undistort(true_model.distort(p2)) - p2)) <= 1e-6
    # shape preserved, batch or single
    assert true_model.undistort(q[:6].reshape(2, 3, 2)).shape == (2, 3, 2)


def test_undistort_refuses_where_there_is_no_inverse():
    # strong barrel: the radius maps to r (1 − a r²), which peaks at r = 1/√(3a) and folds beyond;
    # a distorted point farther out than that peak has no ideal pixel
    m = radial(SHAPE, (-40.0, 100.0), PIXEL_MM)
    a = (40.0 / PIXEL_MM) * (PIXEL_MM / 100.0) ** 3
    r_peak = 1 / np.sqrt(3 * a)
    d_peak = r_peak * (1 - a * r_peak**2)
    q = CENTRE + np.array([[0.5 * d_peak, 0.0], [1.05 * d_peak, 0.0], [np.nan, 3.0]])
    p = m.undistort(q)
    assert np.all(np.isfinite(p[0])) and np.allclose(m.distort(p[:1]), q[:1], atol=1e-6)
    assert np.all(np.isnan(p[1])) and np.all(np.isnan(p[2]))


def test_radial_displacement_is_k_at_r_and_cubic():
    m = radial(SHAPE, (2.0, 100.0), PIXEL_MM)
    for ang in np.radians([0.0, 37.0, 90.0, 200.0]):
        d = np.array([np.cos(ang), np.sin(ang)])
        for r_mm, want_mm in ((100.0, 2.0), (50.0, 0.25)):
            p = CENTRE + d * r_mm / PIXEL_MM
            disp = m.displacement(p[None])[0]
            assert np.allclose(disp, d * want_mm / PIXEL_MM, atol=1e-9)  # outward, radial
    assert m.displacement(CENTRE[None])[0] == pytest.approx([0.0, 0.0], abs=1e-12)
    assert m.rms_residual_px == 0.0
    barrel = radial(SHAPE, (-1.0, 100.0), PIXEL_MM, centre=(200.0, 300.0))
    p = np.array([[200.0 + 100.0 / PIXEL_MM, 300.0]])
    assert barrel.displacement(p)[0] == pytest.approx([-1.0 / PIXEL_MM, 0.0], abs=1e-9)


def test_s_distortion_is_a_rotation_growing_with_radius():
    m = s_distortion(SHAPE, 3.0)
    assert m.max_residual_px < 1e-3  # the polynomial fit of the rotation
    for r, want in ((256.0, 3.0), (128.0, 3.0 / 8)):  # tangential displacement ≈ a (r/R)³
        for ang in np.radians([10.0, 135.0]):
            d = np.array([np.cos(ang), np.sin(ang)])
            disp = m.displacement((CENTRE + r * d)[None])[0]
            tangent = np.array([-d[1], d[0]])
            assert disp @ tangent == pytest.approx(want, rel=2e-3)
            # a rotation moves along the circle: the radial part is second order (−r θ²/2)
            assert abs(disp @ d) < 0.02
    # the gauge: identity to first order at the centre
    J = m.jacobian(CENTRE[None])[0]
    assert np.allclose(J, np.eye(2), atol=1e-12)


def test_json_round_trip_and_spec_keys(tmp_path, true_model):
    p = tmp_path / "sub" / "model.json"
    write_distortion(p, true_model)
    d = json.loads(p.read_text())
    for k in (
        "format",
        "version",
        "model",
        "degree",
        "image_shape",
        "centre_px",
        "scale_px",
        "coefficients_u",
        "coefficients_v",
        "direction",
        "rms_residual_px",
        "max_residual_px",
        "source",
    ):
        assert k in d
    assert (d["format"], d["version"], d["model"], d["direction"]) == (
        "ftrac-distortion",
        1,
        "polynomial-2d",
        "ideal_to_distorted",
    )
    back = read_distortion(p)
    assert back == true_model
    q = np.array([[10.0, 20.0], [400.0, 300.0]])
    assert np.array_equal(back.distort(q), true_model.distort(q))
    assert [x.name for x in p.parent.iterdir()] == ["model.json"]  # no temporary left behind


@pytest.mark.parametrize(
    "edit, key",
    [
        (lambda d: d.pop("coefficients_v"), "coefficients_v"),
        (lambda d: d.update(coefficients_u=[0.0, 1.0]), "coefficients_u"),
        (lambda d: d.update(format="ftrac-pose"), "format"),
        (lambda d: d.update(direction="distorted_to_ideal"), "direction"),
        (lambda d: d.update(degree=2.5), "degree"),
        (lambda d: d.update(scale_px=-3), "scale_px"),
        (lambda d: d.update(image_shape=[512]), "image_shape"),
    ],
)
def test_bad_file_names_the_file_and_key(tmp_path, true_model, edit, key):
    d = true_model.to_dict()
    edit(d)
    p = tmp_path / "bad.json"
    p.write_text(json.dumps(d))
    with pytest.raises(InputError) as exc:
        read_distortion(p)
    assert exc.value.key == key and exc.value.file == str(p)
    p.write_text('{"format": "ftrac-distortion", "scale_px": NaN}')
    with pytest.raises(InputError):
        read_distortion(p)


# -- images -----------------------------------------------------------------------------


def test_distort_image_moves_a_blob_to_the_model_place(true_model):
    v, u = np.mgrid[0:512, 0:512].astype(float)
    ideal = np.array([[400.0, 130.0], [120.0, 200.0]])
    img = sum(np.exp(-((u - c[0]) ** 2 + (v - c[1]) ** 2) / (2 * 2.0**2)) for c in ideal)
    out = distort_image(img, true_model)
    assert out.shape == img.shape and out.dtype == img.dtype
    for want in true_model.distort(ideal):
        cu, cv = np.round(want).astype(int)
        w = out[cv - 8 : cv + 9, cu - 8 : cu + 9]
        got = (
            np.array([(w * u[cv - 8 : cv + 9, cu - 8 : cu + 9]).sum(), (w * v[cv - 8 : cv + 9, cu - 8 : cu + 9]).sum()])
            / w.sum()
        )
        assert np.hypot(*(got - want)) < 0.03


@pytest.mark.parametrize("direction", ["undistort", "distort"])
def test_the_pixel_maps_sampled_and_interpolated_match_every_pixel_evaluated(direction):
    """A strong intensifier on a 1024² frame (2.5 mm pincushion at 100 mm, centre 42 px off,
    plus a 3 px S-distortion): the maps made from samples every 4 px lie within 0.005 px of
    the polynomial (or its Newton inverse) evaluated at every pixel, the image's corners
    included — a quarter of the 1/64 px to which cv2.remap honours a position."""
    from ftrac_design.images import distortion

    shape = (1024, 1024)
    c = (542.0, 482.0)
    pin = radial(shape, (2.5, 100.0), PIXEL_MM, centre=c)
    model = combine(pin, s_distortion(shape, 3.0, radius_px=512.0, centre=c))
    fast, exact = distortion._maps.__wrapped__(model, direction), distortion.exact_maps(model, direction)
    for a, b in zip(fast, exact):
        assert a.shape == b.shape == shape and a.dtype == np.float32
        assert float(np.abs(a - b).max()) < 0.005
    # the maps move pixels by several px at the corners: the comparison is not of two identities
    assert float(np.abs(exact[0] - np.arange(1024)[None]).max()) > 3.0


def test_maps_are_evaluated_at_every_pixel_where_a_sample_is_not_finite(true_model, monkeypatch):
    """Where the polynomial gives no finite position at a sample (Newton refusing a folding
    polynomial far outside its support), nothing is interpolated across it: every pixel is
    evaluated, and a pixel with no finite source reads itself."""
    from ftrac_design.images import distortion

    monkeypatch.setattr(DistortionModel, "distort", lambda self, p: np.full(np.shape(p), np.nan))
    mx, my = distortion._maps.__wrapped__(true_model, "undistort")
    H, W = SHAPE
    assert np.array_equal(mx, np.broadcast_to(np.arange(W, dtype=np.float32)[None], SHAPE))
    assert np.array_equal(my, np.broadcast_to(np.arange(H, dtype=np.float32)[:, None], SHAPE))


def test_undistort_image_undoes_distort_image(true_model):
    rng = np.random.default_rng(3)
    from scipy.ndimage import gaussian_filter

    img = gaussian_filter(rng.standard_normal(SHAPE), 3.0).astype(np.float32)
    back = undistort_image(distort_image(img, true_model), true_model)
    g = np.round(_field_points(true_model, 200.0)).astype(int)
    diff = back[g[:, 1], g[:, 0]] - img[g[:, 1], g[:, 0]]
    # two bilinear resamplings of a field with 3 px correlation: small, unbiased differences
    assert np.sqrt(np.mean(diff**2)) < 0.03 * img.std()
    assert abs(diff.mean()) < 0.005 * img.std()
    with pytest.raises(InputError):
        undistort_image(np.zeros((100, 100)), true_model)


# -- estimation from a bead-grid image --------------------------------------------------


@pytest.fixture(scope="module")
def grid_image(true_model):
    plate = grid_plate(5.0, 45, 45, 1.5)
    return render_grid(plate, true_model, field_radius_px=FIELD_PX, rng=np.random.default_rng(1))


def test_estimate_recovers_the_distortion(grid_image, true_model):
    model, report = estimate_distortion(grid_image.raw, 5.0, PIXEL_MM)
    assert _field_rms(model, true_model) <= 0.1
    assert report.rms_px < 0.1 and report.field_found and report.polarity == "dense-dark"
    assert report.rms_mm == pytest.approx(report.rms_px * PIXEL_MM)
    # nearly every bead inside the field is used (those within a patch of the edge are not)
    inside = np.hypot(*(grid_image.distorted_px - CENTRE).T) < FIELD_PX - 12
    assert report.n_used >= 0.97 * inside.sum()
    # the gauge: identity to first order at the image centre
    a, b = np.array(model.coefficients_u), np.array(model.coefficients_v)
    assert np.array_equal(a[:3], [0, 1, 0]) and np.array_equal(b[:3], [0, 0, 1])
    # the same image gives the same model
    again, _ = estimate_distortion(grid_image.raw, 5.0, PIXEL_MM)
    assert again == model


def test_estimate_is_robust_to_rotation_tilt_missing_and_spurious_beads(true_model):
    # the plate turned 10° and tilted 3°, its centre bead and another missing, three stray
    # blobs (larger balls between lattice sites), a round field cutting the grid
    stray = ((2.5, 2.5), (-12.5, 7.5), (37.5, -22.5))
    plate = grid_plate(5.0, 45, 45, 1.5, missing=((22, 22), (10, 30)), extra_mm=stray)
    pose = plate_pose(np.radians(10.0), (np.radians(3.0), 0.0), offset_mm=(3.0, -2.0))
    gi = render_grid(plate, true_model, pose=pose, field_radius_px=FIELD_PX, rng=np.random.default_rng(2))
    model, report = estimate_distortion(gi.raw, 5.0, PIXEL_MM, polarity="auto")
    assert _field_rms(model, true_model) <= 0.1
    stray_px = gi.distorted_px[[i for i, name in enumerate(gi.ids) if name.startswith("X")]]
    d = np.min(np.hypot(*(report.detected_px[report.used][:, None] - stray_px[None]).transpose(2, 0, 1)), axis=0)
    assert np.all(d > 3.0)  # no stray blob was taken for a grid bead
    # the model's grid indices are those of the plate, up to the lattice's symmetry
    assert len(np.unique(report.index[report.used], axis=0)) == report.n_used


def test_estimate_on_a_display_image_and_lower_degree(grid_image, true_model):
    log_image = -np.log(np.maximum(grid_image.raw, 1.0) / float(grid_image.raw.max()))
    model, report = estimate_distortion(log_image, 5.0, PIXEL_MM, degree=3, bead_diameter_mm=1.5)
    assert report.polarity == "dense-bright"
    assert model.degree == 3 and _field_rms(model, true_model) <= 0.1


def test_estimate_refuses_too_few_beads_and_bad_arguments(true_model):
    gi = render_grid(grid_plate(10.0, 6, 6, 1.5), true_model, rng=np.random.default_rng(0))
    with pytest.raises(InputError) as exc:
        estimate_distortion(gi.raw, 10.0, PIXEL_MM)
    assert exc.value.key == "image" and "63" in str(exc.value)
    for kw in ({"pitch_mm": -1.0}, {"pitch_mm": float("nan")}, {"pixel_mm": 0.0}, {"degree": 0}):
        args = {"pitch_mm": 10.0, "pixel_mm": PIXEL_MM} | kw
        with pytest.raises(InputError):
            estimate_distortion(gi.raw, args.pop("pitch_mm"), args.pop("pixel_mm"), **args)


# -- the command line -------------------------------------------------------------------


def _run(args, capsys):
    rc = main(args)
    out = capsys.readouterr()
    return rc, out.out, out.err


def test_cli_writes_the_model(tmp_path, grid_image, true_model, capsys):
    img = tmp_path / "grid.png"
    write_image(img, grid_image.raw, grid_image.camera, polarity="dense_dark")
    out, plot = tmp_path / "out" / "model.json", tmp_path / "out" / "fit.png"
    rc, so, se = _run(["distortion", str(img), "--pitch", "5", "-o", str(out), "--plot", str(plot)], capsys)
    assert rc == 0, se
    assert "residual RMS" in so and "beads used" in so
    model = read_distortion(out)
    assert _field_rms(model, true_model) <= 0.1
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert sorted(p.name for p in out.parent.iterdir()) == ["fit.png", "model.json"]


@pytest.mark.parametrize("case", ["not-an-image", "missing", "bad-pitch", "tiny-pitch", "no-pixel-size"])
def test_cli_bad_input_exits_2_with_one_line_and_writes_nothing(tmp_path, grid_image, capsys, case):
    img = tmp_path / "grid.png"
    write_image(img, grid_image.raw, grid_image.camera if case != "no-pixel-size" else None)
    args = {
        "not-an-image": [str(tmp_path / "junk.png"), "--pitch", "5"],
        "missing": [str(tmp_path / "absent.png"), "--pitch", "5"],
        "bad-pitch": [str(img), "--pitch", "-5"],
        "tiny-pitch": [str(img), "--pitch", "0.5"],
        "no-pixel-size": [str(img), "--pitch", "5"],
    }[case]
    (tmp_path / "junk.png").write_text("not a PNG")
    out = tmp_path / "out"
    rc, so, se = _run(["distortion", *args, "-o", str(out / "m.json"), "--plot", str(out / "m.png")], capsys)
    assert rc == 2
    assert len(se.strip().splitlines()) == 1 and "Traceback" not in se
    assert not out.exists() or not any(out.iterdir())
