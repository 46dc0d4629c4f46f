"""Every pose that puts three known points on three lines of sight: the perspective-three-point
problem in closed form, vectorised over many triplets at once.

Grunert's solution as Haralick et al. review it (*Review and analysis of solutions of the
three point perspective pose estimation problem*, IJCV 13(3), 1994, §2.1): with the
distances s₁, s₂ = u s₁, s₃ = v s₁ along the unit lines of sight j₁, j₂, j₃, the law of
cosines for the three sides gives a quartic in v; each real root gives u, then s₁, the three
points in the camera frame and the rigid motion that carries the model triangle onto them.

Why our own and not OpenCV's ``solveP3P``: the identification asks for the poses of hundreds
of model triplets per image triplet, and one library call per triplet cost a fifth of the
time of a whole image; and the answer must not depend on a library's release (the set, the
order or the numerics of its solutions). Here every triplet's quartic is solved at once
(companion-matrix eigenvalues, one Newton polish), roots are kept only where the three side
equations hold, and the solutions come out in the order of the triplets and of their roots
by value — the same on any machine up to rounding.
"""

from __future__ import annotations

import numpy as np


def bearings(uv: np.ndarray, K: np.ndarray) -> np.ndarray:
    """Unit lines of sight (…, 3) in the camera frame X of pixels ``uv`` (…, 2) seen with the
    intrinsic matrix ``K`` (3, 3; SPEC §1: u along x, v along y, z along the optical axis)."""
    uv = np.asarray(uv, float)
    h = np.concatenate([uv, np.ones(uv.shape[:-1] + (1,))], -1)
    d = np.linalg.solve(K, h.reshape(-1, 3).T).T.reshape(h.shape)
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def _quartic(a2, b2, c2, ca, cb, cg) -> np.ndarray:
    """Grunert's quartic in v (Haralick et al. 1994, eq. 9): coefficients (m, 5), v⁴ first."""
    p = (a2 - c2) / b2
    q = (a2 + c2) / b2
    A4 = (p - 1) ** 2 - 4 * c2 / b2 * ca * ca
    A3 = 4 * (p * (1 - p) * cb - (1 - q) * ca * cg + 2 * c2 / b2 * ca * ca * cb)
    A2 = 2 * (p * p - 1 + 2 * p * p * cb * cb + 2 * (b2 - c2) / b2 * ca * ca - 4 * q * ca * cb * cg)
    A2 = A2 + 4 * (b2 - a2) / b2 * cg * cg
    A1 = 4 * (-p * (1 + p) * cb + 2 * a2 / b2 * cg * cg * cb - (1 - q) * ca * cg)
    A0 = (1 + p) ** 2 - 4 * a2 / b2 * cg * cg
    return np.stack([A4, A3, A2, A1, A0], -1)


def _cubic_root(A: np.ndarray, B: np.ndarray, C: np.ndarray) -> np.ndarray:
    """The root of largest modulus (complex, (m,)) of m³ + A m² + B m + C (Cardano)."""
    P = B - A * A / 3
    Q = 2 * A**3 / 27 - A * B / 3 + C
    D = np.sqrt(Q * Q / 4 + P**3 / 27 + 0j)
    w = -Q / 2 + np.where(np.real(np.conj(-Q / 2) * D) >= 0, D, -D)  # the larger of −Q/2 ± D
    c1 = w ** (1 / 3)
    zero = np.abs(c1) < 1e-300
    c1 = np.where(zero, 1.0, c1)
    best = np.zeros(len(A), complex)
    for k in range(3):
        ck = c1 * np.exp(2j * np.pi * k / 3)
        m = np.where(zero, -A / 3, ck - P / (3 * ck) - A / 3)
        best = np.where(np.abs(m) > np.abs(best), m, best)
    return best


