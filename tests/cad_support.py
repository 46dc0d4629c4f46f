"""Shared by the CAD tests: one build per preset and profile per test process, an analytic
volume estimate that does not use the CAD code, and probe points at every feature.

The CAD test modules are marked ``xdist_group("cad")``, so under ``pytest -n 2 --dist
loadgroup`` they all run in one worker and share these cached builds.
"""

from __future__ import annotations

import atexit
import functools
import math
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from conftest import MODELS, PRESETS, ROOT  # noqa: E402,F401  (one list of presets for every test)
from scipy.integrate import quad
from scipy.spatial import cKDTree

from ftrac_design.design import load_design
from ftrac_design.design.schema import Design
from ftrac_design.features import compute_features
from ftrac_design.features.model import Features
from ftrac_design.manufacture.profiles import CutSizes, cut_sizes

PROFILES = ("cnc", "fdm")

_TMP = Path(tempfile.mkdtemp(prefix="ftrac-cad-tests-"))
atexit.register(shutil.rmtree, _TMP, ignore_errors=True)


@functools.cache
def design_of(preset: str) -> Design:
    return load_design(MODELS / f"{preset}.toml")


@functools.cache
def build(preset: str, profile: str = "cnc"):
    """Full ``build`` output of a preset (cached per process): a BuildResult."""
    from ftrac_design.cad.build import build_fiducial

    return build_fiducial(design_of(preset), _TMP / f"{preset}-{profile}", profile=profile)


@functools.cache
def step_body(preset: str, profile: str = "cnc"):
    """The body as re-imported from the build's ``fiducial.step``."""
    import cadquery as cq

    return cq.importers.importStep(str(build(preset, profile).out_dir / "fiducial.step"))


# ---- analytic volume ------------------------------------------------------------------------


@dataclass(frozen=True)
class VolumeEstimate:
    """Blank minus every groove and pocket, with the overlaps the estimate neglects bounded.

    ``estimate`` counts each cut on its own and adds back the slot-in-pocket overlaps (large:
    a line slot runs through its beads' pockets), computed by quadrature. It neglects two
    kinds of overlap that are removed twice: an ellipse groove crossing a line groove
    (``crossings``: w_e·w_l·h_e / sin θ each, the parallelogram of the two strips times the
    ellipse groove's depth) and an ellipse groove running into a pocket (``ellipse_pocket``:
    strip ∩ disc area on the unrolled surface times h_e). Both make the true volume larger,
    so ``estimate ≤ V ≤ estimate + neglected`` up to the approximations in those two
    products (flat parallelogram, surface sag), for which :meth:`tolerance` allows 25 %.
    """

    blank: float
    ellipse_grooves: float
    line_grooves: float
    pockets: float
    slot_pocket_overlap: float
    crossings: float
    ellipse_pocket: float
    n_crossings: int

    @property
    def estimate(self) -> float:
        return self.blank - self.ellipse_grooves - self.line_grooves - self.pockets + self.slot_pocket_overlap

    @property
    def neglected(self) -> float:
        return self.crossings + self.ellipse_pocket

    def tolerance(self) -> float:
        """Allowed |V − (estimate + neglected)|: 25 % of the neglected overlaps plus 2e-7 of the
        blank (quadrature and the 1e-9 adaptive volume integration)."""
        return 0.25 * self.neglected + 2e-7 * self.blank


def _ellipse_groove_volume(e, R: float, w: float) -> float:
    """Rectangular section (width w, from one wire radius below the centre-line up to the
    surface) swept with the surface-normal frame: ∫ [A(s) + κ_n(s)·S] ds, where A is the
    section area inside the cylinder (less the surface's sag across the groove) and
    S = ∫ n dA its first moment about the centre-line (Pappus–Guldin to first order)."""
    rw, h = e.wire_diameter / 2, R - e.semi_minor
    s = np.linspace(0.0, 2 * np.pi, 20001)
    P, T = e.sample(s), e.tangent(s)
    dP = np.gradient(P, s, axis=0)
    ddP = np.gradient(dP, s, axis=0)
    speed = np.linalg.norm(dP, axis=1)
    N = P * np.array([1.0, 1.0, 0.0])
    N /= np.linalg.norm(N, axis=1, keepdims=True)
    B = np.cross(T, N)
    k_n = -(ddP * N).sum(axis=1) / speed**2  # normal curvature, positive toward the axis
    area = w * (h + rw) - w**3 * (B[:, :2] ** 2).sum(axis=1) / (24 * R)
    moment = w * (h * h - rw * rw) / 2
    return float(np.trapezoid((area + k_n * moment) * speed, s))


