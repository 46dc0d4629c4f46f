"""Line and conic fits to segmented contour points, with their covariances. Batched.

Both fits return, besides the curve, the information matrix (inverse covariance) of its
parameters for a contour-point noise of σ pixels along the curve normal. The solver uses
it as the paper's task-variable scaling G in Gauss–Markov form (§II.B.5): the distances of
projected model points to the observed curve are whitened by the observed curve's own
uncertainty, which makes the pose estimate reach the Cramér–Rao bound to first order.

Lines are fitted by total least squares (the maximum-likelihood fit for isotropic noise).
Conics start from Halir & Flusser's numerically stable direct ellipse fit and are refined by
Gauss–Newton on the Sampson distance, which equals the geometric distance to first order
(Fitzgibbon's algebraic fit alone over-weights the flat sides of eccentric ellipses). Conic
coefficients are kept in Hartley-normalised coordinates ``p_n = (p − m) / s`` with unit
norm; their 5-dimensional tangent space is spanned by an orthonormal basis ``basis``.

Arrays carry any leading batch shape ``(...)``; ``weights`` are 1 for a contour point and 0
for padding, so observations with different point counts can share one array.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Gauss–Newton refinements of the Sampson distance after the direct fit; the first one
#: does nearly all the work (the direct fit is already close), the second polishes.
SAMPSON_ITERATIONS = 2


@dataclass
class LineFit:
    """A line ``n · (p − m) + c = 0`` in pixels, with its information matrix.

    ``normal`` (..., 2) unit; ``anchor`` m (..., 2); ``offset`` c (...); ``info`` (..., 2, 2)
    is the inverse covariance of (δψ, δc) — ψ the normal's angle, c the offset — for unit
    noise (σ = 1 px), or NaN when unknown; ``rss`` the weighted residual sum of squares (px²)
    and ``dof`` its degrees of freedom.
    """

    normal: np.ndarray
    anchor: np.ndarray
    offset: np.ndarray
    info: np.ndarray
    rss: np.ndarray
    dof: np.ndarray


@dataclass
class ConicFit:
    """A conic ``θ · ξ(p_n) = 0`` with ``ξ = (x², xy, y², x, y, 1)``, ``p_n = (p − m) / s``.

    ``theta`` (..., 6) unit norm; ``center`` m (..., 2) px; ``scale`` s (...) px;
    ``basis`` (..., 6, 5) orthonormal, spanning the tangent space at θ; ``info`` (..., 5, 5)
    the inverse covariance of the tangent coordinates for unit noise (σ = 1 px), or NaN;
    ``rss`` px² and ``dof``.
    """

    theta: np.ndarray
    center: np.ndarray
    scale: np.ndarray
    basis: np.ndarray
    info: np.ndarray
    rss: np.ndarray
    dof: np.ndarray


def fit_line(points: np.ndarray, weights: np.ndarray | None = None) -> LineFit:
    """Total-least-squares line through ``points`` (..., n, 2) px."""
    p = np.asarray(points, float)
    w = np.ones(p.shape[:-1]) if weights is None else np.asarray(weights, float)
    sw = w.sum(-1)
    m = (p * w[..., None]).sum(-2) / sw[..., None]
    q = p - m[..., None, :]
    qx, qy = q[..., 0], q[..., 1]
    wqx = w * qx
    cxx = (wqx * qx).sum(-1)
    cyy = (w * qy * qy).sum(-1)
    cxy = (wqx * qy).sum(-1)
    ang = 0.5 * np.arctan2(2 * cxy, cxx - cyy)  # direction of largest spread
    dx, dy = np.cos(ang), np.sin(ang)
    n = np.empty(m.shape)
    n[..., 0] = -dy
    n[..., 1] = dx
    along = qx * dx[..., None] + qy * dy[..., None]
    r = qy * dx[..., None] - qx * dy[..., None]
    info = np.zeros(p.shape[:-2] + (2, 2))
    # the centroid makes the two parameters uncorrelated: Σ w (d·q) = 0
    info[..., 0, 0] = (w * along * along).sum(-1)
    info[..., 1, 1] = sw
    return LineFit(n, m, np.zeros(sw.shape), info, (w * r * r).sum(-1), sw - 2)


def line_from_coefficients(coef: np.ndarray, principal_point: np.ndarray) -> LineFit:
    """A line given as ``A u + B v + C = 0``; anchored at the foot of the perpendicular from
    the principal point. Its information is unknown (NaN)."""
    coef = np.asarray(coef, float)
    ab = np.linalg.norm(coef[..., :2], axis=-1)
    n = coef[..., :2] / ab[..., None]
    c = coef[..., 2] / ab
    pp = np.asarray(principal_point, float)
    dist = np.einsum("...i,...i->...", n, pp) + c
    m = pp - dist[..., None] * n
    shape = coef.shape[:-1]
    return LineFit(n, m, np.zeros(shape), np.full(shape + (2, 2), np.nan), np.zeros(shape), np.zeros(shape))


def conic_rows(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Rows (..., n, 3, 6) that turn conic coefficients θ into, per point, the conic's value
    ``Q = ξ·θ`` with ``ξ = (x², xy, y², x, y, 1)`` and its gradient ``∂Q/∂x, ∂Q/∂y`` —
    linear in θ, and fixed while a fit iterates on θ."""
    X3 = np.zeros(x.shape + (3, 6))
    X3[..., 0, 0] = x * x
    X3[..., 0, 1] = x * y
    X3[..., 0, 2] = y * y
    X3[..., 0, 3] = x
    X3[..., 0, 4] = y
    X3[..., 0, 5] = 1.0
    X3[..., 1, 0] = 2 * x
    X3[..., 1, 1] = y
    X3[..., 1, 3] = 1.0
    X3[..., 2, 1] = x
    X3[..., 2, 2] = 2 * y
    X3[..., 2, 4] = 1.0
    return X3