def _real_roots(coef: np.ndarray, imag_tol: float = 1e-3) -> tuple[np.ndarray, np.ndarray]:
    """Roots (m, 4) of the quartics ``coef`` (m, 5) and which are (nearly) real: Ferrari's
    solution in complex arithmetic, the nearly real ones polished by two Newton steps."""
    lead = coef[:, 0]
    ok = np.abs(lead) > 1e-12 * np.abs(coef).max(1)
    b, c, d, e = (coef[:, 1:] / np.where(ok, lead, 1.0)[:, None]).T
    # y = x + b/4: y⁴ + p y² + q y + r
    p = c - 3 * b * b / 8
    q = d - b * c / 2 + b**3 / 8
    r = e - b * d / 4 + b * b * c / 16 - 3 * b**4 / 256
    # Ferrari's resolvent: 8m³ + 8p m² + (2p² − 8r) m − q² = 0, a root m ≠ 0
    m = _cubic_root(p, p * p / 4 - r, -q * q / 8)
    sm = np.sqrt(2 * m + 0j)
    sm = np.where(np.abs(sm) < 1e-300, 1e-300, sm)
    roots = []
    for s1 in (1, -1):
        inner = np.sqrt(-(2 * p + 2 * m + s1 * 2 * q / sm) + 0j)
        for s2 in (1, -1):
            roots.append((s1 * sm + s2 * inner) / 2 - b / 4)
    ev = np.stack(roots, -1)
    real = ok[:, None] & np.isfinite(ev) & (np.abs(ev.imag) <= imag_tol * np.maximum(1.0, np.abs(ev.real)))
    v = ev.real
    cb = np.stack([b, c, d, e], -1)
    for _ in range(2):
        f = (((v + cb[:, :1]) * v + cb[:, 1:2]) * v + cb[:, 2:3]) * v + cb[:, 3:4]
        df = ((4 * v + 3 * cb[:, :1]) * v + 2 * cb[:, 1:2]) * v + cb[:, 2:3]
        v = np.where(real & (df != 0), v - f / np.where(df == 0, 1.0, df), v)
    # the roots of each quartic by value: their order is the arithmetic's, not a library's
    o = np.argsort(np.where(real, v, np.inf), axis=1, kind="stable")
    return np.take_along_axis(v, o, 1), np.take_along_axis(real, o, 1)


def _frames(A: np.ndarray, B: np.ndarray, C: np.ndarray) -> np.ndarray:
    """Orthonormal frames (…, 3, 3), columns e₁ along AB, e₃ normal to the triangle ABC."""
    e1 = B - A
    e1 = e1 / np.linalg.norm(e1, axis=-1, keepdims=True)
    n = np.cross(B - A, C - A)
    n = n / np.linalg.norm(n, axis=-1, keepdims=True)
    return np.stack([e1, np.cross(n, e1), n], -1)


def _polish(s: np.ndarray, sides2: np.ndarray, cos: np.ndarray, steps: int = 2) -> np.ndarray:
    """Newton steps on the three laws of cosines for the distances ``s`` (k, 3), with the
    squared sides a², b², c² (k, 3) and cos α, β, γ (k, 3): u from Grunert's substitution
    loses digits near a double root of the quartic (sides off by 10⁻³ where the solution is
    exact); two steps on the equations themselves restore them (Cramer's rule, 3 × 3)."""
    ca, cb, cg = cos.T
    a2, b2, c2 = sides2.T
    for _ in range(steps):
        s1, s2, s3 = s.T
        f = np.stack(
            [
                s2 * s2 + s3 * s3 - 2 * s2 * s3 * ca - a2,
                s1 * s1 + s3 * s3 - 2 * s1 * s3 * cb - b2,
                s1 * s1 + s2 * s2 - 2 * s1 * s2 * cg - c2,
            ]
        )
        # the Jacobian's rows: (0, j12, j13), (j21, 0, j23), (j31, j32, 0)
        j12, j13 = 2 * (s2 - s3 * ca), 2 * (s3 - s2 * ca)
        j21, j23 = 2 * (s1 - s3 * cb), 2 * (s3 - s1 * cb)
        j31, j32 = 2 * (s1 - s2 * cg), 2 * (s2 - s1 * cg)
        det = -j12 * (-j23 * j31) + j13 * (j21 * j32)
        ok = np.abs(det) > 1e-12 * np.maximum(np.abs(s).max(1), 1.0) ** 3
        d = np.where(ok, det, 1.0)
        # the inverse's rows by cofactors
        x1 = (-j23 * j32 * f[0] + j13 * j32 * f[1] + j12 * j23 * f[2]) / d
        x2 = (j23 * j31 * f[0] - j13 * j31 * f[1] + j13 * j21 * f[2]) / d
        x3 = (j21 * j32 * f[0] + j12 * j31 * f[1] - j12 * j21 * f[2]) / d
        s = s - np.where(ok[:, None], np.stack([x1, x2, x3], -1), 0.0)
    return s


