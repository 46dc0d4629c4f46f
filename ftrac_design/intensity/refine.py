"""Intensity-based refinement of a pose: fit the simulator's image to the radiograph.

From a start (R0, t0) — the feature path's pose — minimise over the pose θ and nuisance
parameters the noise-weighted squared difference between the image's log values ``Y`` and
the model ``g L(θ) + B(β)`` over a region of interest around the fiducial:

- ``L(θ)``: the simulator's noise-free log image of the fiducial (:class:`.model.RoiModel`),
- ``g``: an unknown gain (a display image's contrast scale), ``B(β)``: a smooth background,
  a polynomial in (u, v) of ``background_degree`` (its constant term is the offset) — or,
  by default, a high-pass (image minus its Gaussian blur of ``highpass_px``) applied to image
  and model alike, with Huber weights against anatomy clutter,
- weights ``1/var(Y_i) = N0 e^{−Ŷ_i}`` (Poisson counts in the log domain) from the fitted
  model Ŷ, or uniform for a noise-free imaging model.

The nuisance parameters enter linearly and are eliminated exactly at every pose (variable
projection, Kaufman's Jacobian); the pose takes Levenberg–Marquardt steps in the solver's
so(3) parametrisation (``R ← exp([δ]ₓ) R``, ``t ← t + δt``). A coarse-to-fine schedule
smooths image and model alike by Gaussians of ``scales`` px first, which widens the basin
(a thin wire is ~2 px wide). A step is kept only if it lowers the objective, and the result
is the start itself when the final objective at full resolution would be worse, so the
refinement never ends worse than its start. The covariance is the inverse of the
information of the pose with the nuisance parameters unknown (Schur complement), at the
model's noise, i.e. the pixel-level Cramér–Rao bound of :mod:`.bound` with nuisance.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.ndimage import gaussian_filter

from ..features.model import Features
from ..pose.camera import Camera
from ..xray.model import Body, ImagingModel
from ..xray.render import AUTO, resolve_body
from .bound import _dot, polynomial_basis, schur_information
from .model import STEP_PX, RoiModel, perturb, roi_around


@dataclass
class IntensityResult:
    """The refined pose (F → X), its covariance (6 × 6, order rx ry rz tx ty tz; rad, mm),
    the objective at the start and the end (full resolution, weighted), and diagnostics."""

    rotation: np.ndarray
    translation_mm: np.ndarray
    covariance: np.ndarray | None
    converged: bool
    cost_start: float
    cost_end: float
    iterations: int
    gain: float
    background: np.ndarray
    roi: tuple[int, int, int, int]
    rms_residual: float
    message: str = ""
    history: list = field(default_factory=list)

    @property
    def std(self) -> np.ndarray:
        """Predicted 1σ (rad ×3, mm ×3)."""
        return np.sqrt(np.diag(self.covariance)) if self.covariance is not None else np.full(6, np.nan)

    def to_dict(self) -> dict[str, Any]:
        """SPEC §4 pose object plus an ``intensity`` block of diagnostics."""
        ok = self.covariance is not None and np.all(np.isfinite(self.covariance))
        return {"format": "ftrac-pose", "version": 1, "rotation": self.rotation.tolist(),
                "translation_mm": self.translation_mm.tolist(), "converged": bool(self.converged),
                "rms_residual_px": None,
                "covariance": self.covariance.tolist() if ok else None,
                "covariance_order": ["rx", "ry", "rz", "tx", "ty", "tz"],
                "intensity": {"cost_start": self.cost_start, "cost_end": self.cost_end,
                              "iterations": self.iterations, "gain": self.gain, "roi": list(self.roi),
                              "rms_residual_log": self.rms_residual, "message": self.message}}


class _Problem:
    """The objective at one smoothing scale."""

    def __init__(self, model: RoiModel, Y: np.ndarray, imaging: ImagingModel, scale: float, degree: int,
                 highpass: float = 0.0, robust: float | None = None):
        self.model, self.scale, self.imaging, self.highpass, self.robust = model, scale, imaging, highpass, robust
        self.Yraw = Y
        self.Y = self.smooth(Y)
        if highpass > 0:
            degree = -1                             # the high-pass removes any smooth background
        self.basis = polynomial_basis(Y.shape, degree).reshape(-1, Y.size) if degree >= 0 else np.zeros((0, Y.size))
        self.w = np.ones(Y.size)

    def smooth(self, a: np.ndarray) -> np.ndarray:
        if a.ndim == 3:
            return np.array([self.smooth(x) for x in a])
        if self.scale > 0:
            a = gaussian_filter(a, self.scale)
        if self.highpass > 0:
            a = a - gaussian_filter(a, self.highpass)
        return a

    def fit(self, L: np.ndarray):
        """Nuisance fit for model image L: (cost, residual, coefficients, design)."""
        Phi = np.concatenate([L.reshape(1, -1), self.basis])
        A = _dot(Phi * self.w, Phi)
        coef = np.linalg.solve(A + 1e-12 * np.trace(A) / len(A) * np.eye(len(A)), _dot(Phi * self.w, self.Y.ravel()))
        r = self.Y.ravel() - _dot(coef, Phi.T)
        return float(np.sum(self.w * r * r)), r, coef, Phi

    def cost(self, R, t):
        L = self.smooth(self.model.log_image(R, t))
        return self.fit(L)

    def set_weights(self, coef: np.ndarray, Phi: np.ndarray, r: np.ndarray | None = None) -> None:
        """Poisson weights N0 e^{−p̂} (p̂ from the fitted model, or from the smoothed image
        with a high-pass), times Huber weights of the residual ``r`` with ``robust``."""
        if self.imaging.noisy:
            N0 = float(self.imaging.photons_per_px)
            if self.highpass > 0 or len(coef) < 2:
                Ys = gaussian_filter(self.Yraw, 2.0).ravel()
                self.w = N0 * np.exp(-np.clip(Ys - Ys.min(), 0, 20))
            else:
                fitted = _dot(coef, Phi.T)
                # the fitted log image carries the gain's scale: back to line-integral units
                g = coef[0] if abs(coef[0]) > 1e-6 else 1.0
                self.w = N0 * np.exp(-np.clip(fitted / g - (coef[1] / g), -5, 20))
            if self.scale > 0:                      # smoothing lowers the variance: keep the shape only
                self.w = self.w / self.w.mean()
        else:
            self.w = np.ones_like(self.w)
        if self.robust and r is not None:
            z = np.abs(r) * np.sqrt(self.w)
            sd = 1.4826 * np.median(z) if not self.imaging.noisy or self.scale > 0 else 1.0
            self.w = self.w * np.minimum(1.0, self.robust * max(sd, 1e-300) / np.maximum(z, 1e-300))


def history_drop(history: list) -> float:
    """Objective decrease of the last accepted step at the same scale (inf if none before)."""
    if len(history) < 2 or history[-2][0] != history[-1][0]:
        return float("inf")
    return history[-2][1] - history[-1][1]


def _log_of(image: np.ndarray, polarity: str) -> np.ndarray:
    img = np.asarray(image, float)
    if polarity == "dense_bright":
        return img
    if polarity == "dense_dark":
        return -np.log(np.maximum(img, 0.5))
    raise ValueError("polarity: 'dense_bright' (log/display image) or 'dense_dark' (raw counts)")


def refine_intensity(features: Features, image: np.ndarray, camera: Camera, R0: np.ndarray, t0: np.ndarray = None,
                     imaging: ImagingModel = ImagingModel(), roi: tuple[int, int, int, int] | None = None,
                     body: Body | None | str = AUTO, polarity: str = "dense_bright",
                     scales: tuple[float, ...] = (2.0, 0.0), background_degree: int = 2, max_iterations: int = 12,
                     tolerance: float = 1e-4, ftol: float = 1e-7, central_covariance: bool = False,
                     highpass_px: float = 8.0, robust: float | None = 3.0,
                     central_steps: bool = False) -> IntensityResult:
    """Refine the pose (R0, t0) of ``features`` on ``image`` (H, W) — see the module.

    ``image``: a log image (``polarity="dense_bright"``, −ln(I/I0) up to gain and offset) or
    raw counts (``"dense_dark"``). ``imaging`` supplies the blur, the energy and the dose
    (weights; ``photons_per_px=None``: uniform weights and a covariance scaled by the fitted
    residual). ``roi`` = (row0, col0, rows, cols), default the fiducial at the start plus 12 px.
    ``highpass_px`` > 0 (default 8) subtracts a Gaussian of that σ from image and model alike
    instead of fitting the polynomial background — anatomy has structure a quadratic cannot
    follow; ``robust`` = c (default 3) gives Huber weights at full resolution (residuals beyond
    c σ down-weighted, fixed from the residual where that scale starts) against clutter such
    as bone edges. Over an anatomy-like background they cut the errors from 6–30× the
    pixel bound (quadratic background) to 1.4–2.3×; on clean images both reach the bound
    (``benchmarks/intensity_accuracy.py``). ``highpass_px=0, robust=None`` is the plain
    gain + polynomial model. Each scale stops when a step moves the features by less than ``tolerance`` px or lowers
    the objective by less than ``ftol`` of itself (with Poisson weights the objective is a
    χ² of ~n pixels, so 1e-7 is ≪ 1). The covariance uses the last iteration's (forward
    difference) Jacobian, or a fresh central-difference one with ``central_covariance``.
    ``central_steps=True`` takes the LM steps on central differences (twice the renders; on
    300 images it changed no axis's efficiency beyond sampling, depth 0.861 → 0.864:
    ``benchmarks/intensity_depth_check.py``).
    """
    if hasattr(R0, "pose") and isinstance(features, np.ndarray):
        # the call form of cli/track.py, refine_fn(image, features, camera, track_result):
        # forwarded until it calls refine_track_result itself
        return refine_track_result(features, image, camera, R0)
    R0, t0 = np.asarray(R0, float), np.asarray(t0, float)
    body = resolve_body(features, body)
    Yfull = _log_of(image, polarity)
    if roi is None:
        roi = roi_around(features, R0, t0, camera, Yfull.shape, body)
    v0, u0, h, w = roi
    Y = Yfull[v0:v0 + h, u0:u0 + w]
    model = RoiModel(features, camera, imaging, body, roi)
    steps = model.steps(t0) / STEP_PX              # parameter change that moves features ~1 px
    R, t = R0.copy(), t0.copy()

    full = _Problem(model, Y, imaging, 0.0, background_degree, highpass_px, robust)
    c, r, coef, Phi = full.cost(R, t)
    full.set_weights(coef, Phi, r)
    cost_start, _, _, _ = full.cost(R, t)
    history, iterations, message = [], 0, ""
    for scale in scales:
        # robust weights only at full resolution: at a coarse scale far from the pose the
        # largest residuals are the fiducial's own misaligned wires
        prob = _Problem(model, Y, imaging, scale, background_degree, highpass_px, robust if scale == 0 else None)
        cst, r, coef, Phi = prob.cost(R, t)
        prob.set_weights(coef, Phi, r)
        cst, r, coef, Phi = prob.cost(R, t)
        lam = 1e-3
        J = None
        for _ in range(max_iterations):
            iterations += 1
            L0 = model.log_image(R, t)
            _, J = model._differences(R, t, "log", central=central_steps, value=L0)
            J = prob.smooth(J).reshape(6, -1) * coef[0]
            # Kaufman: project the pose columns off the nuisance columns
            A = _dot(Phi * prob.w, Phi)
            Jp = J - _dot(np.linalg.solve(A, _dot(Phi * prob.w, J)).T, Phi.T)
            H = _dot(Jp * prob.w, Jp)
            g = _dot(Jp * prob.w, r)
            D = np.diag(H).copy()
            accepted = False
            for _ in range(8):
                try:
                    dx = np.linalg.solve(H + lam * np.diag(D), g)
                except np.linalg.LinAlgError:
                    lam *= 10
                    continue
                Rn, tn = perturb(R, t, dx)
                cn, rn, coefn, Phin = prob.cost(Rn, tn)
                if cn < cst:
                    R, t, cst, r, coef, Phi = Rn, tn, cn, rn, coefn, Phin
                    lam = max(lam / 3, 1e-7)
                    accepted = True
                    break
                lam *= 4
            history.append((scale, cst, lam))
            if not accepted:
                message = f"no decrease at scale {scale:g} px"
                break
            if np.max(np.abs(dx) / steps) < tolerance or history_drop(history) < ftol * cst:
                break
    c_end, r, coef, Phi = full.cost(R, t)
    converged = True
    if c_end > cost_start:
        R, t, converged, message = R0.copy(), t0.copy(), False, "refinement did not lower the objective; start kept"
        c_end, r, coef, Phi = full.cost(R, t)
    # covariance: information of the pose with gain and background unknown (the weights the
    # objective used, so that cost_end stays comparable)
    if central_covariance or J is None or scales[-1] != 0.0 or not converged:
        L0, Jc = model.jacobian(R, t)
        Jc = full.smooth(Jc).reshape(6, -1) * coef[0]
    else:
        L0, Jc = model.log_image(R, t), J
    c_end_w, r, coef, Phi = full.fit(full.smooth(L0))
    F = schur_information(Jc, Phi, full.w)
    try:
        cov = np.linalg.inv(F)
        if not imaging.noisy:
            cov *= c_end_w / max(r.size - 6 - len(Phi), 1)
    except np.linalg.LinAlgError:
        cov = None
    rms = float(math.sqrt(np.mean(r * r)))
    return IntensityResult(R, t, cov, converged, cost_start, c_end, iterations, float(coef[0]), coef[1:], roi, rms,
                           message, history)


def refine_track_result(image: np.ndarray, features: Features, camera: Camera, result, imaging: ImagingModel | None = None,
                        body: Body | None | str = AUTO, **options):
    """``ftrac-design track --refine intensity``: refine a converged
    :class:`ftrac_design.segment.pipeline.TrackResult` on ``image`` (as stored) and return a
    copy whose pose is the refined one, with the covariance from the pixel information
    (scaled by the fitted χ²/dof when that exceeds 1: a real image's dose and blur are not
    known exactly). A result that did not converge is returned unchanged. ``options`` go to
    :func:`refine_intensity` (e.g. ``scales``, ``roi``)."""
    from dataclasses import replace

    pose = result.pose
    if not pose.converged:
        return result
    polarity = "dense_dark" if "dark" in str(getattr(result, "polarity", "")) else "dense_bright"
    imaging = imaging or ImagingModel(image_shape=tuple(np.asarray(image).shape))
    res = refine_intensity(features, image, camera, pose.rotation, pose.translation_mm, imaging, body=body,
                           polarity=polarity, **{"scales": (1.0, 0.0), **options})
    cov = res.covariance
    dof = max(res.roi[2] * res.roi[3] - 6 - 7, 1)
    chi2 = res.cost_end / dof
    if cov is not None and imaging.noisy and chi2 > 1:
        cov = cov * chi2
    new_pose = replace(pose, rotation=res.rotation, translation_mm=res.translation_mm,
                       covariance=cov if cov is not None else pose.covariance)
    diag = dict(result.diagnostics)
    diag["intensity"] = {"refined": bool(res.converged), "cost_start": res.cost_start, "cost_end": res.cost_end,
                         "chi2_per_dof": chi2, "iterations": res.iterations, "gain": res.gain,
                         "roi": list(res.roi), "message": res.message}
    return replace(result, pose=new_pose, diagnostics=diag)