def tangent_basis(theta: np.ndarray) -> np.ndarray:
    """Orthonormal basis (..., 6, 5) of the complement of unit vectors ``theta`` (..., 6)."""
    # Householder reflection I − 2vvᵀ/|v|² with v = ±θ + e₀ maps e₀ to ∓θ; its other five
    # columns span θ's complement
    v = theta * np.copysign(1.0, theta[..., :1])
    v[..., 0] += 1.0
    out = v[..., :, None] * v[..., None, 1:] * (-2.0 / (v * v).sum(-1))[..., None, None]
    out += _E_TAIL  # columns 1..5 of I − 2vvᵀ/|v|²
    return out


_E_TAIL = np.eye(6)[:, 1:]


def sampson_theta_jacobian(theta: np.ndarray, x: np.ndarray, y: np.ndarray, rows: np.ndarray | None = None):
    """Sampson distances d = Q/|g| (..., n) and ∂d/∂θ (..., n, 6), in normalised units;
    ``rows`` is :func:`conic_rows` of (x, y) when the caller already has it."""
    X3 = conic_rows(x, y) if rows is None else rows
    q = (X3 @ theta[..., None, :, None])[..., 0]  # (..., n, 3): Q, gx, gy
    g = q[..., 1:]
    gn2 = (g * g).sum(-1)
    gn = np.sqrt(gn2)
    # ∂d/∂θ = (ξ − (Q/|g|²) Gᵀg) / |g|, G = ∂g/∂θ the gradient rows
    gtg = (g[..., None, :] @ X3[..., 1:, :])[..., 0, :]
    dd = X3[..., 0, :] - (q[..., 0] / gn2)[..., None] * gtg
    dd /= gn[..., None]
    return q[..., 0] / gn, dd


