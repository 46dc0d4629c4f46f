"""Exact chord lengths of rays through the fiducial's solids, and the solids as primitives.

A ray leaves the source (the X origin) towards the detector point
``D(u, v) = ((u − o_x) s_x, (v − o_y) s_y, f)`` (SPEC §1); in the fiducial frame F it is
``p(s) = c + s d`` with ``c = −Rᵀt``, ``d = Rᵀ D``, s ∈ [0, 1] reaching the detector. A chord
through a convex solid is ``(s_out − s_in) |d|`` (mm). Every function here takes ray
directions ``d`` (N, 3) in F and the common source ``c`` (3,), and is exact for its solid:

- sphere (a bead): ``2 √(r² − m²)`` with m the ray's distance from the centre;
- tube piece (a wire or needle piece): the ray–cylinder intersection clipped by two planes,
  which are perpendicular cuts for straight wires and mitre (bisector) planes for the pieces
  of an ellipse wire, so that consecutive pieces tile the bent tube without gap or overlap;
- body: outer minus bore cylinder about z, each clipped by the end planes z = ±length/2.

An ellipse wire is the tube around the polyline inscribed in its centre-line with vertices
evenly spaced in the parameter; the polyline departs from the ellipse by at most the sagitta
``L² / (8 ρ_min)`` (L the longest piece, ρ_min = b²/a the smallest radius of curvature), which
:func:`ellipse_pieces` keeps below ``max_sagitta_mm`` (default 10 µm, ≈ 0.03 px at the
detector for the default camera and magnification 1.5).
(See :func:`ellipse_pieces` for the vertex placement that removes the polyline's mean offset.)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..features.model import EllipseFeature


@dataclass(frozen=True)
class Pieces:
    """Tube pieces (M of them), mm in F: axis start ``a`` (M, 3), unit axis ``e`` (M, 3),
    length ``L`` (M,), radius ``r`` (M,), clipping-plane normals ``n0``/``n1`` (M, 3) at the
    start and end (keep ``n0·(p − a) ≥ 0`` and ``n1·(p − a − L e) ≤ 0``), attenuation ``mu``
    (M,) 1/mm and the owning feature's index ``owner`` (M,)."""

    a: np.ndarray
    e: np.ndarray
    L: np.ndarray
    r: np.ndarray
    n0: np.ndarray
    n1: np.ndarray
    mu: np.ndarray
    owner: np.ndarray

    @staticmethod
    def concat(parts: list["Pieces"]) -> "Pieces":
        """All pieces of ``parts`` in one set."""
        if not parts:
            z3, z = np.zeros((0, 3)), np.zeros(0)
            return Pieces(z3, z3, z, z, z3, z3, z, np.zeros(0, int))
        return Pieces(
            *(np.concatenate([getattr(p, f) for p in parts]) for f in ("a", "e", "L", "r", "n0", "n1", "mu", "owner"))
        )


def straight_pieces(
    start: np.ndarray, end: np.ndarray, radius: float, mu: float, owner: int, max_len_mm: float = 1.0
) -> Pieces:
    """A straight tube from ``start`` to ``end`` (mm, F) cut by perpendicular planes into
    pieces no longer than ``max_len_mm`` (exact: the cuts coincide, so the pieces tile it)."""
    start, end = np.asarray(start, float), np.asarray(end, float)
    length = float(np.linalg.norm(end - start))
    e = (end - start) / length
    n = max(1, math.ceil(length / max_len_mm))
    s = np.arange(n) * (length / n)
    E = np.broadcast_to(e, (n, 3)).copy()
    return Pieces(
        start + s[:, None] * e,
        E,
        np.full(n, length / n),
        np.full(n, radius),
        E,
        E.copy(),
        np.full(n, mu),
        np.full(n, owner),
    )


def ellipse_vertex_count(el: EllipseFeature, max_sagitta_mm: float = 0.01) -> int:
    """Vertices of the inscribed polyline whose sagitta stays below ``max_sagitta_mm``."""
    a, b = max(el.semi_major, el.semi_minor), min(el.semi_major, el.semi_minor)
    rho_min = b * b / a
    # parameter step ds moves at most a·ds along the curve; sagitta = (a ds)² / (8 ρ_min)
    ds = math.sqrt(8.0 * rho_min * max_sagitta_mm) / a
    return max(16, math.ceil(2 * math.pi / ds))


