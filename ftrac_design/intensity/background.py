"""The smooth background as nuisance parameters: its basis over a region of interest, and the
weighted projection that eliminates it.

An anatomy background under the fiducial is smooth on the scale of the soft tissue and has
edges (bone cortex) that no smooth model follows. Two bases:

- :func:`polynomial_basis` — monomials ``uᵃvᵇ`` (a + b ≤ degree) over the ROI (the plain
  model: gain + quadratic);
- :func:`spline_basis` — tensor-product cubic B-splines with knots every ``spacing_px``
  pixels (uniform, the end knots on the ROI's border), the default of
  :func:`..refine.refine_intensity`: it follows soft-tissue variation on the scale of its
  knots and, unlike a high-pass filter applied to image and model, leaves the pixel noise
  white, so the fit stays a maximum-likelihood fit whose bound is the Schur complement
  below. Its span includes every polynomial of degree ≤ 3 in each coordinate.

:class:`Nuisance` holds such a basis ``N`` (k, n) (sparse) with pixel weights ``w`` and
applies the W-orthogonal projection ``P x = x − Nᵀ (N W Nᵀ)⁻¹ N W x`` (``N W Nᵀ`` factored
once per set of weights: banded Cholesky for the spline, whose Gram matrix is assembled from
1-D products, dense Cholesky for a few monomials). The
information of the pose with the background unknown is then ``(P J) W (P J)ᵀ`` — the Schur
complement of the joint information — without forming a k × k inverse.
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import BSpline
from scipy.linalg import cho_factor, cho_solve, cho_solve_banded, cholesky_banded


def polynomial_basis(shape: tuple[int, int], degree: int) -> np.ndarray:
    """(k, rows, cols) monomials uᵃvᵇ (a + b ≤ degree) in coordinates scaled to [−1, 1]."""
    h, w = shape
    v = np.linspace(-1, 1, h)[:, None] * np.ones((1, w))
    u = np.ones((h, 1)) * np.linspace(-1, 1, w)[None, :]
    return np.array([u**a * v**b for a in range(degree + 1) for b in range(degree + 1 - a)])


def _bspline_1d(n: int, spacing_px: float) -> np.ndarray:
    """(n, m) cubic B-spline design matrix over pixel centres 0 … n−1, uniform knots about
    ``spacing_px`` apart with the end knots on the first and last pixel."""
    intervals = max(int(np.ceil((n - 1) / float(spacing_px))), 1)
    step = max(n - 1, 1) / intervals
    knots = np.arange(-3, intervals + 4) * step
    x = np.minimum(np.arange(n, dtype=float), knots[intervals + 3])  # the last centre on the end knot
    return BSpline.design_matrix(x, knots, 3).toarray()


class TensorSpline:
    """Tensor cubic B-splines over an ROI of ``shape`` with knots every ~``spacing_px`` px:
    basis function (a, b) = ``Bv[:, a] ⊗ Bu[:, b]`` (rows × cols); k = na · nb of them, in
    that (row-major) order. Products with it use the separable, banded structure (each pixel
    meets 4 × 4 of them), never an n × k matrix."""

    def __init__(self, shape: tuple[int, int], spacing_px: float):
        if not spacing_px > 0:
            raise ValueError("spacing_px: a positive knot spacing in pixels")
        self.shape = (int(shape[0]), int(shape[1]))
        self.Bv = _bspline_1d(self.shape[0], spacing_px)
        self.Bu = _bspline_1d(self.shape[1], spacing_px)
        self.na, self.nb = self.Bv.shape[1], self.Bu.shape[1]

    @property
    def k(self) -> int:
        """Number of basis functions."""
        return self.na * self.nb

    def dense(self) -> np.ndarray:
        """(k, rows·cols) explicit basis (for tests and small ROIs)."""
        return np.einsum("ja,ib->abji", self.Bv, self.Bu).reshape(self.k, -1)

    def apply(self, X: np.ndarray) -> np.ndarray:
        """N X for pixel vectors X (m, n): (m, k) projections ``Bvᵀ X Bu``."""
        h, w = self.shape
        Xi = np.asarray(X, float).reshape(-1, h, w)
        return np.einsum("ja,mji,ib->mab", self.Bv, Xi, self.Bu, optimize=True).reshape(len(Xi), self.k)

    def synthesize(self, b: np.ndarray) -> np.ndarray:
        """Nᵀ b for coefficients b (m, k): (m, n) images ``Bv B Buᵀ``."""
        Bm = np.asarray(b, float).reshape(-1, self.na, self.nb)
        return np.einsum("ja,mab,ib->mji", self.Bv, Bm, self.Bu, optimize=True).reshape(len(Bm), -1)

    def gram_banded(self, w: np.ndarray) -> np.ndarray:
        """``N W Nᵀ`` in the upper banded storage of :func:`scipy.linalg.cholesky_banded`
        (bandwidth 3 nb + 3): cubic B-splines overlap only within 3 knots per axis."""
        h, wd = self.shape
        W = np.asarray(w, float).reshape(h, wd)
        na, nb, Bv, Bu = self.na, self.nb, self.Bv, self.Bu
        # M[o][j, b] = Σ_i W[j, i] Bu[i, b] Bu[i, b + o]  (o = 0…3)
        M = [W @ (Bu[:, : nb - o] * Bu[:, o:]) for o in range(4)]
        band = 3 * nb + 3
        ab = np.zeros((band + 1, self.k))
        for oa in range(4):
            Pv = Bv[:, : na - oa] * Bv[:, oa:]  # (h, na − oa)
            for ob in range(-3, 4):
                if oa == 0 and ob < 0:
                    continue  # the lower triangle
                Mo = M[abs(ob)]  # (h, nb − |ob|)
                C = Pv.T @ Mo  # (na − oa, nb − |ob|)
                off = oa * nb + ob
                # entry (a, b)-(a + oa, b + ob): column index of the later one
                a_idx = np.arange(na - oa)[:, None]
                b_idx = np.arange(nb - abs(ob))[None, :] + (max(-ob, 0))
                col = (a_idx + oa) * nb + b_idx + ob
                ab[band - off, col.ravel()] = C.ravel()
        return ab


def spline_basis(shape: tuple[int, int], spacing_px: float) -> TensorSpline:
    """Tensor cubic B-splines over an ROI of ``shape`` (row-major pixels), knots every
    ~``spacing_px`` px; k = (⌈(rows−1)/s⌉ + 3)(⌈(cols−1)/s⌉ + 3) of them."""
    return TensorSpline(shape, spacing_px)


def background_basis(shape: tuple[int, int], degree: int = 2, spline_px: float | None = None):
    """The background columns: a :class:`TensorSpline` of knot spacing ``spline_px``, else
    monomials of ``degree`` as a dense (k, rows·cols) array (``degree < 0``: none)."""
    if spline_px:
        return spline_basis(shape, spline_px)
    if degree < 0:
        return np.zeros((0, shape[0] * shape[1]))
    return polynomial_basis(shape, degree).reshape(-1, shape[0] * shape[1])


class Nuisance:
    """W-orthogonal projection off the columns ``N`` — a dense (k, n) array or a
    :class:`TensorSpline` — with pixel weights ``w`` (n,); see the module."""

    def __init__(self, N, w: np.ndarray):
        self.w = np.asarray(w, float)
        self.N = N
        self.k = 0 if N is None else (N.k if isinstance(N, TensorSpline) else N.shape[0])
        if self.k == 0:
            return
        if isinstance(N, TensorSpline):
            ab = N.gram_banded(self.w)
            # tiny ridge: a basis function whose support holds only zero-weight pixels
            ab[-1] += 1e-13 * max(float(ab[-1].mean()), 1e-300)
            cb = cholesky_banded(ab)
            self._solve = lambda rhs: cho_solve_banded((cb, False), rhs)
        else:
            C = (N * self.w) @ N.T
            ridge = 1e-12 * max(float(np.trace(C)) / self.k, 1e-300)
            cf = cho_factor(C + ridge * np.eye(self.k))
            self._solve = lambda rhs: cho_solve(cf, rhs)

    def coefficients(self, X: np.ndarray) -> np.ndarray:
        """Weighted least-squares background coefficients (k,) or (k, m) of X (n,) or (m, n)."""
        if self.k == 0:
            return np.zeros((0,) + np.shape(X)[:-1])
        Xw = np.atleast_2d(X) * self.w
        rhs = self.N.apply(Xw).T if isinstance(self.N, TensorSpline) else self.N @ Xw.T  # (k, m)
        b = self._solve(rhs)
        return b[:, 0] if np.ndim(X) == 1 else b

    def fitted(self, b: np.ndarray) -> np.ndarray:
        """The background Nᵀ b (n,) or (m, n) of coefficients (k,) or (k, m)."""
        if self.k == 0:
            return np.zeros(self.w.shape if np.ndim(b) == 1 else (np.shape(b)[1],) + self.w.shape)
        bb = np.asarray(b, float).reshape(self.k, -1)
        out = self.N.synthesize(bb.T) if isinstance(self.N, TensorSpline) else (self.N.T @ bb).T
        return out[0] if np.ndim(b) == 1 else out

    def project(self, X: np.ndarray) -> np.ndarray:
        """X minus its weighted least-squares background: P X, (n,) or (m, n)."""
        if self.k == 0:
            return np.array(X, float)
        return X - self.fitted(self.coefficients(X))


def schur_information(J: np.ndarray, N, w: np.ndarray, extra: np.ndarray | None = None) -> np.ndarray:
    """Information (6 × 6) of the parameters with columns ``J`` (m, n) when the background
    ``N`` (dense (k, n), a :class:`TensorSpline`, or None) and the further nuisance columns
    ``extra`` (e, n; e.g. the gain's) are unknown too; pixel weights ``w`` (n,): the Schur
    complement ``A − B C⁻¹ Bᵀ`` of the joint information, as ``(P J) W (P J)ᵀ`` with P the
    W-orthogonal projection off all nuisance columns."""
    nu = Nuisance(N, w)
    Jp = nu.project(J)
    if extra is not None and len(extra):
        Ep = nu.project(np.atleast_2d(extra))
        G = (Ep * w) @ Ep.T
        Jp = Jp - np.linalg.solve(G, (Ep * w) @ Jp.T).T @ Ep
    F = (Jp * w) @ Jp.T
    return (F + F.T) / 2