def p3p(
    points: np.ndarray, rays: np.ndarray, rel_tol: float = 1e-3, dup_tol: float = 1e-4
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every pose that puts model triplets on their lines of sight.

    Parameters
    ----------
    points : (m, 3, 3) ndarray
        Triplets of model points P₁, P₂, P₃ (mm, frame F), not collinear.
    rays : (3, 3) or (m, 3, 3) ndarray
        The unit lines of sight j₁, j₂, j₃ in the camera frame X (:func:`bearings`), one
        triplet for all or one per model triplet.
    rel_tol : float
        A solution is kept when each side of the triangle it places is within this fraction
        of the model's.
    dup_tol : float
        Solutions of one triplet whose points lie within this fraction of their distance of
        each other are one solution (a near-multiple root).

    Returns
    -------
    R : (k, 3, 3) ndarray
        Rotations F → X of the k solutions (X = R P + t).
    t : (k, 3) ndarray
        Translations (mm).
    index : (k,) ndarray of int
        The model triplet each solution belongs to, ascending; up to four per triplet,
        ordered by Grunert's v.
    """
    P = np.asarray(points, float).reshape(-1, 3, 3)
    j = np.broadcast_to(np.asarray(rays, float), P.shape)
    P1, P2, P3 = P[:, 0], P[:, 1], P[:, 2]
    a2 = np.sum((P2 - P3) ** 2, -1)
    b2 = np.sum((P1 - P3) ** 2, -1)
    c2 = np.sum((P1 - P2) ** 2, -1)
    ca = np.sum(j[:, 1] * j[:, 2], -1)
    cb = np.sum(j[:, 0] * j[:, 2], -1)
    cg = np.sum(j[:, 0] * j[:, 1], -1)
    with np.errstate(all="ignore"):
        v, real = _real_roots(_quartic(a2, b2, c2, ca, cb, cg))
        mi, ri = np.nonzero(real)
        v = v[mi, ri]
        a2, b2, c2, ca, cb, cg = (x[mi] for x in (a2, b2, c2, ca, cb, cg))
        p = (a2 - c2) / b2
        u = ((p - 1) * v * v - 2 * p * cb * v + 1 + p) / (2 * (cg - v * ca))
        s1 = np.sqrt(b2 / (1 + v * v - 2 * v * cb))
        sides2 = np.stack([a2, b2, c2], -1)
        s = _polish(np.stack([s1, u * s1, v * s1], -1), sides2, np.stack([ca, cb, cg], -1))
        X = s[..., None] * j[mi]  # (k, 3 points, 3)
        side = np.stack(
            [
                np.sum((X[:, 1] - X[:, 2]) ** 2, -1),
                np.sum((X[:, 0] - X[:, 2]) ** 2, -1),
                np.sum((X[:, 0] - X[:, 1]) ** 2, -1),
            ],
            -1,
        )
        good = (s > 0).all(-1) & np.isfinite(side).all(-1) & (np.abs(side / sides2 - 1) <= 2 * rel_tol).all(-1)
    mi, Xg = mi[good], X[good]
    # a near-multiple root of the quartic gives one pose two or three times (they differ in
    # the sixth digit): kept once, as the solvers that find it once do
    scale = np.abs(Xg).max((1, 2)) if len(Xg) else np.zeros(0)
    same = np.zeros(len(mi), bool)
    for o in (1, 2, 3):  # at most four solutions per triplet: each against those before it
        close = (mi[o:] == mi[:-o]) & (np.abs(Xg[o:] - Xg[:-o]).max((1, 2)) <= dup_tol * scale[o:])
        same[o:] |= close
    if same.any():
        first = np.flatnonzero(~same)
        mi, Xg = mi[first], Xg[first]
    Pg = P[mi]
    R = _frames(Xg[:, 0], Xg[:, 1], Xg[:, 2]) @ np.swapaxes(_frames(Pg[:, 0], Pg[:, 1], Pg[:, 2]), -1, -2)
    t = Xg.mean(1) - np.einsum("kij,kj->ki", R, Pg.mean(1))
    return R, t, mi
