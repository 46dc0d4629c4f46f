"""The radiograph simulator against closed forms, its image files, truth and command line."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest

from ftrac_design.cli.main import main
from ftrac_design.design import Body
from ftrac_design.errors import InputError
from ftrac_design.features import write_features
from ftrac_design.features.model import EllipseFeature, Features, LineFeature, PointFeature
from ftrac_design.images import read_image, write_image
from ftrac_design.pose.camera import Camera
from ftrac_design.pose.simulate import Workspace
from ftrac_design.xray import ImagingModel, Occluder, anatomy, line_integral_box, read_truth, render, write_truth
from ftrac_design.xray.geometry import (
    body_chord_uv,
    cylinder_z_chord,
    ellipse_pieces,
    straight_pieces,
    tube_chord,
    tube_chord_uv,
)
from ftrac_design.xray.materials import linear_attenuation
from ftrac_design.xray.rays import Rays

SMALL = ImagingModel(image_shape=(256, 256), photons_per_px=None)
CAM_SMALL = Camera(1000.0, (0.44, 0.44), (128.0, 128.0))
MU_STEEL = SMALL.mu("steel")
BODY_2005 = Body(30.0, 50.0, 20.0, "acetal")


def _features(points=(), lines=(), ellipses=()):
    return Features(
        "t", None, None, np.array([0.0, -1.0, 0.0]), points=tuple(points), lines=tuple(lines), ellipses=tuple(ellipses)
    )


def _rot_y(deg):
    a = math.radians(deg)
    return np.array([[math.cos(a), 0, math.sin(a)], [0, 1, 0], [-math.sin(a), 0, math.cos(a)]])


# ----------------------------------------------------------------------------- materials
def test_attenuation_at_60_kev_matches_the_issue_and_nist():
    # μ_steel ≈ 9.4 /cm, μ_POM ≈ 0.27 /cm at 60 keV; NIST Fe 1.205 cm²/g
    assert 0.93 <= linear_attenuation("steel", 60.0) <= 0.97
    assert 0.026 <= linear_attenuation("acetal (POM-C)", 60.0) <= 0.028
    assert linear_attenuation("steel", 80.0) < linear_attenuation("steel", 60.0) < linear_attenuation("steel", 40.0)
    assert ImagingModel(attenuation_per_mm={"steel": 1.0}).mu("stainless steel 304") == 1.0


# ----------------------------------------------------------------------------- chords vs sampling
def _sampled_chord(inside, c, d, s_lo, s_hi, n=400_000):
    s = np.linspace(s_lo, s_hi, n)
    p = c + s[:, None] * d
    return float(inside(p).mean() * (s_hi - s_lo) * np.linalg.norm(d))


def test_chords_agree_with_point_membership_sampling():
    rng = np.random.default_rng(3)
    c = np.array([5.0, -660.0, 12.0])
    for _ in range(6):
        target = rng.uniform(-12, 12, 3)
        d = (target - c) * 1.5
        s_lo, s_hi = 0.9 / 1.5, 1.1 / 1.5

        # hollow cylinder
        def body(p):
            r = np.hypot(p[:, 0], p[:, 1])
            return (r <= 15) & (r >= 10) & (np.abs(p[:, 2]) <= 25)

        got = cylinder_z_chord(c, d[None], 15, 25)[0] - cylinder_z_chord(c, d[None], 10, 25)[0]
        assert got == pytest.approx(_sampled_chord(body, c, d, s_lo, s_hi), abs=2e-3)
        # a tube piece with oblique (mitre-like) end planes
        a, e, L, r = np.array([-3.0, 0.5, 1.0]), np.array([1.0, 0.0, 0.0]), 6.0, 4.0
        n0 = np.array([1.0, 0.3, 0.0]) / np.hypot(1, 0.3)
        n1 = np.array([1.0, -0.2, 0.1]) / np.linalg.norm([1.0, -0.2, 0.1])

        def tube(p):
            w = p - a
            along = w @ e
            perp = np.linalg.norm(w - along[:, None] * e, axis=1)
            return (perp <= r) & ((p - a) @ n0 >= 0) & ((p - a - L * e) @ n1 <= 0)

        target = a + rng.uniform(0, L) * e + rng.uniform(-r, r, 3) * [0, 1, 1]
        d = (target - c) * 1.5
        got = tube_chord(c, d[None], a[None], e[None], np.array([L]), np.array([r]), n0[None], n1[None])[0]
        assert got == pytest.approx(_sampled_chord(tube, c, d, s_lo, s_hi), abs=2e-3)


def test_fast_chords_equal_the_reference_forms():
    R = _rot_y(20.0) @ np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]], float)
    t = np.array([3.0, -4.0, 660.0])
    cam = Camera()
    rays = Rays(cam, R, t)
    pieces = ellipse_pieces(
        EllipseFeature("E", np.array([0, 0, 3.0]), np.array([1.0, 0, 0]), np.array([0, 0.8, 0.6]), 17.0, 15.0, 0.5),
        MU_STEEL,
        0,
    )
    rng = np.random.default_rng(0)
    k = rng.integers(0, len(pieces.L), 3000)
    mid = pieces.a[k] + 0.5 * pieces.L[k, None] * pieces.e[k]
    uv = cam.project(mid @ R.T + t) + rng.uniform(-1.5, 1.5, (len(k), 2))
    U, V = uv[:, :1] + rng.uniform(-0.5, 0.5, (len(k), 4)), uv[:, 1:] + rng.uniform(-0.5, 0.5, (len(k), 4))
    fast = tube_chord_uv(rays.c, rays.g0, rays.gu, rays.gv, pieces, k, U, V)
    kk = np.repeat(k, 4)
    ref = tube_chord(
        rays.c,
        rays(U.ravel(), V.ravel()),
        pieces.a[kk],
        pieces.e[kk],
        pieces.L[kk],
        pieces.r[kk],
        pieces.n0[kk],
        pieces.n1[kk],
    ).reshape(U.shape)
    assert np.abs(fast - ref).max() < 1e-8 and (ref > 0).mean() > 0.2
    fast_b = body_chord_uv(rays.c, rays.g0, rays.gu, rays.gv, 15.0, 10.0, 25.0, U, V)
    d = rays(U.ravel(), V.ravel())
    ref_b = (cylinder_z_chord(rays.c, d, 15.0, 25.0) - cylinder_z_chord(rays.c, d, 10.0, 25.0)).reshape(U.shape)
    assert np.abs(fast_b - ref_b).max() < 1e-8


def test_mitred_ellipse_pieces_tile_the_bent_wire():
    """A circle wire (a torus): the pieces' chords sum to the torus chord (sampled), no gap or overlap."""
    rho, r = 12.0, 0.25
    el = EllipseFeature("E", np.zeros(3), np.array([1.0, 0, 0]), np.array([0, 1.0, 0]), rho, rho, 2 * r)
    P = ellipse_pieces(el, 1.0, 0)
    rng = np.random.default_rng(1)
    c = np.array([0.0, 0.0, -600.0])
    for _ in range(8):
        phi = rng.uniform(0, 2 * np.pi)
        target = (rho + rng.uniform(-0.8, 0.8) * r) * np.array([np.cos(phi), np.sin(phi), 0.0])
        target[2] = rng.uniform(-0.1, 0.1)
        d = (target - c) + rng.normal(0, 40, 3) * [1, 1, 0]  # oblique rays too
        d = d * (1.0 / np.linalg.norm(d)) * 700
        n = len(P.L)
        total = tube_chord(c, np.broadcast_to(d, (n, 3)), P.a, P.e, P.L, P.r, P.n0, P.n1).sum()

        def torus(p):
            return (np.hypot(p[:, 0], p[:, 1]) - rho) ** 2 + p[:, 2] ** 2 <= r * r

        s_mid = float(-(c @ d) / (d @ d))
        ref = _sampled_chord(torus, c, d, s_mid - 0.01, s_mid + 0.01, n=600_000)
        # the polyline departs from the circle by ≤ 6.7 µm: chords agree to ~1e-2 mm off-centre
        assert total == pytest.approx(ref, abs=0.012)


