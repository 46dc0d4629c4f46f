"""Sub-pixel centre-line points of thin bright wires: Steger's ridge detector.

At the wire's scale σ the Hessian of the (background-free) density image has, across a
wire, one strongly negative eigenvalue λ whose eigenvector n is the wire's normal; along
it, the second-order Taylor model peaks at ``t = −(n·∇g) / (nᵀ H n)``. A pixel is a ridge
point when that peak lies inside the pixel (|t nₓ|, |t n_y| ≤ ½), and the point
``p + t n`` is the sub-pixel centre-line position (C. Steger, *An unbiased detector of
curvilinear structures*, IEEE PAMI 20(2), 1998). For a symmetric wire profile on a flat
background the estimate is unbiased whatever the blur; the top-hat makes the background
flat, and the identification later drops points near crossings and beads, where the
profile is not symmetric.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .image import derivatives


@dataclass
class RidgePoints:
    """Ridge points: ``uv`` (n, 2) px, ``normal`` (n, 2) unit, ``strength`` (n,) the
    scale-normalised curvature σ²|λ| (density units), ``snr`` (n,) strength over its noise."""

    uv: np.ndarray
    normal: np.ndarray
    strength: np.ndarray
    snr: np.ndarray

    def take(self, keep: np.ndarray) -> "RidgePoints":
        """The points selected by boolean or index array ``keep``."""
        return RidgePoints(self.uv[keep], self.normal[keep], self.strength[keep], self.snr[keep])

    def __len__(self) -> int:
        return len(self.uv)


def ridge_points(
    img: np.ndarray,
    sigma: float,
    noise: float | np.ndarray,
    min_snr: float = 6.0,
    max_aspect: float = 0.5,
    derivs: dict[str, np.ndarray] | None = None,
) -> RidgePoints:
    """Steger ridge points of bright lines in ``img`` (float32, background removed) at scale
    ``sigma`` px. ``noise`` is the pixel noise σ of ``img`` (one number or a map (H, W)); a point is kept when its
    curvature exceeds ``min_snr`` times the curvature that noise alone produces, and when
    the curvature along the line is at most ``max_aspect`` of that across it (which
    rejects blobs). ``derivs``: :func:`.image.derivatives` of ``img`` at ``sigma``, when
    already computed."""
    d = derivs if derivs is not None else derivatives(img, sigma)
    xx, xy, yy = d["xx"], d["xy"], d["yy"]
    # white noise of σ through the second-derivative filter: σ·‖g2⊗g0‖ (≈ σ·0.61/σ_s³·…);
    # measured here from the kernels so it is exact for the sampled filter
    from .image import gaussian_kernels

    g0, _, g2 = gaussian_kernels(sigma)
    noise_curv = noise * float(np.sqrt((g2.astype(np.float64) ** 2).sum() * (g0.astype(np.float64) ** 2).sum()))
    # most negative eigenvalue of [[xx, xy], [xy, yy]]
    half_tr = 0.5 * (xx + yy)
    disc = np.sqrt(0.25 * (xx - yy) ** 2 + xy * xy)
    lam = half_tr - disc
    cand = np.flatnonzero((-lam > min_snr * noise_curv).ravel())
    if cand.size == 0:
        z = np.zeros((0, 2))
        return RidgePoints(z, z, np.zeros(0), np.zeros(0))
    W = img.shape[1]
    j, i = np.divmod(cand, W)
    fxx, fxy, fyy = xx.ravel()[cand].astype(float), xy.ravel()[cand].astype(float), yy.ravel()[cand].astype(float)
    fx, fy = d["x"].ravel()[cand].astype(float), d["y"].ravel()[cand].astype(float)
    l1 = lam.ravel()[cand].astype(float)
    nc = noise_curv.ravel()[cand].astype(float) if np.ndim(noise_curv) == 2 else noise_curv
    l2 = (half_tr + disc).ravel()[cand].astype(float)
    # eigenvector of l1: (xy, l1 − xx) or (l1 − yy, xy), whichever is better conditioned
    a = np.stack([fxy, l1 - fxx], -1)
    b = np.stack([l1 - fyy, fxy], -1)
    n = np.where((np.abs(a).sum(1) >= np.abs(b).sum(1))[:, None], a, b)
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)
    nx, ny = n[:, 0], n[:, 1]
    curv = fxx * nx * nx + 2 * fxy * nx * ny + fyy * ny * ny
    with np.errstate(all="ignore"):
        t = -(fx * nx + fy * ny) / curv
    ok = (np.abs(t * nx) <= 0.5) & (np.abs(t * ny) <= 0.5) & (np.abs(l2) <= max_aspect * np.abs(l1))
    uv = np.stack([i + t * nx, j + t * ny], -1)[ok]
    strength = -l1[ok] * sigma * sigma
    return RidgePoints(uv, n[ok], strength, -l1[ok] / (nc[ok] if np.ndim(nc) else nc))
