"""Pixel-level Cramér–Rao bound of the pose from one radiograph.

With Poisson counts ``N_i ~ Poisson(μ_i)``, ``μ_i = N0 I_i(θ) e^{−b_i}`` (``I_i`` the blurred
transmission of the fiducial, ``b_i`` a known background line integral), the Fisher
information of the pose θ = (rx, ry, rz, tx, ty, tz) is

    F = Σ_i (∂μ_i/∂θ)(∂μ_i/∂θ)ᵀ / μ_i = Σ_i N0 e^{−b_i} (∂I_i/∂θ)(∂I_i/∂θ)ᵀ / I_i,

the same as in the log domain, where ``var(−ln N_i) ≈ 1/μ_i``. Raw quantisation (step
1/gain ≈ 0.2 quanta at 16 bits) is neglected. ``nuisance=True`` gives the bound when the
image's gain and a smooth background (a polynomial in u, v, or the cubic B-spline that
:func:`..refine.refine_intensity` fits by default) are unknown as well — the Schur
complement of the full information — which is what the refinement can reach.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from threadpoolctl import threadpool_limits

from ..features.model import Features
from ..pose.camera import Camera
from ..xray.model import ImagingModel
from .background import background_basis, polynomial_basis  # noqa: F401 (polynomial_basis: re-export)
from .background import schur_information as _schur
from .model import RoiModel, roi_around


@dataclass
class PixelBound:
    """Fisher information (6 × 6) of (rx, ry, rz, tx, ty, tz), its inverse and the per-axis
    standard deviations (rad, rad, rad, mm, mm, mm), over ``roi`` (row0, col0, rows, cols)."""

    information: np.ndarray
    covariance: np.ndarray
    std: np.ndarray
    roi: tuple[int, int, int, int]

    @property
    def std_deg_mm(self) -> np.ndarray:
        """std with the rotations in degrees."""
        return np.concatenate([np.degrees(self.std[:3]), self.std[3:]])


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Contraction over the last axis of both: ``a @ b.T`` (a 1-D operand: a vector). Without
    BLAS: these products are a few × 50,000 pixels, where a threaded BLAS spends more time
    waking and spinning its threads than multiplying (measured: refinement CPU time 0.90 →
    0.44 s on the loaded 2-core machine with one BLAS thread)."""
    sa = "in" if a.ndim == 2 else "n"
    sb = "jn" if b.ndim == 2 else "n"
    out = ("i" if a.ndim == 2 else "") + ("j" if b.ndim == 2 else "")
    return np.einsum(f"{sa},{sb}->{out}", a, b)


def schur_information(J: np.ndarray, N, w: np.ndarray) -> np.ndarray:
    """Information of the first parameters, columns ``J`` (6, n), with nuisance columns
    ``N`` (k, n) unknown too; pixel weights ``w`` (n,) (:func:`.background.schur_information`)."""
    return _schur(J, N if N is not None and len(N) else None, w)


def pixel_information(
    features: Features,
    R: np.ndarray,
    t: np.ndarray,
    camera: Camera = Camera(),
    imaging: ImagingModel = ImagingModel(),
    background: np.ndarray | None = None,
    roi: tuple[int, int, int, int] | None = None,
    nuisance: bool = False,
    background_degree: int = 2,
    background_spline_px: float | None = None,
) -> PixelBound:
    """Pixel-level Cramér–Rao bound of the pose at (R, t) under ``imaging`` (see the module); the
    fiducial's body (``features.body``, where known) is part of the image.

    ``background`` (H, W) is a known line-integral image (it lowers the counts); ``roi``
    defaults to the fiducial's projection plus 12 px. ``nuisance=True``: the gain and a smooth
    background are unknown as well — a polynomial of ``background_degree`` or, with
    ``background_spline_px``, the cubic B-spline of that knot spacing that
    :func:`..refine.refine_intensity` fits by default (:mod:`.background`). Raises ValueError
    for a noise-free imaging model (the information is infinite).
    """
    if not imaging.noisy:
        raise ValueError("a pixel-level bound needs a finite dose (photons_per_px)")
    R, t = np.asarray(R, float), np.asarray(t, float)
    if roi is None:
        roi = roi_around(features, R, t, camera, imaging.image_shape)
    model = RoiModel(features, camera, imaging, roi)
    I, JI = model.jacobian(R, t, what="transmission")
    v0, u0, h, w = roi
    scale = np.full(I.shape, float(imaging.photons_per_px))
    if background is not None:
        scale *= np.exp(-np.asarray(background, float)[v0 : v0 + h, u0 : u0 + w])
    mu = scale * I  # expected counts
    # log domain: ∂L = −∂I / I, var L = 1/μ
    JL = (-JI / I).reshape(6, -1)
    wts = mu.ravel()
    if nuisance:
        bg = background_basis(I.shape, background_degree, background_spline_px)
        with threadpool_limits(1, "blas"):  # small products: see refine.refine_intensity
            F = _schur(JL, bg, wts, extra=(-np.log(I)).reshape(1, -1))  # the gain's column: L itself
    else:
        F = schur_information(JL, None, wts)
    cov = np.linalg.inv(F)
    return PixelBound(F, cov, np.sqrt(np.diag(cov)), roi)