# ----------------------------------------------------------------------------- closed forms in the image
def test_bead_integrated_attenuation_is_mu_volume_magnification_squared():
    """Σ_pixels p × (s_x s_y) = ∫ p dA_detector = μ ∫ (f/z)² / cos θ dV ≈ μ V M² on the axis."""
    r, z0 = 1.0, 667.0
    f = _features(points=[PointFeature("B", np.zeros(3), 2 * r)])
    p, _ = line_integral_box(f, np.eye(3), np.array([0.0, 0.0, z0]), CAM_SMALL, SMALL)
    M = CAM_SMALL.focal_length_mm / z0
    expected = MU_STEEL * 4 / 3 * np.pi * r**3 * M**2 / (0.44 * 0.44)
    assert p.sum() == pytest.approx(expected, rel=2e-3)


def test_straight_wire_profile_is_the_chord_of_a_circle():
    """A wire along x through the principal ray: at column o_x the ray in the y–z plane passes
    the axis at distance z0 |Y| / √(Y² + f²), Y = (v − o_y) s_y, so p = μ 2 √(r² − dist²)."""
    r, z0 = 0.25, 667.0
    f = _features(lines=[LineFeature("L", np.array([-10.0, 0, 0]), np.array([10.0, 0, 0]), 2 * r)])
    im = ImagingModel(image_shape=(256, 256), photons_per_px=None, supersample=1, single_precision=False)
    p, (v0, u0) = line_integral_box(f, np.eye(3), np.array([0.0, 0.0, z0]), CAM_SMALL, im)
    col = p[:, 128 - u0]
    v = v0 + np.arange(len(col))
    Y = (v - 128.0) * 0.44
    dist = z0 * np.abs(Y) / np.sqrt(Y**2 + 1000.0**2)
    expected = MU_STEEL * 2 * np.sqrt(np.maximum(r * r - dist**2, 0))
    np.testing.assert_allclose(col, expected, atol=1e-9)
    assert col.max() == pytest.approx(MU_STEEL * 2 * r, rel=1e-9)  # 0.5 mm wire: ~0.48
    # the profile's width at the detector is the wire's, magnified: 2 r f / z0 (± a pixel)
    assert np.count_nonzero(col) == pytest.approx(2 * r * 1000 / z0 / 0.44, abs=1.01)


