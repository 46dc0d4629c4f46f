"""The held-out renderer in benchmarks/independent/ against closed forms.

Chords through the steel meshes (a ball, a wire piece) match the ideal solids to 1 µm; a
noise-free monochromatic image of one ball carries the sphere's closed-form total
attenuation (∫(1 − e^{−μ c}) dA, which blurring preserves) within 0.5 %; the CAD body alone
matches the analytic hollow cylinder away from its pockets; the tungsten spectrum's mean
energy is the Kramers closed form unfiltered and in the expected range filtered.
"""

from __future__ import annotations

import hashlib
import json
import math
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("embreex", reason="the independent renderer casts rays with Embree (pip install embreex)")
pytest.importorskip("cadquery", reason="the independent renderer renders the CAD build (needs CadQuery)")
pytest.importorskip("numba", reason="the independent renderer's DRR is compiled with numba")

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

from independent import RenderSettings, render_independent  # noqa: E402
from independent.attenuation import linear_attenuation  # noqa: E402
from independent.detector import DetectorModel  # noqa: E402
from independent.fiducial import (  # noqa: E402
    CACHE_ENV,
    assemble,
    ball_mesh,
    build_digest,
    cylinder_mesh,
    load_scene,
)
from independent.raycast import material_chords  # noqa: E402
from independent.render import renderer_digest  # noqa: E402
from independent.spectrum import kramers_bins, kramers_mean_energy, tungsten_spectrum  # noqa: E402
from independent_check import reusable  # noqa: E402

from ftrac_design.features import Features  # noqa: E402
from ftrac_design.pose import Camera  # noqa: E402
from ftrac_design.pose.simulate import rotations_from_beams  # noqa: E402

PRESET = "nine_bead"  # no wires: the quickest build, balls apart in the AP view
CAM = Camera(principal_point_px=(128.0, 128.0))
SMALL = RenderSettings(image_shape=(256, 256))
SHARP = replace(SMALL, detector=DetectorModel(glare_fraction=0.0, mtf_core_cyc_mm=1e9))
MU_KEV = 60.0


@pytest.fixture(scope="module")
def build_cache(tmp_path_factory):
    """Point the renderer's build cache at a temporary folder for this module."""
    mp = pytest.MonkeyPatch()
    mp.setenv(CACHE_ENV, str(tmp_path_factory.mktemp("independent_cache")))
    load_scene.cache_clear()
    yield
    load_scene.cache_clear()
    mp.undo()


def _empty_features() -> Features:
    return Features(name="t", source=None, sha256=None, nominal_beam_direction=np.array([0.0, -1.0, 0.0]))


def _rays_near(center, axis_or_none, radius, n, rng, limit):
    """Random unit rays whose distance to ``center`` (or to the line through it along
    ``axis``) is at most ``limit × radius``; returns origins 40 mm back, directions, distances."""
    d = rng.standard_normal((n, 3))
    if axis_or_none is not None:  # keep the rays within 30° of perpendicular to the axis
        a = axis_or_none / np.linalg.norm(axis_or_none)
        d -= np.outer(d @ a, a) * 0.9
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    e1 = np.cross(d, [0.3, 0.5, 0.8])
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    e2 = np.cross(d, e1)
    b = limit * radius * np.sqrt(rng.uniform(0, 1, n))
    ang = rng.uniform(0, 2 * np.pi, n)
    foot = center + b[:, None] * (np.cos(ang)[:, None] * e1 + np.sin(ang)[:, None] * e2)
    return foot - 40 * d, d


def test_ball_chord_matches_the_sphere():
    rng = np.random.default_rng(3)
    c, r = np.array([1.0, -2.0, 3.0]), 1.0
    scene = assemble(_empty_features(), [("ball", "steel", ball_mesh(c, r))])
    o, d = _rays_near(c, None, r, 4000, rng, 0.95)
    chord = material_chords(scene, o, d)
    w = o - c
    b2 = np.einsum("ij,ij->i", w, w) - np.einsum("ij,ij->i", w, d) ** 2
    exact = 2 * np.sqrt(r * r - b2)
    assert chord["unpaired"] == 0
    assert np.max(np.abs(chord["steel"] - exact)) <= 1e-3  # mm: 1 µm
    assert np.all(chord["acetal"] == 0)


def test_wire_chord_matches_the_cylinder():
    rng = np.random.default_rng(4)
    a, b, r = np.array([0.0, 0.0, -10.0]), np.array([2.0, 1.0, 10.0]), 0.25
    axis = (b - a) / np.linalg.norm(b - a)
    mid = (a + b) / 2
    scene = assemble(_empty_features(), [("wire", "steel", cylinder_mesh(a, b, r))])
    o, d = _rays_near(mid, axis, r, 4000, rng, 0.9)
    chord = material_chords(scene, o, d)
    # distance between the ray and the axis line, and the ray's angle to the axis
    n = np.cross(d, axis)
    sin_t = np.linalg.norm(n, axis=1)
    dist = np.abs(np.einsum("ij,ij->i", o - a, n)) / sin_t
    exact = 2 * np.sqrt(r * r - dist**2) / sin_t
    assert chord["unpaired"] == 0
    assert np.max(np.abs(chord["steel"] - exact)) <= 1e-3


