"""4-axis groove export: grooves.csv round-trips onto the feature centre-lines within 1 µm,
and the DXF of the unwrapped surface re-reads with ezdxf."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ftrac_design.design import load_design
from ftrac_design.design.presets import PRESETS_DIR
from ftrac_design.features import compute_features
from ftrac_design.manufacture.profiles import PROFILES, cut_sizes
from ftrac_design.manufacture.unwrap import (
    CSV_COLUMNS,
    LAYERS,
    STEP_DEG,
    chord_error,
    read_grooves_csv,
    unwrap_features,
    write_grooves_csv,
    write_grooves_dxf,
)

MODELS = PRESETS_DIR
PRESETS = ("ftrac_2005", "ftrac_mini", "nine_bead")
MICRON = 1e-3


def wrap(theta_deg, z, r):
    t = np.radians(theta_deg)
    return np.column_stack([r * np.cos(t), r * np.sin(t), z])


def distance_to_ellipse(e, pts: np.ndarray) -> np.ndarray:
    """Distance (mm) from points to ellipse ``e``, by dense sampling refined with Newton steps."""
    s = np.linspace(0, 2 * np.pi, 2000, endpoint=False)
    curve = e.sample(s)
    k = np.argmin(np.linalg.norm(pts[:, None, :] - curve[None, :, :], axis=2), axis=1)
    t = s[k]
    for _ in range(12):  # minimise |p - c(t)|^2
        c = e.sample(t)
        d1 = -e.semi_major * np.sin(t)[:, None] * e.major_axis + e.semi_minor * np.cos(t)[:, None] * e.minor_axis
        d2 = -(c - e.center)
        g = np.sum((c - pts) * d1, axis=1)
        h = np.sum(d1 * d1, axis=1) + np.sum((c - pts) * d2, axis=1)
        t = t - g / h
    return np.linalg.norm(e.sample(t) - pts, axis=1)


def distance_to_segment(a, b, pts):
    d = b - a
    t = np.clip((pts - a) @ d / (d @ d), 0, 1)
    return np.linalg.norm(a + t[:, None] * d - pts, axis=1)


@pytest.mark.parametrize("preset", PRESETS)
@pytest.mark.parametrize("profile", PROFILES)
def test_csv_round_trip_within_a_micron(tmp_path, preset, profile):
    d = load_design(MODELS / f"{preset}.toml")
    f = compute_features(d)
    cuts = cut_sizes(d, profile)
    path = write_grooves_csv(tmp_path / "grooves.csv", unwrap_features(f, d.outer_radius, cuts))
    header = path.read_text().splitlines()[0].split(",")
    assert tuple(header) == CSV_COLUMNS
    back = {p.feature: p for p in read_grooves_csv(path)}
    assert set(back) == set(f.ids)
    for e in f.ellipses:
        p = back[e.id]
        assert p.kind == "ellipse" and p.theta_deg[0] == 0 and p.theta_deg[-1] == 360
        assert np.all(np.diff(p.theta_deg) == pytest.approx(STEP_DEG))
        verts = wrap(p.theta_deg, p.z, p.seat_radius)
        assert distance_to_ellipse(e, verts).max() < MICRON
        # the A/Z-linear toolpath between vertices (segment midpoints) stays on the centre-line too
        mids = wrap((p.theta_deg[1:] + p.theta_deg[:-1]) / 2, (p.z[1:] + p.z[:-1]) / 2, p.seat_radius)
        assert distance_to_ellipse(e, mids).max() < MICRON
        assert p.depth == pytest.approx(d.outer_radius - d.ellipse_seat_radius + d.wire.diameter / 2, abs=1e-9)
        assert p.cut_width == pytest.approx(cuts.groove_width)
    for ln in f.lines:
        p = back[ln.id]
        verts = wrap(p.theta_deg, p.z, p.seat_radius)
        assert np.linalg.norm(verts[0] - ln.start) < MICRON and np.linalg.norm(verts[-1] - ln.end) < MICRON
        assert p.depth == pytest.approx(d.outer_radius - d.line_seat_radius + d.wire.diameter / 2, abs=1e-9)
    for pt in f.points:
        p = back[pt.id]
        assert p.kind == "pocket" and len(p.z) == 1
        assert np.linalg.norm(wrap(p.theta_deg, p.z, p.seat_radius)[0] - pt.center) < MICRON
        assert p.cut_width == pytest.approx(cuts.pocket_diameter)
        assert p.depth == pytest.approx(d.outer_radius - math.hypot(*pt.center[:2]) + pt.diameter / 2, abs=1e-9)


def test_chord_error_is_stated_and_tiny():
    d = load_design(MODELS / "ftrac_2005.toml")
    f = compute_features(d)
    paths = unwrap_features(f, d.outer_radius, cut_sizes(d))
    amp = d.ellipse_seat_radius * math.tan(math.radians(30))
    expected = amp * (1 - math.cos(math.radians(STEP_DEG) / 2))
    for p in paths:
        if p.kind == "ellipse":
            assert chord_error(p, f) == pytest.approx(expected, rel=1e-3)
            assert chord_error(p, f) < 1e-4  # 0.1 µm


def test_unwrap_uses_the_features_not_the_design():
    """A feature set moved off the design formulas (a different seat radius) unwraps to that radius."""
    from dataclasses import replace

    d = load_design(MODELS / "ftrac_2005.toml")
    f = compute_features(d)
    e = f.ellipses[0]
    e2 = replace(e, semi_major=e.semi_major * 0.9, semi_minor=e.semi_minor * 0.9)
    f2 = replace(f, ellipses=(e2,), lines=(), points=())
    (p,) = unwrap_features(f2, d.outer_radius, cut_sizes(d))
    assert p.seat_radius == pytest.approx(e.semi_minor * 0.9)
    assert distance_to_ellipse(e2, wrap(p.theta_deg, p.z, p.seat_radius)).max() < MICRON


@pytest.mark.parametrize("preset", PRESETS)
def test_dxf_rereads(tmp_path, preset):
    import ezdxf

    d = load_design(MODELS / f"{preset}.toml")
    f = compute_features(d)
    paths = unwrap_features(f, d.outer_radius, cut_sizes(d))
    out = write_grooves_dxf(tmp_path / "grooves.dxf", paths, d.outer_radius, d.half_length, d.mount.socket_depth)
    doc = ezdxf.readfile(out)
    assert doc.units == ezdxf.units.MM
    assert set(LAYERS) <= {layer.dxf.name for layer in doc.layers}
    msp = doc.modelspace()
    outline = [e for e in msp.query("LWPOLYLINE") if e.dxf.layer == "OUTLINE"]
    assert len(outline) == 1
    xs = [p[0] for p in outline[0].get_points()]
    ys = [p[1] for p in outline[0].get_points()]
    assert max(xs) - min(xs) == pytest.approx(2 * math.pi * d.outer_radius)
    assert max(ys) - min(ys) == pytest.approx(d.body.length)
    centre = [e for e in msp.query("LWPOLYLINE") if e.dxf.layer == "GROOVE_CENTRELINES"]
    assert len(centre) == len(f.ellipses) + len(f.lines)
    circles = [e for e in msp.query("CIRCLE") if e.dxf.layer == "POCKETS"]
    assert len(circles) == len(f.points)
    # a pocket circle sits at (R·θ, z) of its bead
    for c, pt in zip(circles, f.points):
        th = math.atan2(pt.center[1], pt.center[0]) % (2 * math.pi)
        assert c.dxf.center[0] == pytest.approx(d.outer_radius * th)
        assert c.dxf.center[1] == pytest.approx(pt.center[2])
    # ellipse centre-lines: y = z of the feature at x = R·θ
    for poly, e in zip(centre, f.ellipses):
        pts = np.array([p[:2] for p in poly.get_points()])
        th = pts[:, 0] / d.outer_radius
        verts = wrap(np.degrees(th), pts[:, 1], e.semi_minor)
        assert distance_to_ellipse(e, verts).max() < MICRON