def test_body_chord_through_its_axis():
    """Axis across the beam through the principal ray: the central ray crosses the wall twice."""
    f = _features()
    R = _rot_y(90.0)  # F's z axis along camera x
    im = ImagingModel(image_shape=(256, 256), photons_per_px=None, supersample=1, single_precision=False)
    p, (v0, u0) = line_integral_box(replace(f, body=BODY_2005), R, np.array([0.0, 0.0, 667.0]), CAM_SMALL, im)
    assert p[128 - v0, 128 - u0] == pytest.approx(im.mu("acetal") * 2 * (15.0 - 10.0), rel=1e-12)


def test_single_precision_stays_close_to_double(features_2005):
    R, t = Workspace().sample(1, features_2005.nominal_beam_direction, np.random.default_rng(8))
    a, oa = line_integral_box(features_2005, R[0], t[0], Camera(), ImagingModel())
    b, ob = line_integral_box(features_2005, R[0], t[0], Camera(), ImagingModel(single_precision=False))
    assert oa == ob and a.shape == b.shape
    assert np.abs(a - b).max() < 2e-3 and np.mean(np.abs(a - b) > 4e-4) < 1e-3 and a.max() > 1.5


def test_bead_centroid_follows_the_projection():
    f = _features(points=[PointFeature("B", np.zeros(3), 2.0)])
    rng = np.random.default_rng(4)
    for _ in range(4):
        R = Workspace().sample(1, np.array([0, -1.0, 0]), rng)[0][0]
        t = np.array([*rng.uniform(-8, 8, 2), rng.uniform(640, 690)])
        p, (v0, u0) = line_integral_box(f, R, t, CAM_SMALL, SMALL)
        V, U = np.mgrid[v0 : v0 + p.shape[0], u0 : u0 + p.shape[1]]
        centroid = np.array([(p * U).sum(), (p * V).sum()]) / p.sum()
        np.testing.assert_allclose(centroid, CAM_SMALL.project(t), atol=0.01)


