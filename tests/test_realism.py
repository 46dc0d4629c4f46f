"""Realistic test images: the patient's line integrals, the C-arm's image chain and the named
conditions, against closed forms (window/level/gamma, unsharp mask, field shapes, blade
transmission, chords of bone, seeds' integrated attenuation, the dose helper)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from ftrac_design.errors import InputError
from ftrac_design.pose.camera import Camera
from ftrac_design.xray.display import (
    Detector,
    Display,
    Shutter,
    apply_chain,
    apply_gamma,
    n0_for_counts,
    round_field,
    unsharp_mask,
    window_level,
)
from ftrac_design.xray.materials import linear_attenuation, mass_attenuation
from ftrac_design.xray.patient import (
    Placement,
    clips,
    patient,
    patient_model,
    render_patient,
    seed_line_integral_sum,
    seeds,
)
from ftrac_design.xray.scenario import CONDITIONS, realistic_image
from ftrac_design.xray.solids import Canal, Column, Tube, capsule_chord, capsule_volume
from ftrac_design.xray.truth import projected_features


# ----------------------------------------------------------------------------- materials
def test_tissue_attenuation_is_nist_table_4():
    # NIST SRD 126 Table 4 (ICRU-44 tissues) and Table 3 (Ti) at 60 keV, cm²/g
    for name, mu_rho in (
        ("soft_tissue", 0.2048),
        ("adipose", 0.1974),
        ("cortical_bone", 0.3148),
        ("air", 0.1875),
        ("titanium", 0.7661),
        ("lung", 0.2053),
    ):
        assert mass_attenuation(name, 60.0) == pytest.approx(mu_rho, rel=1e-6)
    assert linear_attenuation("soft tissue", 60.0) == pytest.approx(0.2048 * 1.06 / 10)
    # spongiosa: cortical bone and marrow mixed to 1.18 g/cm³
    f = (1.18 - 1.06) / (1.92 - 1.06)
    mu = f * linear_attenuation("cortical_bone", 60) + (1 - f) * linear_attenuation("soft_tissue", 60)
    assert linear_attenuation("trabecular bone", 60.0) == pytest.approx(mu, rel=1e-9)
    assert linear_attenuation("acetal (POM-C)", 60.0) == pytest.approx(0.0273, abs=2e-4)  # unchanged


# ----------------------------------------------------------------------------- display functions
def test_window_level_and_gamma_closed_forms():
    s = np.array([1.0, 1.5, 2.0, 2.5, 3.0, 4.0], np.float32)
    x = window_level(s, centre=2.0, width=2.0)
    np.testing.assert_allclose(x, [0.0, 0.25, 0.5, 0.75, 1.0, 1.0])
    np.testing.assert_allclose(apply_gamma(x, 2.0), [0.0, 0.0625, 0.25, 0.5625, 1.0, 1.0])
    np.testing.assert_allclose(apply_gamma(np.float32([0.25]), 0.5), [0.5])


@pytest.mark.parametrize("polarity", ["dense-bright", "dense-dark"])
def test_display_chain_maps_known_line_integrals(polarity):
    # a huge dose makes the noise negligible: the stored grey levels follow the closed form
    p = np.repeat(np.linspace(0.5, 3.5, 64, dtype=np.float32)[None, :], 32, axis=0)
    n0 = 1e9
    det = Detector(bits=16, gain=5e4 / n0, offset=0.0)
    disp = Display("display", window=(2.0, 2.0), gamma=0.7, polarity=polarity, bits=8)
    img, info = apply_chain(line_integral=p, n0=n0, detector=det, display=disp, rng=np.random.default_rng(0))
    y = np.clip((p - 1.0) / 2.0, 0, 1) ** 0.7
    want = np.rint(255 * (y if polarity == "dense-bright" else 1 - y))
    assert img.dtype == np.uint8 and info["polarity"] == polarity and info["formation"] == "display"
    assert np.abs(img.astype(int) - want).max() <= 1


def test_unsharp_mask_constant_and_gains():
    c = np.full((40, 50), 3.25, np.float32)
    np.testing.assert_allclose(unsharp_mask(c, 4.0, 1.5), c, rtol=1e-6)
    # a sinusoid of f cycles/px is amplified by 1 + amount (1 − exp(−2π²σ²f²))
    f, sigma, amount = 1 / 16, 2.0, 1.0
    x = np.arange(256, dtype=np.float32)
    img = np.repeat(np.sin(2 * np.pi * f * x)[None, :], 8, axis=0)
    out = unsharp_mask(img, sigma, amount)[4, 64:192]
    gain = float(np.abs(out).max())
    assert gain == pytest.approx(1 + amount * (1 - math.exp(-2 * math.pi**2 * sigma**2 * f**2)), rel=0.01)
    # a step of height h overshoots by amount h (1/2 − g0/2), g0 the kernel's centre ≈ 1/(√(2π) σ)
    h, sigma, amount = 2.0, 3.0, 0.8
    step = np.zeros((8, 200), np.float32)
    step[:, 100:] = h
    out = unsharp_mask(step, sigma, amount)[4]
    g0 = 1 / (math.sqrt(2 * math.pi) * sigma)
    assert out[100] - h == pytest.approx(amount * h * (0.5 - g0 / 2), rel=0.01)
    assert out[0] == pytest.approx(0, abs=1e-6) and out[-1] == pytest.approx(h, rel=1e-6)


def test_round_field_area():
    r = 300.0
    w = round_field((1024, 1024), (511.5, 511.5), r, edge_px=1.5)
    assert w.sum() == pytest.approx(math.pi * r * r, rel=2e-4)
    _, info = apply_chain(
        np.full((1024, 1024), 1e4, np.float32),
        Detector(gain=0.5),
        Display("linear"),
        Shutter("round", (511.5, 511.5), r),
        np.random.default_rng(1),
    )
    assert abs(int(info["field_mask"].sum()) - math.pi * r * r) <= 2 * math.pi * r
    assert info["field_mask"][512, 512] and not info["field_mask"][0, 0]


def test_round_field_is_black_outside_in_either_polarity():
    for pol in ("dense-dark", "dense-bright"):
        img, info = apply_chain(
            np.full((256, 256), 2e3, np.float32),
            Detector(gain=1.0),
            Display("display", polarity=pol),
            Shutter("round", None, 100.0),
            np.random.default_rng(2),
        )
        assert img[0, 0] == 0 and img[-1, -1] == 0 and img[128, 128] > 0


def test_blades_pass_their_transmission_and_stay_noisy():
    n0, T = 1e5, 0.05
    sh = Shutter(
        "blades", (511.5, 511.5), opening_px=(200.0, math.inf, math.inf, math.inf), transmission=T, penumbra_px=2.0
    )
    det = Detector(bits=16, gain=0.5, offset=100.0)
    img, info = apply_chain(np.full((1024, 1024), n0, np.float32), det, Display("linear"), sh, np.random.default_rng(3))
    q = (img.astype(float) - det.offset) / det.gain
    under, open_ = q[:, :250], q[:, 400:]
    assert under.mean() / open_.mean() == pytest.approx(T, rel=0.01)
    # photons are cut before the noise: the relative noise grows as 1/√(T N0)
    assert under.std() / under.mean() == pytest.approx(1 / math.sqrt(T * n0), rel=0.05)
    assert not info["field_mask"][:, :250].any() and info["field_mask"][:, 400:].all()


def test_dose_helper_sets_the_median_behind_the_patient():
    bg = patient((256, 256), seed=3, kind="pelvis", pixel_mm=1.7)
    for counts in (150.0, 3000.0):
        n0 = n0_for_counts(bg, counts)
        behind = bg > 0.5
        assert np.median(n0 * np.exp(-bg[behind].astype(float))) == pytest.approx(counts, rel=1e-6)
    n0 = n0_for_counts(bg, 400.0, statistic="mean")
    assert np.mean(n0 * np.exp(-bg[bg > 0.5].astype(float))) == pytest.approx(400.0, rel=1e-6)


def test_log_formation_recovers_the_line_integral():
    p = np.repeat(np.linspace(0.0, 5.0, 50, dtype=np.float32)[None, :], 64, axis=0)
    n0 = 1e6
    img, info = apply_chain(
        line_integral=p,
        n0=n0,
        detector=Detector(bits=16, gain=0.06),
        display=Display("log"),
        rng=np.random.default_rng(4),
    )
    assert img.dtype == np.float32 and info["polarity"] == "dense-bright"
    # mean over rows: unbiased to the noise's 1/√(N) / √64
    np.testing.assert_allclose(img.mean(0), p[0], atol=0.02)


# ----------------------------------------------------------------------------- solids and the patient
def test_capsule_chord_matches_point_sampling():
    rng = np.random.default_rng(5)
    p0, p1, r = np.array([0.3, -0.2, 1.0]), np.array([2.5, 1.4, -1.7]), 0.4
    z = np.linspace(-4, 4, 200_001)
    for x, y in rng.uniform(-0.5, 3.0, (25, 2)):
        P = np.c_[np.full_like(z, x), np.full_like(z, y), z]
        d = P - p0
        s = np.clip(d @ (p1 - p0) / np.dot(p1 - p0, p1 - p0), 0, 1)
        inside = np.linalg.norm(d - s[:, None] * (p1 - p0), axis=1) <= r
        assert float(capsule_chord(np.array(x), np.array(y), p0, p1, r)) == pytest.approx(inside.mean() * 8.0, abs=2e-3)


def test_arc_tube_column_and_canal_closed_forms():
    tube = Tube((0.0, 0.0), half_width=5.0, depth=4.0, wall=1.0, radius=50.0, angles=(0.0, math.pi / 2))
    d = np.array([0.0, 2.0, 4.5])  # across the arc at 45°
    x, y = (50 + d) * math.cos(math.pi / 4), (50 + d) * math.sin(math.pi / 4)
    wall, core = tube.chords(x, y, 0.1)
    outer = 8 * np.sqrt(1 - (d / 5) ** 2)
    inner = 6 * np.sqrt(np.maximum(1 - (d / 4) ** 2, 0))
    np.testing.assert_allclose(core, inner, atol=1e-5)
    np.testing.assert_allclose(wall, outer - inner, atol=1e-5)
    col = Column((0.0, 0.0), 20.0, 15.0, 12.0, wall=1.0, plate=1.0, plate_fill=0.5)
    w, c = col.chords(np.array([0.0, 0.0, 0.0]), np.array([0.0, 11.5, 13.0]), 0.1)
    np.testing.assert_allclose(w + c, [30.0, 30.0, 0.0], atol=1e-5)
    np.testing.assert_allclose(w, [2.0, 2.0 + 14.0, 0.0], atol=1e-5)  # end plate: half its core depth solid
    can = Canal((0.0, 0.0), (6.0, 8.0), 20.0, wall=1.5)
    w, c = can.chords(np.array([0.0, 0.0, 0.0]), np.array([0.0, 7.5, 9.0]), 0.01)
    np.testing.assert_allclose(w, [0.0, 20.0, 0.0], atol=1e-5)
    np.testing.assert_allclose(c, [20.0, 0.0, 0.0], atol=1e-5)


@pytest.mark.parametrize("kind", ["pelvis", "spine"])
def test_patient_dynamic_range_air_to_bone(kind):
    for seed in range(3):
        p = patient((512, 512), seed=seed, kind=kind, pixel_mm=0.88)
        assert p.dtype == np.float32
        assert p.min() <= 0.01 and p.max() >= 5.0 and p.max() <= 8.5


def test_patient_is_seeded():
    a = patient((256, 256), seed=9, kind="chest", pixel_mm=1.76)
    assert np.array_equal(a, patient((256, 256), seed=9, kind="chest", pixel_mm=1.76))
    assert not np.array_equal(a, patient((256, 256), seed=10, kind="chest", pixel_mm=1.76))


def test_femoral_head_profile_is_the_chord_of_a_cortical_shell():
    model = patient_model("pelvis", 4)
    k, st = next((k, s) for k, s in enumerate(model.structures) if s.name == "femoral head")
    model = dataclasses.replace(model, placement=Placement(st.shape.center, 0.0, False, 1.0))
    pix, mag, E = 0.44, 1.3, 60.0
    full = render_patient(model, (257, 257), pix, mag, E)
    rest = render_patient(
        dataclasses.replace(model, structures=model.structures[:k] + model.structures[k + 1 :]), (257, 257), pix, mag, E
    )
    rho = np.abs(np.arange(257) - 128.0) * pix / mag  # mm from the head's centre along row 128
    R, w = st.shape.axes[0], st.shape.wall
    outer = 2 * np.sqrt(np.maximum(R * R - rho**2, 0))
    inner = 2 * np.sqrt(np.maximum((R - w) ** 2 - rho**2, 0))
    mu_s, mu_c, mu_t = (linear_attenuation(m, E) for m in ("soft_tissue", "cortical_bone", "trabecular_bone"))
    want = (mu_c - mu_s) * (outer - inner) + (mu_t - mu_s) * inner
    got = (full - rest)[128].astype(float)
    np.testing.assert_allclose(got, want, atol=2e-4)
    # a sharp cortical edge: from nothing to over a third of the rim's peak within one pixel
    edge = int(np.argmax(want > 0))
    assert got[edge - 1] == pytest.approx(0, abs=1e-6) and got[edge] > 0.33 * want.max()


def test_seeds_integrated_attenuation_is_mu_volume_over_pixel_area():
    rng = np.random.default_rng(6)
    img = seeds((160, 160), 12, rng, (80, 80), 50, pixel_mm=0.44, magnification=1.4, supersample=8)
    want = seed_line_integral_sum(12, pixel_mm=0.44, magnification=1.4)
    assert img.sum() == pytest.approx(want, rel=0.01)
    # closed clips: two touching legs, each a capsule of the leg's length
    img = clips((160, 160), 3, rng, (80, 80), 40, pixel_mm=0.44, magnification=1.4, supersample=8)
    px = 0.44 / 1.4
    want = 3 * 2 * linear_attenuation("titanium", 60.0) * capsule_volume(7.0, 0.4) / px**2
    assert img.sum() == pytest.approx(want, rel=0.01)


# ----------------------------------------------------------------------------- conditions
@pytest.fixture(scope="module")
def pose(features_2005):
    from ftrac_design.pose.simulate import Workspace

    R, t = Workspace().sample(1, features_2005.nominal_beam_direction, np.random.default_rng(11))
    return R[0], t[0]


@pytest.mark.parametrize("condition", CONDITIONS)
def test_condition_image_and_info(condition, features_2005, pose):
    R, t = pose
    img, info = realistic_image(features_2005, R, t, Camera(), condition, seed=1)
    want = {"linear": np.uint16, "log": np.float32, "display": np.uint8}[info["formation"]]
    assert img.shape == (1024, 1024) and img.dtype == want
    assert info["condition"] == condition and info["polarity"] in ("dense-dark", "dense-bright")
    # every feature projects inside the exposed field
    proj = projected_features(features_2005, R, t, Camera())
    uv = np.array(list(proj["points"].values()) + [p for ln in proj["lines"].values() for p in ln.values()])
    mask = info["field_mask"]
    assert mask[np.rint(uv[:, 1]).astype(int), np.rint(uv[:, 0]).astype(int)].all()
    if condition == "fluoro-dose":
        assert 100 <= info["counts_behind_patient"] <= 500
    if condition == "blur-2px":
        assert 1.6 <= info["blur_sigma_px"] <= 2.0 + 1e-9
    if condition == "strong-anatomy":
        assert info["patient"]["kind"] in ("pelvis", "spine") and info["patient"]["landmark"]
    if condition == "seeds-needle":
        assert info["seeds"] >= 30 and len(info["needles"]) >= 1
    if condition == "display-dark" or condition == "display-bright":
        # beads (steel) read darker than the ring around them in dense-dark, brighter in dense-bright
        pts = np.array(list(proj["points"].values()))
        at = np.array([img[int(round(v)), int(round(u))] for u, v in pts], float)
        ring = np.array([np.median(img[int(v) - 12 : int(v) + 13, int(u) - 12 : int(u) + 13]) for u, v in pts], float)
        sign = 1 if condition == "display-bright" else -1
        assert np.median(sign * (at - ring)) > 0


def test_condition_images_are_seeded(features_2005, pose):
    R, t = pose
    a, ia = realistic_image(features_2005, R, t, condition="round-shutter", seed=5)
    b, ib = realistic_image(features_2005, R, t, condition="round-shutter", seed=5)
    c, _ = realistic_image(features_2005, R, t, condition="round-shutter", seed=6)
    assert np.array_equal(a, b) and np.array_equal(ia["field_mask"], ib["field_mask"])
    assert not np.array_equal(a, c)


@pytest.mark.parametrize(
    "call",
    [
        lambda f, R, t: realistic_image(f, R, t, condition="cloudy"),
        lambda f, R, t: patient((64, 64), kind="knee"),
        lambda f, R, t: Display(bits=7),
        lambda f, R, t: Display(polarity="inverted"),
        lambda f, R, t: Detector(bits=10),
        lambda f, R, t: Shutter("oval"),
        lambda f, R, t: apply_chain(np.full((8, 8), -1.0)),
        lambda f, R, t: n0_for_counts(np.zeros((4, 4)), 0.0),
    ],
)
def test_bad_settings_are_input_errors(call, features_2005, pose):
    with pytest.raises(InputError):
        call(features_2005, *pose)