def _ap_pose(features, t=(4.0, -3.0, 667.0), roll=0.3):
    R = rotations_from_beams(np.asarray(features.nominal_beam_direction, float)[None], np.array([roll]))[0]
    return R, np.asarray(t, float)


def _energy(counts, truth, settings):
    """Expected energy per pixel / open-field energy (the transmission) of a noise-free image."""
    e = (counts.astype(float) - settings.detector.offset_adu) / truth["gain_adu_per_kev"]
    return e / (truth["open_field_quanta_per_px"] * MU_KEV)


def test_ball_total_attenuation_matches_the_closed_form(build_cache):
    scene = load_scene(PRESET, body=False)
    R, t = _ap_pose(scene.features)
    counts, truth = render_independent(
        PRESET,
        R,
        t,
        CAM,
        mono_kev=MU_KEV,
        patient=False,
        noise=False,
        body=False,
        settings=replace(SMALL, detector=DetectorModel(glare_fraction=0.0)),
    )
    T = _energy(counts, truth, SMALL)
    uv = np.array(list(truth["points_px"].values()))
    gaps = np.linalg.norm(uv[:, None] - uv[None], axis=-1) + np.eye(len(uv)) * 1e9
    k = int(np.argmax(gaps.min(1)))  # the ball farthest from the others
    win = 0.45 * gaps[k].min()
    vv, uu = np.mgrid[0:256, 0:256]
    mask = np.hypot(uu - uv[k, 0], vv - uv[k, 1]) <= win
    measured = float(np.sum(1.0 - T[mask]))  # px²
    p = scene.features.points[k]
    X = R @ p.center + t
    D, Z = float(np.linalg.norm(X)), float(X[2])
    r, mu = p.diameter / 2, float(linear_attenuation("steel", MU_KEV))
    sphere = math.pi / 2 * (2 * r * r - (1 - math.exp(-2 * mu * r) * (1 + 2 * mu * r)) / mu**2)  # mm² at the ball
    expected = sphere * CAM.focal_length_mm**2 * D / Z**3 / (CAM.pixel_size_mm[0] * CAM.pixel_size_mm[1])
    assert measured == pytest.approx(expected, rel=0.005)


def _hollow_cylinder_chord(o, d, r_out, r_in, half):
    """Chord (mm) of rays o + s d through {r_in ≤ |xy| ≤ r_out, |z| ≤ half} (F, axis z)."""

    def through(r):
        a = d[:, 0] ** 2 + d[:, 1] ** 2
        bq = o[:, 0] * d[:, 0] + o[:, 1] * d[:, 1]
        c = o[:, 0] ** 2 + o[:, 1] ** 2 - r * r
        disc = bq * bq - a * c
        ok = disc > 0
        sq = np.sqrt(np.where(ok, disc, 0.0))
        s1, s2 = (-bq - sq) / a, (-bq + sq) / a
        z1, z2 = (-half - o[:, 2]) / d[:, 2], (half - o[:, 2]) / d[:, 2]
        lo = np.maximum(s1, np.minimum(z1, z2))
        hi = np.minimum(s2, np.maximum(z1, z2))
        return np.where(ok, np.clip(hi - lo, 0.0, None), 0.0)

    return through(r_out) - through(r_in)