def test_render_is_pixel_integrated_not_point_sampled():
    """Supersampling 4 vs 16: a bead's blurred centroid moves < 0.01 px (feature centres unbiased)."""
    f = _features(points=[PointFeature("B", np.zeros(3), 2.0)])
    t = np.array([0.137, -0.071, 667.0])
    cents = []
    for s in (4, 16):
        img = render(
            f,
            np.eye(3),
            t,
            CAM_SMALL,
            ImagingModel(image_shape=(256, 256), photons_per_px=None, supersample=s),
        )
        p = img.line_integral
        V, U = np.mgrid[0:256, 0:256]
        m = (np.abs(U - 128) < 12) & (np.abs(V - 128) < 12)
        cents.append(np.array([(p * U)[m].sum(), (p * V)[m].sum()]) / p[m].sum())
    assert np.abs(cents[0] - cents[1]).max() < 0.01


# ----------------------------------------------------------------------------- noise, blur, raw
@pytest.mark.parametrize("dose", [2_000.0, 20_000.0])
def test_log_image_variance_is_one_over_expected_counts(dose):
    im = ImagingModel(image_shape=(256, 256), photons_per_px=dose)
    bg = np.full((256, 256), 1.0, np.float32)  # uniform attenuation p = 1
    img = render(
        _features(),
        np.eye(3),
        np.array([0, 0, 667.0]),
        CAM_SMALL,
        im,
        rng=np.random.default_rng(0),
        background=bg,
    )
    var = img.log_image.var()
    assert var == pytest.approx(1.0 / (dose * math.exp(-1.0)), rel=0.05)
    assert img.log_image.mean() == pytest.approx(1.0, abs=5 * math.sqrt(var / img.log_image.size) + 1e-3)


def test_same_seed_same_image_and_polarities(features_2005):
    R, t = Workspace().sample(1, features_2005.nominal_beam_direction, np.random.default_rng(9))
    im = ImagingModel(image_shape=(256, 256))
    a = render(features_2005, R[0], t[0], CAM_SMALL, im, rng=np.random.default_rng(5))
    b = render(features_2005, R[0], t[0], CAM_SMALL, im, rng=np.random.default_rng(5))
    c = render(features_2005, R[0], t[0], CAM_SMALL, im, rng=np.random.default_rng(6))
    assert np.array_equal(a.raw, b.raw) and np.array_equal(a.log_image, b.log_image)
    assert not np.array_equal(a.raw, c.raw)
    # raw: dense = dark (bead pixel darker than the flat field); log: dense = bright
    uv = np.rint(a.truth["projected"]["points"]["B1"]).astype(int)
    assert a.raw[uv[1], uv[0]] < np.median(a.raw) and a.log_image[uv[1], uv[0]] > np.median(a.log_image)
    assert a.raw.dtype == np.uint16 and np.median(a.raw) == pytest.approx(0.8 * 65535, rel=0.02)