def ellipse_pieces(el: EllipseFeature, mu: float, owner: int, max_sagitta_mm: float = 0.01) -> Pieces:
    """The ellipse wire as mitre-jointed tube pieces along a polyline (see module).

    The vertices sit on the ellipse pushed outward by 2/3 of the local sagitta
    ``σ = L² / (8 ρ)``: a chord of an arc lies on average 2σ/3 inside it, so the polyline's
    mean offset from the centre-line is zero (to second order) and its largest departure
    is 2σ/3 ≤ 2/3 × ``max_sagitta_mm`` (default 6.7 µm, 0.02 px at magnification 1.5).
    """
    n = ellipse_vertex_count(el, max_sagitta_mm)
    s = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    a, b = el.semi_major, el.semi_minor
    speed2 = a * a * np.sin(s) ** 2 + b * b * np.cos(s) ** 2
    rho = speed2**1.5 / (a * b)
    L = np.sqrt(speed2) * (2 * np.pi / n)
    normal = (b * np.cos(s))[:, None] * el.major_axis + (a * np.sin(s))[:, None] * el.minor_axis
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    V = el.sample(s) + (L * L / (12.0 * rho))[:, None] * normal
    W = np.roll(V, -1, axis=0)
    seg = W - V
    L = np.linalg.norm(seg, axis=1)
    e = seg / L[:, None]
    e_prev = np.roll(e, 1, axis=0)
    n0 = e + e_prev  # bisector plane at each vertex
    n0 /= np.linalg.norm(n0, axis=1, keepdims=True)
    n1 = np.roll(n0, -1, axis=0)
    r = el.wire_diameter / 2.0
    return Pieces(V, e, L, np.full(n, r), n0, n1, np.full(n, mu), np.full(n, owner))


def sphere_chord(c: np.ndarray, d: np.ndarray, center: np.ndarray, radius: np.ndarray) -> np.ndarray:
    """Chord (mm) of rays ``c + s d`` through spheres; ``center`` (N, 3) or (3,), ``radius`` (N,) or scalar."""
    w = c - center
    A = np.einsum("ij,ij->i", d, d)
    s0 = -np.einsum("ij,ij->i", w, d) / A if w.ndim == 2 else -(d @ w) / A
    m = w + s0[:, None] * d
    h2 = radius * radius - np.einsum("ij,ij->i", m, m)
    return 2.0 * np.sqrt(np.maximum(h2, 0.0))