def analytic_volume(design: Design, f: Features, cuts: CutSizes) -> VolumeEstimate:
    """Independent estimate of the body volume from the design, features and cut sizes."""
    R, rb, L = design.outer_radius, design.bore_radius, design.body.length
    w, p = cuts.groove_width, cuts.pocket_diameter / 2
    blank = math.pi * (R * R - rb * rb) * L
    v_ell = sum(_ellipse_groove_volume(e, R, w) for e in f.ellipses)
    v_line = overlap = crossings = 0.0
    n_cross = 0
    for ln in f.lines:
        floor = math.hypot(*ln.start[:2]) - ln.wire_diameter / 2
        area = quad(lambda v: math.sqrt(R * R - v * v) - floor, -w / 2, w / 2)[0]
        v_line += area * ln.length
        z0, z1 = ln.start[2], ln.end[2]
        for b in f.beads_on(ln.id):
            zb = b.center[2]

            def strip(x, zb=zb):
                half = math.sqrt(max(p * p - x * x, 0.0))
                return max(min(half, z1 - zb) - max(-half, z0 - zb), 0.0) * (math.sqrt(R * R - x * x) - floor)

            overlap += quad(strip, -w / 2, w / 2, limit=200)[0]
        phi = math.atan2(ln.start[1], ln.start[0])
        for e in f.ellipses:
            # the seated ellipse's azimuth is monotonic in s: find where it meets the line's
            s = np.linspace(0, 2 * np.pi, 72001)
            P = e.sample(s)
            k = int(np.argmin(np.abs(np.angle(np.exp(1j * (np.arctan2(P[:, 1], P[:, 0]) - phi))))))
            if z0 <= P[k, 2] <= z1:
                T = e.tangent(s[k])
                h_e = R - e.semi_minor + e.wire_diameter / 2
                crossings += w * w * h_e / math.hypot(T[0], T[1])
                n_cross += 1
    v_pock = 0.0
    for b in f.points:
        floor = math.hypot(*b.center[:2]) - b.diameter / 2
        v_pock += quad(lambda x: 2 * math.sqrt(p * p - x * x) * (math.sqrt(R * R - x * x) - floor), -p, p)[0]
    return VolumeEstimate(
        blank, v_ell, v_line, v_pock, overlap, crossings, _ellipse_pocket_overlap(design, f, cuts), n_cross
    )


def _ellipse_pocket_overlap(design: Design, f: Features, cuts: CutSizes) -> float:
    """Σ (area where an ellipse groove's strip meets a pocket's disc on the unrolled surface)
    × the ellipse groove's depth; zero when no groove comes within reach of a pocket."""
    R, w, p = design.outer_radius, cuts.groove_width, cuts.pocket_diameter / 2
    total = 0.0
    for e in f.ellipses:
        s = np.linspace(0, 2 * np.pi, 40001)
        P = e.sample(s)
        h_e = R - e.semi_minor + e.wire_diameter / 2
        for b in f.points:
            phi_b = math.atan2(b.center[1], b.center[0])
            u = R * np.angle(np.exp(1j * (np.arctan2(P[:, 1], P[:, 0]) - phi_b)))
            near = np.hypot(u, P[:, 2] - b.center[2]) < p + w
            if not near.any():
                continue
            tree = cKDTree(np.column_stack([u[near], P[near, 2] - b.center[2]]))
            n = 400
            g = np.linspace(-p, p, n)
            X, Y = np.meshgrid(g, g)
            inside = X**2 + Y**2 <= p * p
            d, _ = tree.query(np.column_stack([X[inside], Y[inside]]))
            total += float((d <= w / 2).sum()) * (g[1] - g[0]) ** 2 * h_e
    return total


# ---- probes ---------------------------------------------------------------------------------


@dataclass(frozen=True)
class Probe:
    feature: str
    kind: str  # centre | below | side | floor-gap | wall-gap
    point: np.ndarray
    inside: bool  # expected in the body's material


@dataclass(frozen=True)
class _Cut:
    owner: str
    kind: str
    data: tuple


def probe_epsilon(cuts: CutSizes) -> float:
    """Probe offset beyond a wire or bead surface: 2 % of the narrowest cut (≈ 0.01 mm for
    a 0.48 mm groove), far above OCC's 1e-7 mm and far below any feature size."""
    sizes = [s for s in (cuts.groove_width, cuts.pocket_diameter) if s > 0]
    return 0.02 * min(sizes)


def _cut_regions(design: Design, f: Features, cuts: CutSizes) -> list[_Cut]:
    """Every cut as a region in closed form, from the features (independent of the CAD)."""
    out = []
    for e in f.ellipses:
        s = np.linspace(0, 2 * np.pi, 7201, endpoint=False)
        P, T = e.sample(s), e.tangent(s)
        N = P * np.array([1.0, 1.0, 0.0])
        N /= np.linalg.norm(N, axis=1, keepdims=True)
        out.append(_Cut(e.id, "ellipse", (cKDTree(P), P, T, N, np.cross(T, N), e.wire_diameter / 2)))
    for ln in f.lines:
        u = ln.start * np.array([1.0, 1.0, 0.0])
        u /= np.linalg.norm(u)
        v = np.cross([0.0, 0.0, 1.0], u)
        floor = math.hypot(*ln.start[:2]) - ln.wire_diameter / 2
        out.append(_Cut(ln.id, "line", (u, v, floor, ln.start[2], ln.end[2])))
    for b in f.points:
        u = b.center * np.array([1.0, 1.0, 0.0])
        u /= np.linalg.norm(u)
        out.append(_Cut(b.id, "pocket", (u, b.center - u * b.diameter / 2)))
    return out