def test_blur_acts_on_intensity_and_matches_its_sigma():
    """A bead's blurred intensity deficit (1 − I) keeps its integral; blur σ widens its second
    moment by σ². Compared between two blurred images: the detector's pixels read the second
    moment of a blurred (smooth) image without bias, but not of the sharp one (there the
    pixel a sub-sample falls in, not its position, counts: −0.008 px² here)."""
    f = _features(points=[PointFeature("B", np.zeros(3), 2.0)])
    t = np.array([0.0, 0.0, 667.0])
    images = [
        1
        - np.exp(
            -render(
                f,
                np.eye(3),
                t,
                CAM_SMALL,
                ImagingModel(image_shape=(256, 256), photons_per_px=None, focal_spot_mm=0.0, detector_blur_px=s),
            ).line_integral
        )
        for s in (0.0, 1.0, 2.5)
    ]
    sharp, a, b = images
    assert b.sum() == pytest.approx(sharp.sum(), rel=1e-4) and a.sum() == pytest.approx(sharp.sum(), rel=1e-4)
    V, U = np.mgrid[0:256, 0:256]
    var = lambda w: (w * (U - 128.0) ** 2).sum() / w.sum()  # noqa: E731
    assert var(b) - var(a) == pytest.approx(2.5**2 - 1.0**2, rel=1e-3)


def test_needle_occluder_in_camera_frame():
    """A needle across the principal ray in X: the central ray meets its full diameter."""
    occ = Occluder((-40.0, 0.0, 600.0), (40.0, 0.0, 600.0), diameter=1.0, frame="X")
    im = ImagingModel(
        image_shape=(256, 256),
        photons_per_px=None,
        supersample=1,
        focal_spot_mm=0,
        detector_blur_px=0,
        single_precision=False,
    )
    img = render(_features(), _rot_y(30), np.array([0, 0, 667.0]), CAM_SMALL, im, occluders=[occ])
    assert img.line_integral[128, 128] == pytest.approx(im.mu("steel") * 1.0, rel=1e-6)
    assert img.truth["occluders"][0]["frame"] == "X"


def test_truncated_fiducial_renders_its_visible_part(features_2005):
    img = render(
        features_2005,
        np.eye(3) @ np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]], float),
        np.array([45.0, 0.0, 667.0]),
        CAM_SMALL,
        SMALL,
    )
    li = img.line_integral
    assert li[:, -3:].max() > 0.1 and li[:, :20].max() == 0.0


# ----------------------------------------------------------------------------- truth
def test_truth_projections_and_conics(features_2005, tmp_path):
    R, t = Workspace().sample(1, features_2005.nominal_beam_direction, np.random.default_rng(2))
    img = render(features_2005, R[0], t[0], imaging=ImagingModel(photons_per_px=None))
    tr = img.truth
    assert tr["format"] == "ftrac-radiograph-truth" and tr["pose"]["converged"] is True
    cam = Camera()
    for p in features_2005.points:
        np.testing.assert_allclose(tr["projected"]["points"][p.id], cam.project(R[0] @ p.center + t[0]), atol=1e-9)
    for el in features_2005.ellipses:
        uv = cam.project(el.sample(np.linspace(0, 6, 20)) @ R[0].T + t[0])
        A, B, C, D, E, F = tr["projected"]["ellipses"][el.id]["conic"]
        val = A * uv[:, 0] ** 2 + B * uv[:, 0] * uv[:, 1] + C * uv[:, 1] ** 2 + D * uv[:, 0] + E * uv[:, 1] + F
        grad = np.hypot(2 * A * uv[:, 0] + B * uv[:, 1] + D, B * uv[:, 0] + 2 * C * uv[:, 1] + E)
        assert np.abs(val / grad).max() < 1e-6  # on the conic, in pixels
    write_truth(tmp_path / "t.json", tr)
    back = read_truth(tmp_path / "t.json")
    np.testing.assert_array_equal(back["R"], R[0])
    assert back["camera_obj"] == cam
    assert ImagingModel.from_dict(back["imaging"]) == ImagingModel(photons_per_px=None)


# ----------------------------------------------------------------------------- image files
IMAGES = {
    "uint8": np.random.default_rng(0).integers(0, 256, (24, 40)).astype(np.uint8),
    "uint16": np.random.default_rng(1).integers(0, 65536, (24, 40)).astype(np.uint16),
    "float": np.random.default_rng(2).normal(1.0, 0.3, (24, 40)),
}