def test_body_alone_matches_the_hollow_cylinder(build_cache):
    scene = load_scene(PRESET, steel=False)
    R, t = _ap_pose(scene.features, roll=0.0)
    counts, truth = render_independent(
        PRESET, R, t, CAM, mono_kev=MU_KEV, patient=False, noise=False, steel=False, focal_spot_mm=0.0, settings=SHARP
    )
    p_mesh = -np.log(_energy(counts, truth, SHARP))
    # the analytic body through the same 4 × 4 sub-samples of every pixel
    s = SHARP.subsample
    off = (np.arange(s) + 0.5) / s - 0.5
    vv, uu = np.mgrid[0:256, 0:256].astype(float)
    U = np.broadcast_to(uu[..., None, None] + off[None, None, None, :], (256, 256, s, s)).reshape(-1)
    V = np.broadcast_to(vv[..., None, None] + off[None, None, :, None], (256, 256, s, s)).reshape(-1)
    d = (
        np.stack(
            [
                (U - CAM.principal_point_px[0]) * CAM.pixel_size_mm[0],
                (V - CAM.principal_point_px[1]) * CAM.pixel_size_mm[1],
                np.full(U.size, CAM.focal_length_mm),
            ],
            -1,
        )
        @ R
    )
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    o = np.broadcast_to(-R.T @ t, d.shape)
    r_out, r_in, half = 15.0, 10.0, 25.0
    mu = float(linear_attenuation("acetal", MU_KEV))
    chord = _hollow_cylinder_chord(o, d, r_out, r_in, half).reshape(256, 256, s * s)
    p_exact = -np.log(np.mean(np.exp(-mu * chord), axis=-1))
    # compare where neither a silhouette (facets), a ball pocket, nor the end faces' key slot is near
    oc = o.reshape(256, 256, s * s, 3)[:, :, 0]
    dc = d.reshape(256, 256, s * s, 3).mean(2)
    dist = np.abs(oc[..., 0] * dc[..., 1] - oc[..., 1] * dc[..., 0]) / np.hypot(dc[..., 0], dc[..., 1])
    sz = -(oc[..., 0] * dc[..., 0] + oc[..., 1] * dc[..., 1]) / (dc[..., 0] ** 2 + dc[..., 1] ** 2)
    z_at = oc[..., 2] + sz * dc[..., 2]
    keep = (np.abs(dist - r_out) > 0.6) & (np.abs(dist - r_in) > 0.6) & (dist < r_out) & (np.abs(z_at) < half - 4)
    for c in truth["points_px"].values():
        keep &= np.hypot(uu - c[0], vv - c[1]) > 9.0
    assert keep.sum() > 5000
    err = np.abs(p_mesh - p_exact)[keep]
    assert np.median(err) < 5e-4
    assert err.max() < mu * 0.05  # 0.05 mm of acetal: the STL's 0.01 mm facets, seen obliquely


def test_spectrum_mean_energy():
    for kvp in (70.0, 80.0, 90.0):
        e, w = kramers_bins(kvp)
        assert float(np.sum(e * w)) == pytest.approx(kramers_mean_energy(kvp), rel=1e-12)
    spec = tungsten_spectrum(80.0, 3.0, 0.1)
    # tabulated tungsten spectra at 80 kV behind ~3 mm Al + 0.1 mm Cu have mean photon energies
    # in the mid-40s keV (hardened well above the unfiltered Kramers mean of 25 keV)
    assert 43.0 <= spec.mean_energy_kev <= 50.0
    assert spec.mean_energy_kev > tungsten_spectrum(80.0, 3.0, 0.0).mean_energy_kev
    assert np.sum(spec.photons) == pytest.approx(1.0)


def test_same_seed_same_image(build_cache):
    scene = load_scene(PRESET)
    R, t = _ap_pose(scene.features)
    a, _ = render_independent(PRESET, R, t, CAM, patient=False, seed=5, settings=SMALL, dose_behind_patient=2000)
    b, _ = render_independent(PRESET, R, t, CAM, patient=False, seed=5, settings=SMALL, dose_behind_patient=2000)
    c, _ = render_independent(PRESET, R, t, CAM, patient=False, seed=6, settings=SMALL, dose_behind_patient=2000)
    assert a.dtype == np.uint16 and a.shape == (256, 256)
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)


def test_a_saved_image_names_the_build_and_the_renderer_it_was_drawn_with(build_cache):
    """The truth of an image holds the digest of the build it was drawn from and of the
    renderer's source: a saved image of parts the package no longer builds is not reused."""
    scene = load_scene(PRESET)
    digest = build_digest(scene.build_dir)
    h = hashlib.sha256()
    for name in ("fiducial.stl", "features.json"):
        h.update((scene.build_dir / name).read_bytes())
    assert digest == h.hexdigest()
    R, t = _ap_pose(scene.features)
    img, truth = render_independent(PRESET, R, t, CAM, patient=False, seed=5, settings=SMALL, noise=False)
    assert truth["build_sha256"] == digest and truth["renderer_sha256"] == renderer_digest()
    folder = scene.build_dir.parent
    png, js = folder / "img.png", folder / "img.json"
    png.write_bytes(b"")
    js.write_text(json.dumps(truth))
    assert reusable(png, js, R, t, 5, truth["dose_behind_patient"], digest)
    assert not reusable(png, js, R, t, 5, truth["dose_behind_patient"], "0" * 64)
    js.write_text(json.dumps({**truth, "renderer_sha256": "0" * 64}))
    assert not reusable(png, js, R, t, 5, truth["dose_behind_patient"], digest)


def test_the_build_cache_is_keyed_on_the_package_code(build_cache, monkeypatch):
    """A change to the package's code moves the build to another folder (built again), so a
    CAD change is never hidden by an old build of the same design file."""
    import independent.fiducial as fid

    here = fid.build_path(PRESET)
    assert here.parent.name == fid.design_path(PRESET).stem
    monkeypatch.setattr(fid, "code_fingerprint", lambda: "another")
    assert fid.build_path(PRESET) != here and fid.build_path(PRESET).parent == here.parent