def _in_cut(q: np.ndarray, c: _Cut, R: float, w: float, p: float, m: float) -> bool:
    """Is ``q`` within the cut ``c`` grown by margin ``m`` (to the surface and beyond)?"""
    if c.kind == "line":
        u, v, floor, z0, z1 = c.data
        return q @ u >= floor - m and abs(q @ v) <= w / 2 + m and z0 - m <= q[2] <= z1 + m
    if c.kind == "pocket":
        u, floor = c.data
        d = q - floor
        a = d @ u
        return a >= -m and np.linalg.norm(d - a * u) <= p + m
    tree, P, T, N, B, rw = c.data
    _, k = tree.query(q)
    d = q - P[k]
    return d @ N[k] >= -rw - m and abs(d @ B[k]) <= w / 2 + m


def probes(
    design: Design, f: Features, cuts: CutSizes, n_ellipse: int = 96, n_line: int = 40
) -> tuple[list[Probe], int]:
    """Probe points at every feature, and how many in-material probes were skipped because
    they fall within another feature's cut (crossings, pockets on a line).

    Per sample on a wire centre-line (P, tangent T, outward normal N, across B = T × N):
    - outside the body: P itself; P − (r_w − ε)N (the floor is one wire radius down); P ±
      (w/2 − ε)B (the walls are half a groove width to the sides);
    - inside: P − (r_w + ε)N (below) and P ± (max(r_w, w/2) + ε)B (both sides: for a press
      fit the groove is narrower than the wire, so material starts before the wire's radius).
    Per bead the same with the ball radius and the pocket diameter, to the sides both around
    the circumference and, where no line slot continues, along z.
    """
    R, w, p = design.outer_radius, cuts.groove_width, cuts.pocket_diameter / 2
    eps = probe_epsilon(cuts)
    margin = 5 * eps
    regions = _cut_regions(design, f, cuts)
    out: list[Probe] = []
    skipped = 0

    def add(owner: str, kind: str, q: np.ndarray, inside: bool) -> None:
        nonlocal skipped
        if inside and any(c.owner != owner and _in_cut(q, c, R, w, p, margin) for c in regions):
            skipped += 1
            return
        out.append(Probe(owner, kind, q, inside))

    def around(owner: str, P, N, sides, r, half):
        add(owner, "centre", P, False)
        add(owner, "floor-gap", P - (r - eps) * N, False)
        add(owner, "below", P - (r + eps) * N, True)
        for B in sides:
            add(owner, "wall-gap", P + (half - eps) * B, False)
            add(owner, "side", P + (max(r, half) + eps) * B, True)

    for e in f.ellipses:
        s = np.linspace(0, 2 * np.pi, n_ellipse, endpoint=False)
        for P, T in zip(e.sample(s), e.tangent(s)):
            N = P * np.array([1.0, 1.0, 0.0])
            N /= np.linalg.norm(N)
            B = np.cross(T, N)
            around(e.id, P, N, (B, -B), e.wire_diameter / 2, w / 2)
    for ln in f.lines:
        N = ln.start * np.array([1.0, 1.0, 0.0])
        N /= np.linalg.norm(N)
        B = np.cross([0.0, 0.0, 1.0], N)
        t = np.linspace(0, 1, n_line + 2)[1:-1]  # interior points; the slot ends at the ends
        for P in ln.sample(t):
            around(ln.id, P, N, (B, -B), ln.wire_diameter / 2, w / 2)
    for b in f.points:
        N = b.center * np.array([1.0, 1.0, 0.0])
        N /= np.linalg.norm(N)
        sides = [np.cross([0.0, 0.0, 1.0], N)]
        sides.append(-sides[0])
        z = np.array([0.0, 0.0, 1.0])
        if b.line is None:
            sides += [z, -z]
        else:  # along z only on a side where the line's slot does not continue
            ln = f.line(b.line)
            if b.center[2] >= ln.end[2] - 1e-9:
                sides.append(z)
            if b.center[2] <= ln.start[2] + 1e-9:
                sides.append(-z)
        around(b.id, b.center, N, sides, b.diameter / 2, p)
    return out, skipped


def classify(solid, points: np.ndarray) -> np.ndarray:
    """OCC state of each point: "in", "out" or "on" (tolerance 1e-7 mm)."""
    from OCP.BRepClass3d import BRepClass3d_SolidClassifier
    from OCP.gp import gp_Pnt
    from OCP.TopAbs import TopAbs_IN, TopAbs_OUT

    clf = BRepClass3d_SolidClassifier(solid.wrapped)
    states = []
    for q in points:
        clf.Perform(gp_Pnt(*map(float, q)), 1e-7)
        st = clf.State()
        states.append("in" if st == TopAbs_IN else "out" if st == TopAbs_OUT else "on")
    return np.array(states)


def design_features_cuts(preset: str, profile: str = "cnc"):
    d = design_of(preset)
    return d, compute_features(d), cut_sizes(d, profile)