@pytest.mark.parametrize("suffix", [".png", ".tif", ".npy", ".dcm"])
@pytest.mark.parametrize("kind", list(IMAGES))
def test_image_round_trip(tmp_path, suffix, kind):
    arr = IMAGES[kind]
    cam = Camera(1100.0, (0.3, 0.31), (19.5, 11.0))
    path = write_image(tmp_path / f"a{suffix}", arr, cam, polarity="dense_dark")
    img, c, meta = read_image(path)
    assert img.dtype == np.float64 and img.shape == arr.shape
    values = img  # the recorded linear map is applied on reading
    if kind == "float":
        # quantised to 16 bits (PNG, DICOM), or float32 (TIFF, and every frame's pixels)
        step = np.ptp(arr) / 65535 if suffix in (".png", ".dcm") else 2e-7 * np.abs(arr).max()
        assert np.abs(values - arr).max() <= step
    else:
        np.testing.assert_array_equal(values, arr)
    if suffix == ".npy":
        assert meta["polarity_hint"] is None and c is None
    else:
        assert meta["polarity_hint"] == "dense_dark"
        assert meta["bits"] == (8 if kind == "uint8" else 32 if (kind, suffix) == ("float", ".tif") else 16)
    if suffix == ".dcm":
        assert c == cam  # tags + noted principal point
        import pydicom

        ds = pydicom.dcmread(path)
        assert [float(x) for x in ds.ImagerPixelSpacing] == [0.31, 0.3] and float(ds.DistanceSourceToDetector) == 1100
    else:
        assert c is None


def test_png_8_bit_float_quantisation(tmp_path):
    arr = IMAGES["float"]
    path = write_image(tmp_path / "a.png", arr, bit_depth=8, value_range=(0.0, 2.0))
    img, _, meta = read_image(path)
    assert meta["bits"] == 8
    assert np.abs(img - np.clip(arr, 0, 2)).max() <= 1 / 255 + 1e-6


def test_dicom_without_spacing_names_the_tag(tmp_path):
    import pydicom

    path = write_image(tmp_path / "a.dcm", IMAGES["uint16"], Camera())
    ds = pydicom.dcmread(path)
    del ds.ImagerPixelSpacing
    ds.save_as(tmp_path / "b.dcm")
    with pytest.raises(InputError, match=r"ImagerPixelSpacing \(0018,1164\)"):
        read_image(tmp_path / "b.dcm")
    img, cam, _ = read_image(tmp_path / "b.dcm", camera=Camera(900.0))  # --camera overrides
    assert cam == Camera(900.0) and img.shape == (24, 40)
    del ds.DistanceSourceToDetector
    ds.ImagerPixelSpacing = [0.2, 0.2]
    ds.save_as(tmp_path / "c.dcm")
    with pytest.raises(InputError, match=r"DistanceSourceToDetector \(0018,1110\)"):
        read_image(tmp_path / "c.dcm")


@pytest.mark.parametrize(
    "name,content",
    [("x.png", b"not a png"), ("x.tif", b"II*\0garbage"), ("x.npy", b"nope"), ("x.dcm", b"\0" * 200), ("x.jpg2", b"")],
)
def test_unreadable_image_is_input_error(tmp_path, name, content):
    (tmp_path / name).write_bytes(content)
    with pytest.raises(InputError):
        read_image(tmp_path / name)


def test_anatomy_background_is_seeded():
    a, b, c = anatomy((128, 160), seed=1), anatomy((128, 160), seed=1), anatomy((128, 160), seed=2)
    assert a.shape == (128, 160) and a.dtype == np.float32 and a.min() >= 0
    assert np.array_equal(a, b) and not np.array_equal(a, c)


# ----------------------------------------------------------------------------- command line
@pytest.fixture(scope="module")
def features_json(tmp_path_factory, features_2005):
    path = tmp_path_factory.mktemp("f") / "features.json"
    write_features(path, features_2005)  # design.source = the preset: the body is found
    return path


