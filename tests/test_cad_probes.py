"""Probes at every feature: the groove or pocket is open where the wire or ball sits and
material starts just beyond its radius below and to both sides (it seats and holds it).

Points are classified by OpenCASCADE (``BRepClass3d_SolidClassifier``) against the body as
re-imported from ``fiducial.step`` (cnc) or built in memory (fdm). The classifier costs
~0.1 s a point on bodies with swept ellipse grooves, so the default run samples each
ellipse every 45° and each line at 4 points (every bead in full); the ``slow`` run samples
every 5° and at 24 points per line, for every preset and both profiles.
"""

from __future__ import annotations

import cad_support as S
import numpy as np
import pytest

pytestmark = pytest.mark.xdist_group("cad")

pytest.importorskip("cadquery")


def _body(preset: str, profile: str):
    if profile == "cnc":
        return S.step_body(preset).val()
    from ftrac_design.cad.body import build_body
    from ftrac_design.manufacture.plan import plan_body

    d, f, cuts = S.design_features_cuts(preset, profile)
    return build_body(plan_body(d, f, cuts))


def _check(preset: str, profile: str, n_ellipse: int, n_line: int) -> None:
    d, f, cuts = S.design_features_cuts(preset, profile)
    probes, skipped = S.probes(d, f, cuts, n_ellipse=n_ellipse, n_line=n_line)
    states = S.classify(_body(preset, profile), np.array([p.point for p in probes]))
    wrong = [
        f"{p.feature} {p.kind} at {np.round(p.point, 4).tolist()}: {st}, expected {'in' if p.inside else 'out'}"
        for p, st in zip(probes, states)
        if (st == "in") != p.inside
    ]
    assert not wrong, f"{len(wrong)} of {len(probes)} probes wrong:\n" + "\n".join(wrong[:20])
    # every feature was probed, both ways, and the skipped neighbourhoods stay small
    for fid in f.ids:
        kinds = {(p.kind, p.inside) for p in probes if p.feature == fid}
        assert ("centre", False) in kinds and ("below", True) in kinds and ("side", True) in kinds, fid
    n_inside = sum(p.inside for p in probes)
    assert skipped < 0.25 * (n_inside + skipped)


@pytest.mark.parametrize("preset", S.PRESETS)
def test_probes_cnc(preset):
    _check(preset, "cnc", n_ellipse=8, n_line=4)


def test_probes_fdm():
    """FDM grooves are wider than the wire: the side probes sit at half the groove width + ε."""
    _check("ftrac_2005", "fdm", n_ellipse=8, n_line=4)


@pytest.mark.slow
@pytest.mark.parametrize("profile", S.PROFILES)
@pytest.mark.parametrize("preset", S.PRESETS)
def test_probes_dense(preset, profile):
    _check(preset, profile, n_ellipse=72, n_line=24)


def test_probe_geometry_is_consistent():
    """The probe set itself: offsets follow the cut sizes (press fit narrower than the wire)."""
    d, f, cuts = S.design_features_cuts("ftrac_2005", "cnc")
    eps = S.probe_epsilon(cuts)
    assert 0 < eps < 0.25 * (d.wire.diameter - cuts.groove_width) + 0.01
    probes, _ = S.probes(d, f, cuts, n_ellipse=4, n_line=2)
    e = f.ellipses[0]
    P = e.sample(0.0)
    sides = [
        p
        for p in probes
        if p.feature == e.id
        and p.kind == "side"
        and abs(np.linalg.norm(p.point - P) - (d.wire.diameter / 2 + eps)) < 1e-12
    ]
    assert len(sides) == 2  # press fit: material from the wire radius (0.25 > 0.24) outward