def _direct_ellipse(xi: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Halir & Flusser (1998) direct least-squares ellipse from design rows ξ (..., n, 6),
    batched; unit-norm θ."""
    S = np.swapaxes(xi * w[..., None], -1, -2) @ xi
    S1, S2, S3 = S[..., :3, :3], S[..., :3, 3:], S[..., 3:, 3:]
    T = -np.linalg.solve(S3, np.swapaxes(S2, -1, -2))
    M = _CINV @ (S1 + S2 @ T)
    _, vec = np.linalg.eig(M)
    vec = vec.real
    cond = 4 * vec[..., 0, :] * vec[..., 2, :] - vec[..., 1, :] ** 2
    # the ellipse eigenvector is the one with 4ac − b² > 0; take the most elliptic if noise
    # leaves several (it cannot leave none for points spread around a closed curve)
    a1 = np.take_along_axis(vec, cond.argmax(-1)[..., None, None], -1)  # (..., 3, 1)
    th = np.concatenate([a1, T @ a1], -2)[..., 0]
    return th / np.sqrt((th * th).sum(-1))[..., None]


_CINV = np.array([[0.0, 0.0, 0.5], [0.0, -1.0, 0.0], [0.5, 0.0, 0.0]])


def normalisation(points: np.ndarray, w: np.ndarray):
    """Hartley normalisation: centroid m (..., 2) and scale s (...) with RMS radius √2·s."""
    sw = w.sum(-1)
    m = (w[..., None, :] @ points)[..., 0, :] / sw[..., None]
    q = points - m[..., None, :]
    s = np.sqrt((w * (q * q).sum(-1)).sum(-1) / (2 * sw))
    return m, s


def fit_conic(points: np.ndarray, weights: np.ndarray | None = None, iterations: int = SAMPSON_ITERATIONS) -> ConicFit:
    """Conic through contour ``points`` (..., n ≥ 5, 2) px: direct ellipse fit, then Sampson
    Gauss–Newton, and the information matrix of the tangent coordinates (unit noise).

    The information, tangent basis and residuals are those of the last iterate before its
    step. That step is small (at the paper's 0.25 mm segmentation error, over 1,000
    simulated ellipses: 0.01 standard deviations typically, 0.3 at most) and the information
    varies with θ on the scale of the ellipse's shape, not of its noise, so a further pass
    to re-evaluate them would change nothing measurable and cost a third of the fit."""
    p = np.asarray(points, float)
    w = np.ones(p.shape[:-1]) if weights is None else np.asarray(weights, float)
    m, s = normalisation(p, w)
    q = (p - m[..., None, :]) / s[..., None, None]
    x, y = q[..., 0], q[..., 1]
    rows = conic_rows(x, y)
    theta = _direct_ellipse(rows[..., 0, :], w)
    for it in range(max(iterations, 1)):
        basis = tangent_basis(theta)
        d, dd = sampson_theta_jacobian(theta, x, y, rows)
        G = dd @ basis  # (..., n, 5)
        Gw = np.swapaxes(G * w[..., None], -1, -2)
        info = Gw @ G
        if not iterations:
            break
        step = np.linalg.solve(info, -(Gw @ d[..., None]))
        theta = theta + (basis @ step)[..., 0]
        theta /= np.sqrt((theta * theta).sum(-1))[..., None]
    # pixel distances are s × normalised ones: ∂d_px/∂θ = s ∂d_n/∂θ, information × s²
    s2 = s * s
    return ConicFit(theta, m, s, basis, info * s2[..., None, None], (w * d * d).sum(-1) * s2, w.sum(-1) - 5)


def conic_matrix(theta: np.ndarray) -> np.ndarray:
    """Symmetric 3×3 matrix of conic coefficients (A, B, C, D, E, F)."""
    A, B, C, D, E, F = np.moveaxis(theta, -1, 0)
    return np.stack(
        [np.stack([A, B / 2, D / 2], -1), np.stack([B / 2, C, E / 2], -1), np.stack([D / 2, E / 2, F], -1)], -2
    )


def conic_vector(M: np.ndarray) -> np.ndarray:
    """Inverse of :func:`conic_matrix`."""
    return np.stack(
        [M[..., 0, 0], 2 * M[..., 0, 1], M[..., 1, 1], 2 * M[..., 0, 2], 2 * M[..., 1, 2], M[..., 2, 2]], -1
    )


def conic_center_and_axes(theta: np.ndarray):
    """Centre (..., 2) and semi-axes (a ≥ b) of an ellipse given by θ, in θ's coordinates."""
    M = conic_matrix(theta)
    A2 = M[..., :2, :2]
    c = -np.linalg.solve(A2, M[..., :2, 2:3])[..., 0]
    F0 = M[..., 2, 2] + np.einsum("...i,...i->...", M[..., :2, 2], c)
    ev = np.linalg.eigvalsh(A2)
    ax = np.sqrt(np.abs(-F0[..., None] / ev))
    return c, np.max(ax, -1), np.min(ax, -1)


def conic_from_coefficients(coef: np.ndarray) -> ConicFit:
    """A conic given as pixel coefficients (A…F), re-expressed in coordinates normalised
    about its centre and by its mean semi-axis. Its information is unknown (NaN)."""
    coef = np.asarray(coef, float)
    c, a, b = conic_center_and_axes(coef / np.linalg.norm(coef, axis=-1, keepdims=True))
    s = np.sqrt(a * b) / np.sqrt(2.0)
    H = np.zeros(coef.shape[:-1] + (3, 3))
    H[..., 0, 0] = s
    H[..., 1, 1] = s
    H[..., :2, 2] = c
    H[..., 2, 2] = 1.0
    Mn = np.swapaxes(H, -1, -2) @ conic_matrix(coef) @ H
    theta = conic_vector(Mn)
    theta /= np.linalg.norm(theta, axis=-1, keepdims=True)
    shape = coef.shape[:-1]
    return ConicFit(
        theta, c, s, tangent_basis(theta), np.full(shape + (5, 5), np.nan), np.zeros(shape), np.zeros(shape)
    )