def _dot(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    return np.einsum("ij,ij->i", x, y)


def tube_chord(
    c: np.ndarray,
    d: np.ndarray,
    a: np.ndarray,
    e: np.ndarray,
    L: np.ndarray,
    r: np.ndarray,
    n0: np.ndarray,
    n1: np.ndarray,
) -> np.ndarray:
    """Chord (mm) of rays ``c + s d`` (d (N, 3)) through clipped cylinders given row-wise
    (``a``, ``e``, ``n0``, ``n1`` (N, 3), ``L``, ``r`` (N,); see :class:`Pieces`)."""
    w = c - a
    de, we = _dot(d, e), _dot(w, e)
    dp = d - de[:, None] * e
    wp = w - we[:, None] * e
    A = _dot(dp, dp)
    A = np.where(A > 0, A, np.inf)  # a ray along the axis meets no side wall
    s0 = -_dot(wp, dp) / A
    m = wp + s0[:, None] * dp
    h = np.sqrt(np.maximum(r * r - _dot(m, m), 0.0) / A)
    lo, hi = s0 - h, s0 + h
    # plane 0: n0·w + s n0·d ≥ 0
    g, gd = _dot(n0, w), _dot(n0, d)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = -g / gd
    lo = np.where(gd > 0, np.maximum(lo, s), lo)
    hi = np.where(gd < 0, np.minimum(hi, s), hi)
    hi = np.where((gd == 0) & (g < 0), lo, hi)
    # plane 1: n1·(w − L e) + s n1·d ≤ 0
    g = _dot(n1, w) - L * _dot(n1, e)
    gd = _dot(n1, d)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = -g / gd
    hi = np.where(gd > 0, np.minimum(hi, s), hi)
    lo = np.where(gd < 0, np.maximum(lo, s), lo)
    hi = np.where((gd == 0) & (g > 0), lo, hi)
    return np.maximum(hi - lo, 0.0) * np.sqrt(_dot(d, d))


def cylinder_z_chord(c: np.ndarray, d: np.ndarray, radius: float, half_length: float) -> np.ndarray:
    """Chord (mm) of rays ``c + s d`` (d (N, 3)) through the solid cylinder x² + y² ≤ radius²,
    |z| ≤ half_length."""
    if radius <= 0:
        return np.zeros(len(d))
    dx, dy, dz = d[:, 0], d[:, 1], d[:, 2]
    A0 = dx * dx + dy * dy
    A = np.where(A0 > 0, A0, np.inf)
    s0 = -(c[0] * dx + c[1] * dy) / A
    mx, my = c[0] + s0 * dx, c[1] + s0 * dy
    h = np.sqrt(np.maximum(radius * radius - mx * mx - my * my, 0.0) / A)
    lo, hi = s0 - h, s0 + h
    with np.errstate(divide="ignore", invalid="ignore"):
        z1 = (-half_length - c[2]) / dz
        z2 = (half_length - c[2]) / dz
    zlo = np.where(dz != 0, np.minimum(z1, z2), np.where(abs(c[2]) <= half_length, -np.inf, np.inf))
    zhi = np.where(dz != 0, np.maximum(z1, z2), np.where(abs(c[2]) <= half_length, np.inf, -np.inf))
    lo, hi = np.maximum(lo, zlo), np.minimum(hi, zhi)
    return np.maximum(hi - lo, 0.0) * np.sqrt(A0 + dz * dz)


def _lin(g0: np.ndarray, gu: np.ndarray, gv: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Coefficients (M, 3) of the linear form x·d(u, v) = α + β u + γ v for rows of x (M, 3)."""
    return np.stack([x @ g0, x @ gu, x @ gv], -1)


def tube_chord_uv(
    c: np.ndarray,
    g0: np.ndarray,
    gu: np.ndarray,
    gv: np.ndarray,
    pieces: Pieces,
    k: np.ndarray,
    U: np.ndarray,
    V: np.ndarray,
    dtype=np.float64,
) -> np.ndarray:
    """:func:`tube_chord` of piece ``k`` (n,) for rays through image points (U, V) (n, s),
    with ray directions d = g0 + u gu + v gv (F). Same result, several times faster: every
    dot product with d is a linear form in (u, v) whose coefficients are computed per piece
    (in float64, about a reference point near the piece), and the ray's distance from the
    axis comes from ``m |d⊥| = d·(e × w)`` (no cancellation between the two ~|c|² terms of
    the textbook quadratic). ``dtype=float32`` evaluates the per-sample part in single
    precision: with the linear forms centred on each piece the chord keeps ~1e-5 mm."""
    w = c - pieces.a
    we = np.einsum("ij,ij->i", w, pieces.e)
    M = len(pieces.L)
    # reference pixel of each piece: where its start projects (any nearby point would do)
    u_ref = np.rint(U[:, 0]) if U.ndim == 2 else np.rint(U)
    v_ref = np.rint(V[:, 0]) if V.ndim == 2 else np.rint(V)
    Lf = _lin(g0, gu, gv, np.concatenate([pieces.e, w, np.cross(pieces.e, w), pieces.n0, pieces.n1]))
    De, Dw, Dm, D0, D1 = (Lf[i * M : (i + 1) * M][k] for i in range(5))
    g_0 = np.einsum("ij,ij->i", pieces.n0, w)[k]
    g_1 = (np.einsum("ij,ij->i", pieces.n1, w) - pieces.L * np.einsum("ij,ij->i", pieces.n1, pieces.e))[k]
    we_k, r2 = we[k], (pieces.r**2)[k]
    dref = g0 + u_ref[:, None] * gu + v_ref[:, None] * gv  # d at the reference pixel (n, 3)

    def centred(D):
        a0 = D[:, 0] + u_ref * D[:, 1] + v_ref * D[:, 2]
        return [np.asarray(x, dtype)[:, None] for x in (a0, D[:, 1], D[:, 2])]

    Uc = np.asarray(U - u_ref[:, None], dtype)
    Vc = np.asarray(V - v_ref[:, None], dtype)

    def f(D):
        a0, b, g = centred(D)
        return a0 + Uc * b + Vc * g

    # |d|² about the reference: |dref + Uc gu + Vc gv|²
    dd_ref = np.einsum("ij,ij->i", dref, dref)
    du, dv = dref @ gu, dref @ gv
    cst = [np.asarray(x, dtype)[:, None] for x in (dd_ref, 2 * du, 2 * dv)]
    dd = (
        cst[0]
        + Uc * cst[1]
        + Vc * cst[2]
        + dtype(gu @ gu) * Uc * Uc
        + dtype(2 * (gu @ gv)) * Uc * Vc
        + dtype(gv @ gv) * Vc * Vc
    )
    de = f(De)
    A = dd - de * de
    A = np.where(A > 0, A, np.inf)
    mn = f(Dm)
    with np.errstate(invalid="ignore"):
        h = np.sqrt(np.maximum(np.asarray(r2, dtype)[:, None] * A - mn * mn, 0)) / A
    # a ray along the axis meets no side wall (as :func:`tube_chord` has it), not ∞ / ∞ = NaN
    h = np.where(np.isfinite(A), h, 0)
    s0 = (np.asarray(we_k, dtype)[:, None] * de - f(Dw)) / A
    lo, hi = s0 - h, s0 + h
    # start plane: g_0 + s n0·d ≥ 0; end plane: g_1 + s n1·d ≤ 0
    for g, D, sign in ((g_0, D0, 1.0), (g_1, D1, -1.0)):
        gd = f(D)
        g = np.asarray(g, dtype)[:, None]
        with np.errstate(divide="ignore", invalid="ignore"):
            s = -g / gd
        up = gd * dtype(sign)
        lo = np.where(up > 0, np.maximum(lo, s), lo)
        hi = np.where(up < 0, np.minimum(hi, s), hi)
        hi = np.where((gd == 0) & (g * dtype(sign) < 0), lo, hi)
    return np.maximum(hi - lo, 0) * np.sqrt(dd)


def body_chord_uv(
    c: np.ndarray,
    g0: np.ndarray,
    gu: np.ndarray,
    gv: np.ndarray,
    outer_radius: float,
    bore_radius: float,
    half_length: float,
    U: np.ndarray,
    V: np.ndarray,
) -> np.ndarray:
    """Chord (mm) through the hollow cylinder bore_radius ≤ √(x² + y²) ≤ outer_radius,
    |z| ≤ half_length (F) of rays through image points (U, V) (any shape), d = g0 + u gu + v gv.
    Equals :func:`cylinder_z_chord` (outer) minus the same for the bore."""
    dx = g0[0] + U * gu[0] + V * gv[0]
    dy = g0[1] + U * gu[1] + V * gv[1]
    dz = g0[2] + U * gu[2] + V * gv[2]
    A0 = dx * dx + dy * dy
    A = np.where(A0 > 0, A0, np.inf)
    mn = c[0] * dy - c[1] * dx  # m √A, m = the ray's distance from the axis
    s0 = -(c[0] * dx + c[1] * dy) / A
    with np.errstate(divide="ignore", invalid="ignore"):
        z1 = (-half_length - c[2]) / dz
        z2 = (half_length - c[2]) / dz
    inside = abs(c[2]) <= half_length
    zlo = np.where(dz != 0, np.minimum(z1, z2), -np.inf if inside else np.inf)
    zhi = np.where(dz != 0, np.maximum(z1, z2), np.inf if inside else -np.inf)
    mn2 = mn * mn
    out = None
    for radius, sign in ((outer_radius, 1.0), (bore_radius, -1.0)):
        if radius <= 0:
            continue
        with np.errstate(invalid="ignore"):
            # a ray along the axis meets no side wall (as :func:`cylinder_z_chord` has it), not NaN
            h = np.where(np.isfinite(A), np.sqrt(np.maximum(radius * radius * A - mn2, 0.0)) / A, 0.0)
        ch = np.maximum(np.minimum(s0 + h, zhi) - np.maximum(s0 - h, zlo), 0.0)
        out = ch if out is None else out - ch
    return out * np.sqrt(A0 + dz * dz)