def test_radiograph_cli_writes_images_and_truth(tmp_path, features_json):
    out = tmp_path / "rg"
    assert (
        main(
            [
                "radiograph",
                "--features",
                str(features_json),
                "--workspace-sample",
                "2",
                "--seed",
                "3",
                "-o",
                str(out),
                "--format",
                "dicom",
                "--output-kind",
                "raw",
                "--image-size",
                "512",
                "512",
            ]
        )
        == 0
    )
    names = sorted(p.name for p in out.iterdir())
    assert names == ["img_0000.dcm", "img_0000.truth.json", "img_0001.dcm", "img_0001.truth.json", "truth.jsonl"]
    lines = (out / "truth.jsonl").read_text().splitlines()
    assert len(lines) == 2 and json.loads(lines[1])["image"] == "img_0001.dcm"
    tr = read_truth(out / "img_0000.truth.json")
    assert tr["body"]["outer_diameter"] == 30.0 and tr["output"] == "raw"
    img, cam, meta = read_image(out / "img_0000.dcm")
    assert cam == tr["camera_obj"] and meta["polarity_hint"] == "dense_dark" and img.shape == (512, 512)
    # same seed, same workspace poses as the shared sampler
    R, t = Workspace().sample(2, np.array([0, -1.0, 0]), np.random.default_rng(3))
    np.testing.assert_allclose(tr["R"], R[0])
    # a pose file gives one image per pose
    pose = tmp_path / "pose.json"
    pose.write_text(json.dumps({"rotation": R[1].tolist(), "translation_mm": t[1].tolist()}))
    out2 = tmp_path / "rg2"
    assert (
        main(
            [
                "radiograph",
                "--features",
                str(features_json),
                "--pose",
                str(pose),
                "-o",
                str(out2),
                "--no-noise",
                "--image-size",
                "256",
                "256",
                "--format",
                "npy",
            ]
        )
        == 0
    )
    assert (out2 / "img_0000.npy").exists()
    assert read_truth(out2 / "img_0000.truth.json")["imaging"]["photons_per_px"] is None
    # a background file in line-integral units (a quantised PNG with its rescale) is added in the log domain
    bg = np.full((256, 256), 0.5)
    write_image(tmp_path / "bg.png", bg, value_range=(0.0, 1.0))
    out3 = tmp_path / "rg3"
    assert (
        main(
            [
                "radiograph",
                "--features",
                str(features_json),
                "--pose",
                str(pose),
                "-o",
                str(out3),
                "--no-noise",
                "--image-size",
                "256",
                "256",
                "--format",
                "npy",
                "--background",
                str(tmp_path / "bg.png"),
            ]
        )
        == 0
    )
    a, b = np.load(out2 / "img_0000.npy"), np.load(out3 / "img_0000.npy")
    assert np.abs(b - a - 0.5).max() < 1e-4


@pytest.mark.parametrize(
    "extra,expect",
    [
        (["--pose", "MISSING.json"], "MISSING.json"),
        (["--pose", "BAD"], "rotation"),
        (["--workspace-sample", "1", "--pose", "BAD"], "exactly one"),
        (["--workspace-sample", "1", "--occluder", "1,2,3"], "--occluder"),
        (["--workspace-sample", "1", "--background", "MISSING.png"], "MISSING.png"),
    ],
)
def test_radiograph_cli_fails_cleanly(tmp_path, features_json, capsys, extra, expect):
    bad = tmp_path / "BAD"
    bad.write_text(json.dumps({"rotation": [[1, 0, 0], [0, 1, 0], [0, 0, 2]], "translation_mm": [0, 0, 600]}))
    extra = [str(tmp_path / e) if e in ("MISSING.json", "BAD", "MISSING.png") else e for e in extra]
    out = tmp_path / "rg"
    assert main(["radiograph", "--features", str(features_json), "-o", str(out), *extra]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and expect in err
    assert not out.exists() and not any(p.name.startswith(".rg") for p in tmp_path.iterdir())


def test_radiograph_cli_needs_a_body(tmp_path, features_2005, capsys):
    from dataclasses import replace

    path = tmp_path / "features.json"
    write_features(path, replace(features_2005, source=None))
    out = tmp_path / "rg"
    assert main(["radiograph", "--features", str(path), "--workspace-sample", "1", "-o", str(out)]) == 2
    assert "body" in capsys.readouterr().err and not out.exists()
    assert (
        main(
            [
                "radiograph",
                "--features",
                str(path),
                "--workspace-sample",
                "1",
                "-o",
                str(out),
                "--no-body",
                "--image-size",
                "128",
                "128",
            ]
        )
        == 0
    )


def test_a_ray_along_an_axis_gets_the_reference_chord_not_nan():
    """A ray exactly along the body's axis, or along a wire piece, meets no side wall in the
    reference chords (:func:`cylinder_z_chord`, :func:`tube_chord`); the fast per-pixel forms
    give the same, not ∞ / ∞ (NaN pixels once stopped a pixel comparison of two poses)."""
    c = np.array([12.5, 0.0, -600.0])
    g0, gu, gv = np.array([0.0, 0.0, 1.0]), np.array([1e-3, 0.0, 0.0]), np.array([0.0, 1e-3, 0.0])
    U, V = np.array([[0.0, 1.0]]), np.array([[0.0, 0.0]])
    fast_b = body_chord_uv(c, g0, gu, gv, 15.0, 10.0, 25.0, U, V)
    d = g0 + U.ravel()[:, None] * gu + V.ravel()[:, None] * gv
    ref_b = cylinder_z_chord(c, d, 15.0, 25.0) - cylinder_z_chord(c, d, 10.0, 25.0)
    assert np.all(np.isfinite(fast_b)) and np.abs(fast_b.ravel() - ref_b).max() < 1e-8
    pieces = straight_pieces(np.array([12.4, 0.0, -5.0]), np.array([12.4, 0.0, 5.0]), 0.25, 1.0, 0, 20.0)
    fast_t = tube_chord_uv(c, g0, gu, gv, pieces, np.zeros(1, int), U, V)
    k = [0, 0]
    ref_t = tube_chord(c, d, pieces.a[k], pieces.e[k], pieces.L[k], pieces.r[k], pieces.n0[k], pieces.n1[k])
    assert np.all(np.isfinite(fast_t)) and np.abs(fast_t.ravel() - ref_t).max() < 1e-8


def test_capsule_pixels_clipped_to_a_box_are_the_box_pixels_of_the_whole_in_order():
    """A box bounds the work (a pose near the source projects wires metres long) and changes
    nothing inside it: the same pixels, in the same order, as the unclipped enumeration
    filtered to the box; primitives wholly outside it give none."""
    from ftrac_design.xray.rays import capsule_pixels

    rng = np.random.default_rng(11)
    for _ in range(100):
        n = int(rng.integers(1, 6))
        u0, v0, u1, v1 = (rng.uniform(-50, 150, n) for _ in range(4))
        rad = rng.uniform(0.3, 20, n)
        r0, c0 = int(rng.integers(-10, 60)), int(rng.integers(-10, 60))
        box = (r0, r0 + int(rng.integers(1, 80)), c0, c0 + int(rng.integers(1, 80)))
        k, r, c = capsule_pixels(u0, v0, u1, v1, rad)
        inside = (r >= box[0]) & (r < box[1]) & (c >= box[2]) & (c < box[3])
        k2, r2, c2 = capsule_pixels(u0, v0, u1, v1, rad, box)
        assert np.array_equal(k[inside], k2) and np.array_equal(r[inside], r2) and np.array_equal(c[inside], c2)
    far = capsule_pixels(np.array([1e6]), np.array([1e6]), np.array([2e6]), np.array([1e6]), np.array([3.0]), box)
    assert all(len(a) == 0 for a in far)
