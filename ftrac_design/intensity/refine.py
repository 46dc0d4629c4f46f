"""Intensity-based refinement of a pose: fit the simulator's image to the radiograph.

From a start (R0, t0) — the feature path's pose — minimise over the pose θ and nuisance
parameters the noise-weighted squared difference between the image's log values ``Y`` and
the model ``g L(θ) + B(β)`` over a region of interest around the fiducial:

- ``L(θ)``: the simulator's noise-free log image of the fiducial (:class:`.model.RoiModel`),
- ``g``: an unknown gain (a display image's contrast scale), ``B(β)``: a smooth background —
  by default a tensor cubic B-spline with knots every 12 px (:mod:`.background`), or a
  polynomial in (u, v); where that background cannot explain the image (χ²/dof > 3 at the
  start: anatomy clutter) a high-pass (image minus its Gaussian blur of ``highpass_px``)
  applied to image and model alike instead; Huber weights against clutter such as bone edges,
- weights ``1/var(Y_i) = N0 e^{−Ŷ_i}`` (Poisson counts in the log domain) from the fitted
  model Ŷ, or uniform for a noise-free imaging model.

The nuisance parameters enter linearly and are eliminated exactly at every pose (variable
projection, Kaufman's Jacobian; the background's W-orthogonal projection factored once per
set of weights); the pose takes Levenberg–Marquardt steps in the solver's
so(3) parametrisation (``R ← exp([δ]ₓ) R``, ``t ← t + δt``). From a far start a
coarse-to-fine schedule smooths image and model alike by Gaussians of a few px first, which
widens the basin (a thin wire is ~2 px wide); from a start within a pixel (the feature
path's) it goes straight to full resolution. A step is kept only if it lowers the objective, and the result
is the start itself when the final objective at full resolution would be worse, so the
refinement never ends worse than its start. The covariance is the inverse of the
information of the pose with the nuisance parameters unknown (Schur complement), at the
model's noise, i.e. the pixel-level Cramér–Rao bound of :mod:`.bound` with nuisance.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any, Literal

import numpy as np
from scipy.ndimage import gaussian_filter
from threadpoolctl import threadpool_limits

from ..features.model import Features
from ..pose.camera import Camera
from ..pose.record import IntensityFit
from ..segment.acceptance import inside_covariance
from ..xray.model import ImagingModel
from ..xray.rays import BehindSourceError
from .background import Nuisance, background_basis
from .bound import _dot
from .model import STEP_PX, RoiModel, perturb, roi_around

#: knot spacing (px) of the default spline background (see :func:`refine_intensity`)
DEFAULT_SPLINE_PX = 12.0
#: how dense matter shows in the image the refinement reads: bright (a log image) or dark (raw counts)
RefinePolarity = Literal["dense_bright", "dense_dark"]
#: the largest move of a pose (χ²₆ of the refined pose under the feature path's pose's own
#: covariance, :func:`~ftrac_design.segment.acceptance.inside_covariance`) with which
#: :func:`refine_track_result` takes the refinement: p = 10⁻⁴, the bound past which the
#: realism benchmark calls a pose confidently wrong. On the 136 ``ftrac_mini`` poses the
#: feature path gave on realism seed 2134 (11 conditions, 106 of them right), the refinement
#: taken every time left 86 right and 43 confidently wrong, 25 of them 22–175° away (display
#: frames, round fields, blades, fluoroscopy, blur: every one beyond this bound); with it, 103
#: right and 17 confidently wrong, the pixel-level covariance too tight for a model the
#: image departs from. On ``ftrac_2005``'s 204 poses of that seed no refinement went beyond it
MOVE_CHI2 = 25.7
#: χ² per degree of freedom of the smooth-background fit above which ``background="auto"``
#: takes the image as cluttered (see :func:`refine_intensity`)
CLUTTER_CHI2 = 3.0
#: side (px) of the tiles whose summed scores make the cluster-robust covariance
#: (:attr:`IntensityResult.robust_covariance`): wider than the residual's correlation where the
#: model departs from the image (blur, edge enhancement, bone edges: a few px), and ~700 of them
#: over a 200 × 220 px ROI, so the estimate's own spread is a few per cent
ROBUST_TILE_PX = 8


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
    n_nuisance: int = 7
    background_model: Literal["polynomial", "spline", "highpass"] = "polynomial"
    #: the cluster-robust ("sandwich") covariance H⁻¹ (Σ_c s_c s_cᵀ) H⁻¹, s_c the objective's
    #: gradient summed over a tile of :data:`ROBUST_TILE_PX`: what the pose's spread is when the
    #: residual is not the model's white noise (None where it could not be formed)
    robust_covariance: np.ndarray | None = None

    @property
    def std(self) -> np.ndarray:
        """Predicted 1σ (rad ×3, mm ×3)."""
        return np.sqrt(np.diag(self.covariance)) if self.covariance is not None else np.full(6, np.nan)

    def to_dict(self) -> dict[str, Any]:
        """SPEC §4 pose object plus an ``intensity`` block of diagnostics."""
        ok = self.covariance is not None and np.all(np.isfinite(self.covariance))
        return {
            "format": "ftrac-pose",
            "version": 1,
            "rotation": self.rotation.tolist(),
            "translation_mm": self.translation_mm.tolist(),
            "converged": bool(self.converged),
            "rms_residual_px": None,
            "covariance": self.covariance.tolist() if ok else None,
            "covariance_order": ["rx", "ry", "rz", "tx", "ty", "tz"],
            "intensity": {
                "cost_start": self.cost_start,
                "cost_end": self.cost_end,
                "iterations": self.iterations,
                "gain": self.gain,
                "roi": list(self.roi),
                "rms_residual_log": self.rms_residual,
                "background": self.background_model,
                "message": self.message,
            },
        }


class _Problem:
    """The objective at one smoothing scale: the weighted residual of ``Y − g L − Nᵀβ`` with
    the gain g and background β eliminated (:class:`.background.Nuisance`)."""

    def __init__(
        self,
        model: RoiModel,
        Y: np.ndarray,
        imaging: ImagingModel,
        scale: float,
        degree: int,
        highpass: float = 0.0,
        robust: float | None = None,
        spline_px: float | None = None,
        loss: str = "huber",
    ):
        self.model, self.scale, self.imaging, self.highpass, self.robust = model, scale, imaging, highpass, robust
        self.loss = loss
        self.Yraw = Y
        self.Y = self.smooth(Y)
        self.y = self.Y.ravel()
        if highpass > 0:
            degree, spline_px = -1, None  # the high-pass removes any smooth background
        self.basis = background_basis(Y.shape, degree, spline_px)
        self.set_pixel_weights(np.ones(Y.size))

    @property
    def n_nuisance(self) -> int:
        """Nuisance parameters: the gain and the background's coefficients."""
        return 1 + self.nuis.k

    def set_pixel_weights(self, w: np.ndarray) -> None:
        self.w = w
        self.nuis = Nuisance(self.basis, w)
        self.yp = self.nuis.project(self.y)

    def smooth(self, a: np.ndarray) -> np.ndarray:
        if a.ndim == 3:
            return np.array([self.smooth(x) for x in a])
        if self.scale > 0:
            a = gaussian_filter(a, self.scale)
        if self.highpass > 0:
            a = a - gaussian_filter(a, self.highpass)
        return a

    def fit(self, L: np.ndarray):
        """Nuisance fit for the (smoothed) model image L: (cost, residual, gain, background
        coefficients, projected model column)."""
        l = L.ravel()
        lp = self.nuis.project(l)
        wl = self.w * lp
        den = float(lp @ wl)
        g = float(wl @ self.yp) / den if den > 0 else 0.0
        r = self.yp - g * lp
        return float(np.sum(self.w * r * r)), r, g, self.nuis.coefficients(self.y - g * l), lp

    def cost(self, R, t):
        return self.fit(self.smooth(self.model.log_image(R, t)))

    def project_jacobian(self, J: np.ndarray, lp: np.ndarray) -> np.ndarray:
        """Kaufman's variable-projection Jacobian: the pose columns (6, n) W-projected off the
        background columns and off the (projected) model column of the gain."""
        Jp = self.nuis.project(J)
        den = float(lp @ (self.w * lp))
        return Jp - np.outer(_dot(Jp * self.w, lp) / den, lp) if den > 0 else Jp

    def set_weights(self, g: float, r: np.ndarray, huber: bool = True) -> None:
        """Poisson weights N0 e^{−p̂} (p̂ the fitted model above its lowest value, in the
        model's line-integral units; with a high-pass, from the smoothed image), times Huber
        weights of the residual ``r`` with ``robust``."""
        if self.imaging.noisy:
            N0 = float(self.imaging.photons_per_px)
            if self.highpass > 0:
                Ys = gaussian_filter(self.Yraw, 2.0).ravel()
                w = N0 * np.exp(-np.clip(Ys - Ys.min(), 0, 20))
            else:
                fitted = self.y - r
                gg = g if g > 1e-6 else 1.0
                w = N0 * np.exp(-np.clip((fitted - fitted.min()) / gg, 0, 20))
            if self.scale > 0:  # smoothing lowers the variance: keep the shape only
                w = w / w.mean()
        else:
            w = np.ones(self.y.size)
        if self.robust and huber:
            z = np.abs(r) * np.sqrt(w)
            sd = 1.4826 * np.median(z) if not self.imaging.noisy or self.scale > 0 else 1.0
            c = self.robust * max(sd, 1e-300)
            if self.loss == "tukey":
                w = w * np.clip(1 - (z / c) ** 2, 0, 1) ** 2
            else:
                w = w * np.minimum(1.0, c / np.maximum(z, 1e-300))
        self.set_pixel_weights(w)


def history_drop(history: list) -> float:
    """Objective decrease of the last accepted step at the same scale (inf if none before)."""
    if len(history) < 2 or history[-2][0] != history[-1][0]:
        return float("inf")
    return history[-2][1] - history[-1][1]


def _log_of(image: np.ndarray, polarity: RefinePolarity) -> np.ndarray:
    img = np.asarray(image, float)
    if polarity == "dense_bright":
        return img
    if polarity == "dense_dark":
        return -np.log(np.maximum(img, 0.5))
    raise ValueError("polarity: 'dense_bright' (log/display image) or 'dense_dark' (raw counts)")


@dataclass(frozen=True)
class RefineOptions:
    """How :func:`refine_intensity` fits.

    ``background`` — the model of what lies under the fiducial:

    - ``"spline"``: a tensor cubic B-spline with knots every ``background_spline_px`` (12) px,
      fitted jointly with the gain (:mod:`.background`); white noise stays white, so the fit
      is maximum likelihood and its bound is :func:`.bound.pixel_information` with
      ``nuisance=True, background_spline_px=12``;
    - ``"polynomial"``: the polynomial of ``background_degree`` (the plain model);
    - ``"highpass"``: image and model minus their Gaussian blur of ``highpass_px`` (8) px —
      colours the noise (up to 29 % efficiency lost on clean images), but over an anatomy-like
      background its errors were the smallest we measured;
    - ``"auto"`` (default): the spline (the polynomial if ``background_spline_px`` is None),
      unless its χ² per degree of freedom at the start exceeds ``clutter_chi2`` (3: clean
      images give 1.0–2.1 from a start a few bound-σ off, anatomy 1.6–14), then the high-pass
      (never with ``highpass_px=0``). The choice is ``IntensityResult.background_model``.

    ``robust`` = c (default 3): Huber weights at full resolution (residuals beyond c σ
    down-weighted; ``robust_loss="tukey"``: Tukey's biweight, zero beyond c σ) against
    clutter such as bone edges, recomputed from the residual at the pose each round reached
    (``reweight_rounds`` rounds of iteratively reweighted least squares, the Poisson weights
    with them). ``background="polynomial", robust=None`` is the plain gain + quadratic model.
    Figures: ``benchmarks/intensity_accuracy.py``, ``docs/how/intensity.md``.

    Each scale (and round) stops when a step is smaller than ``step_sigma`` of the estimate's
    own σ in the Mahalanobis norm ``√(δᵀ H δ / s²)`` (H the Gauss–Newton information, s² the
    fitted χ² per degree of freedom; at full resolution with Poisson weights, s ≈ 1 and this
    is the step in units of the pixel-level bound), or moves the features by less than
    ``tolerance`` px, or (``ftol`` > 0) lowers the objective by less than ``ftol`` of itself.
    Why 0.3 σ and not tighter: steps on forward differences do not converge much below it —
    their Jacobian changes with the pose by the sub-samples' silhouette crossings, so
    the iterates wander by ~0.2 σ — and the polishing step below lands within 0.01–0.05 σ RMS
    of where a 0.01 σ rule ends, at 15 % less CPU (120 paired images).
    A coarse scale stops at 0.3 σ or ``step_sigma`` if larger (it only brings the pose into the
    fine scale's basin). The rule is tested on the Gauss–Newton step proposed at each new
    linearisation, before a trial render: a converged scale costs no trial (nor a cascade of
    rejected ones), and its last linearisation serves the next scale and the polishing step.

    ``scales``: the smoothing scales (px, ending at 0) in order, or ``"auto"`` (default):
    ``coarse_scales`` (2 px) then full resolution where the first Gauss–Newton step at full
    resolution moves the features by more than ``coarse_px`` (1) px, else full resolution
    only. From the feature path's starts (10–50 bound-σ, well under a pixel) a 1 px scale
    first cost 2–3 iterations and changed nothing on clean images; over anatomy it ended
    further off (RMS error / bound 3.0–6.0 vs 2.6–4.9 on the same 30 ftrac_2005 images;
    ``benchmarks/intensity_feature_start.py``).
    ``polish`` (default): one last Gauss–Newton step on a central-difference Jacobian — the
    LM steps on forward differences stop where ``J_fwdᵀ W r = 0``, which is not the
    objective's minimum (0.1–0.23 σ RMS from it; ``benchmarks/intensity_depth_check.py
    stopping``); its central differences add six backward renders to the last forward ones
    (taken at the same pose). The covariance uses that last Jacobian, or a fresh
    central-difference one with ``central_covariance``. ``central_steps=True`` takes every LM step on central
    differences (twice the renders).
    """

    #: "dense_bright" (a log image) or "dense_dark" (raw counts)
    polarity: RefinePolarity = "dense_bright"
    #: smoothing scales (px, ending at 0) in order, or "auto"
    scales: tuple[float, ...] | str = "auto"
    #: degree of the polynomial background
    background_degree: int = 2
    #: Levenberg–Marquardt iterations per scale and round
    max_iterations: int = 12
    #: stop when a step moves the features by less than this, px
    tolerance: float = 1e-4
    #: stop when a step lowers the objective by less than this share of it (0: off)
    ftol: float = 0.0
    #: covariance from a fresh central-difference Jacobian
    central_covariance: bool = False
    #: high-pass scale, px (0: never)
    highpass_px: float = 8.0
    #: Huber / Tukey threshold c, σ (None: plain least squares)
    robust: float | None = 3.0
    #: every LM step on central differences
    central_steps: bool = False
    #: "auto", "spline", "polynomial" or "highpass"
    background: Literal["auto", "spline", "polynomial", "highpass"] = "auto"
    #: knot spacing of the spline background, px (None: the polynomial)
    background_spline_px: float | None = DEFAULT_SPLINE_PX
    #: χ²/dof at the start above which "auto" takes the image as cluttered
    clutter_chi2: float = CLUTTER_CHI2
    #: stop when the Gauss–Newton step is below this many of the estimate's own σ
    step_sigma: float = 0.3
    #: rounds of reweighting at full resolution
    reweight_rounds: int = 2
    #: "huber" or "tukey"
    robust_loss: str = "huber"
    #: one final Gauss–Newton step on central differences
    polish: bool = True
    #: the coarse scales of scales="auto", px
    coarse_scales: tuple[float, ...] = (2.0,)
    #: scales="auto" smooths first where the first full-resolution step exceeds this, px
    coarse_px: float = 1.0


def refine_intensity(
    features: Features,
    image: np.ndarray,
    camera: Camera,
    R0: np.ndarray,
    t0: np.ndarray = None,
    imaging: ImagingModel = ImagingModel(),
    roi: tuple[int, int, int, int] | None = None,
    options: RefineOptions | None = None,
    within: Callable[[np.ndarray, np.ndarray], bool] | None = None,
    **overrides: Any,
) -> IntensityResult:
    """Refine the pose (R0, t0) of ``features`` on ``image`` (H, W) — see the module.

    Parameters
    ----------
    features : Features
        The fiducial, its body (``features.body``, where known) included in the model.
    image : numpy.ndarray
        (H, W): a log image (``polarity="dense_bright"``, −ln(I/I0) up to gain and offset) or raw
        counts (``"dense_dark"``).
    camera : Camera
        The image's camera.
    R0, t0 : numpy.ndarray
        The start pose (F → X; mm).
    imaging : ImagingModel
        Blur, energy and dose (weights; ``photons_per_px=None``: uniform weights and a covariance
        scaled by the fitted residual).
    roi : (row0, col0, rows, cols) or None
        The region fitted (default: the fiducial at the start plus 12 px).
    options : RefineOptions or None
        How it fits (:class:`RefineOptions`, which explains each option; default its defaults).
    within : callable or None
        ``within(R, t)`` (F → X, mm): whether a pose lies where the caller could use the answer.
        The fit stops, not converged, at the first step that takes it outside; None: anywhere.
    **overrides
        Fields of ``options`` set by keyword (``scales=(0.0,)``, ``background="spline"``, …); an
        unknown keyword raises TypeError.

    Returns
    -------
    IntensityResult
        The refined pose, its covariance and how the fit went.
    """
    if hasattr(R0, "pose") and isinstance(features, np.ndarray):
        # the call form of cli/track.py, refine_fn(image, features, camera, track_result):
        # forwarded until it calls refine_track_result itself
        return refine_track_result(features, image, camera, R0)
    o = replace(options or RefineOptions(), **overrides)
    # one BLAS thread: the products here are small (k ≲ 500 background columns, 6 pose
    # columns), where a threaded BLAS spends more time spinning its threads than multiplying
    # (a banded Cholesky of 391 columns: 217 ms with threads on the loaded 2-core machine)
    with threadpool_limits(1, "blas"):
        return _refine(features, image, camera, R0, t0, imaging, roi, o, within)


def _refine(features, image, camera, R0, t0, imaging, roi, o: RefineOptions, within=None):
    R0, t0 = np.asarray(R0, float), np.asarray(t0, float)
    Yfull = _log_of(image, o.polarity)
    if roi is None:
        roi = roi_around(features, R0, t0, camera, Yfull.shape)
    v0, u0, h, w = roi
    Y = Yfull[v0 : v0 + h, u0 : u0 + w]
    fit = _Refinement(RoiModel(features, camera, imaging, roi), Y, imaging, o, R0, t0)
    fit.within = within
    for scale in fit.scales():
        fit.at_scale(scale)
        if fit.left:
            break
    if o.polish and fit.prob is not None and fit.prob.scale == 0 and not o.central_steps and not fit.left:
        fit.polish()
    return fit.result(R0, t0, roi)


def _background_mode(o: RefineOptions, model: RoiModel, Y: np.ndarray, imaging: ImagingModel, R0, t0) -> str:
    """The background model the options ask for; "auto" takes the spline (or the polynomial)
    unless the start's χ² per degree of freedom says the image is cluttered (then the high-pass)."""
    if o.background not in ("auto", "spline", "polynomial", "highpass"):
        raise ValueError("background: 'auto', 'spline', 'polynomial' or 'highpass'")
    if o.background == "highpass" and not o.highpass_px > 0:
        raise ValueError("background='highpass' needs highpass_px > 0")
    mode = o.background
    if mode in ("auto", "spline") and not o.background_spline_px:
        mode = "polynomial" if mode == "spline" else "auto"
    if mode == "auto":
        mode = "spline" if o.background_spline_px else "polynomial"
        if o.highpass_px > 0:
            probe = _Problem(
                model,
                Y,
                imaging,
                0.0,
                o.background_degree,
                0.0,
                None,
                o.background_spline_px if mode == "spline" else None,
            )
            _, r, g, _, _ = probe.cost(R0, t0)
            probe.set_weights(g, r)
            c, r, _, _, _ = probe.cost(R0, t0)
            if imaging.noisy and c / max(r.size - 6 - probe.n_nuisance, 1) > o.clutter_chi2:
                mode = "highpass"
    return mode


class _Refinement:
    """One refinement's state as it runs: the pose, the current scale's objective and its fit at
    the pose (cost, residual, gain, background, projected model column), the last linearisation,
    the history and the message."""

    def __init__(self, model: RoiModel, Y: np.ndarray, imaging: ImagingModel, o: RefineOptions, R0, t0):
        self.model, self.Y, self.imaging, self.o = model, Y, imaging, o
        self.steps = model.steps(t0) / STEP_PX  # parameter change that moves features ~1 px
        self.mode = _background_mode(o, model, Y, imaging, R0, t0)
        self.R, self.t = R0.copy(), t0.copy()
        self.history: list = []
        self.iterations, self.message, self.J, self.prob, self.Jraw = 0, "", None, None, None
        self.last: dict = {}  # the last forward differences: pose, value, J
        # where the caller can use the answer (:func:`refine_intensity`'s ``within``), and
        # whether a step left it
        self.within: Callable[[np.ndarray, np.ndarray], bool] | None = None
        self.left = False

    def problem(self, scale: float, huber: bool) -> _Problem:
        o = self.o
        return _Problem(
            self.model,
            self.Y,
            self.imaging,
            scale,
            o.background_degree,
            o.highpass_px if self.mode == "highpass" else 0.0,
            o.robust if huber else None,
            o.background_spline_px if self.mode == "spline" else None,
            o.robust_loss,
        )

    def forward(self, R, t):
        """Forward differences of the (unsmoothed) log image at (R, t); the last pose's are
        kept (a scale's last, converged linearisation is the next scale's first, and the
        polishing step's central differences reuse them)."""
        key = (R.tobytes(), t.tobytes())
        if self.last.get("key") != key:
            L0 = self.model.log_image(R, t)
            J = self.model._differences(R, t, "log", central=self.o.central_steps, value=L0)[1]
            self.last.update(key=key, value=L0, J=J)
        return self.last["J"]

    def scales(self) -> tuple[float, ...]:
        o = self.o
        scales = o.scales
        if not isinstance(scales, str):
            return scales
        if scales != "auto":
            raise ValueError("scales: 'auto' or a tuple of smoothing scales (px) ending at 0")
        # the coarse scales only where the start is far: where the first Gauss–Newton step
        # at full resolution (no Huber) moves the features by more than coarse_px. Its
        # linearisation is the first iteration's, whichever scale comes first: no extra render.
        # From the feature path (~10–50 bound-σ, well under a pixel) the 1 px scale cost
        # 2–3 iterations and, over anatomy, moved the pose into worse minima (RMS error /
        # bound 3.0–6.0 with it, 2.6–4.9 without, same 30 images).
        if o.coarse_scales and self._far():
            return tuple(o.coarse_scales) + (0.0,)
        return (0.0,)

    def _far(self) -> bool:
        R, t = self.R, self.t
        p0 = self.problem(0.0, False)
        _, r0, g0, _, lp0 = p0.cost(R, t)
        p0.set_weights(g0, r0)
        _, r0, g0, _, lp0 = p0.cost(R, t)
        J0 = p0.project_jacobian(p0.smooth(self.forward(R, t)).reshape(6, -1) * g0, lp0)
        try:
            d0 = np.linalg.solve(_dot(J0 * p0.w, J0), _dot(J0 * p0.w, r0))
            return not np.max(np.abs(d0) / self.steps) <= self.o.coarse_px
        except np.linalg.LinAlgError:
            return True

    def at_scale(self, scale: float) -> None:
        """The rounds at one smoothing scale: weights from the residual at the pose reached, then
        Levenberg–Marquardt, until the weights move nothing."""
        o = self.o
        # robust weights only at full resolution: at a coarse scale far from the pose the
        # largest residuals are the fiducial's own misaligned wires
        huber = bool(o.robust) and scale == 0
        self.prob, self.Jraw = self.problem(scale, huber), None
        prob = self.prob
        for _round in range(max(int(o.reweight_rounds), 1) if huber or self.imaging.noisy else 1):
            _, r, g, _, _ = prob.cost(self.R, self.t)
            prob.set_weights(g, r)
            self.cst, self.r, self.g, self.b, self.lp = prob.cost(self.R, self.t)
            dof = max(self.r.size - 6 - prob.n_nuisance, 1)
            if _round > 0 and self.Jraw is not None and self._settled(dof):
                break
            moved = self._levenberg_marquardt(scale, dof)
            if self.left:
                return
            if not moved and _round > 0:
                break  # reweighting moved nothing: converged

    def _settled(self, dof: int) -> bool:
        """With new weights: is a step still due? (the last linearisation, re-projected: no render)"""
        prob = self.prob
        Jt = prob.project_jacobian(self.Jraw, self.lp)
        Ht = _dot(Jt * prob.w, Jt)
        try:
            dt = np.linalg.solve(Ht, _dot(Jt * prob.w, self.r))
        except np.linalg.LinAlgError:
            dt = np.full(6, np.inf)
        if math.sqrt(max(float(dt @ Ht @ dt), 0.0) / max(self.cst / dof, 1e-300)) < self.o.step_sigma:
            self.J = Jt
            return True
        return False

    def _levenberg_marquardt(self, scale: float, dof: int) -> int:
        """One round's iterations (the objective's weights change between rounds); the steps taken."""
        o, prob = self.o, self.prob
        lam, moved, this_round = 1e-3, 0, []
        # a coarse scale only brings the pose into the fine scale's basin
        rule = o.step_sigma if scale == 0 else max(o.step_sigma, 0.3)
        for _ in range(o.max_iterations):
            self.iterations += 1
            self.Jraw = prob.smooth(self.forward(self.R, self.t)).reshape(6, -1) * self.g
            J = self.J = prob.project_jacobian(self.Jraw, self.lp)
            H = _dot(J * prob.w, J)
            grad = _dot(J * prob.w, self.r)
            D = np.diag(H).copy()
            s2 = max(self.cst / dof, 1e-300)
            # converged when the Gauss–Newton step from here is below the rule: stop before
            # rendering a trial (a rejected cascade costs up to 8 renders), and the polishing
            # step below reuses this linearisation
            try:
                dgn = np.linalg.solve(H, grad)
                if math.sqrt(max(float(dgn @ H @ dgn), 0.0) / s2) < rule:
                    break
            except np.linalg.LinAlgError:
                pass
            accepted, lam, dx = self._damped_step(H, D, grad, lam)
            moved += accepted
            self.history.append((scale, self.cst, lam))
            this_round.append((scale, self.cst, lam))
            if not accepted:
                self.message = f"no decrease at scale {scale:g} px"
                break
            if self.within is not None and not self.within(self.R, self.t):
                # the answer could not be used from here on, and the renders that follow a fit
                # walking away cost up to a minute a frame (2 px of blur, tuning seed 2135)
                self.left, self.message = True, f"a step at scale {scale:g} px left the region the answer may lie in"
                break
            if np.max(np.abs(dx) / self.steps) < o.tolerance or history_drop(this_round) < o.ftol * self.cst:
                break
        return moved

    def _damped_step(self, H, D, grad, lam: float):
        """A step that lowers the objective, the damping raised until one does (8 tries); taken
        when found. A trial pose with the fiducial at or behind the source counts as one that
        does not lower it. Returns (taken, the damping, the step)."""
        dx = None
        for _ in range(8):
            try:
                dx = np.linalg.solve(H + lam * np.diag(D), grad)
            except np.linalg.LinAlgError:
                lam *= 10
                continue
            Rn, tn = perturb(self.R, self.t, dx)
            try:
                cn, rn, gn, bn, lpn = self.prob.cost(Rn, tn)
            except BehindSourceError:
                # a step that carries the fiducial onto the source lowers nothing: a shorter one
                # may (where the pixels hardly tell depth, an undamped step can be metres long)
                lam *= 4
                continue
            if cn < self.cst:
                self.R, self.t, self.cst, self.r, self.g, self.b, self.lp = Rn, tn, cn, rn, gn, bn, lpn
                return True, max(lam / 3, 1e-7), dx
            lam *= 4
        return False, lam, dx

    def polish(self) -> None:
        """LM on forward differences stops where J_fwdᵀ W r = 0, not at the objective's minimum
        (0.1–0.23 σ RMS from it on ftrac_2005: intensity_depth_check.py stopping): one
        Gauss–Newton step on central differences, kept if it lowers the objective."""
        model, prob, R, t = self.model, self.prob, self.R, self.t
        self.iterations += 1
        L0 = model.log_image(R, t)
        if self.last.get("key") == (R.tobytes(), t.tobytes()):
            Jc = model.central_from_forward(R, t, L0, self.last["J"])  # six renders, not twelve
        else:
            Jc = model._differences(R, t, "log", central=True, value=L0)[1]
        J = self.J = prob.project_jacobian(prob.smooth(Jc).reshape(6, -1) * self.g, self.lp)
        H = _dot(J * prob.w, J)
        try:
            dx = np.linalg.solve(H, _dot(J * prob.w, self.r))
            Rn, tn = perturb(R, t, dx)
            cn, rn, gn, bn, lpn = prob.cost(Rn, tn)
            if cn < self.cst:
                self.R, self.t, self.cst, self.r, self.g, self.b, self.lp = Rn, tn, cn, rn, gn, bn, lpn
            self.history.append((0.0, self.cst, 0.0))
        except (np.linalg.LinAlgError, BehindSourceError):
            pass

    def result(self, R0, t0, roi) -> IntensityResult:
        """The image objective at full resolution, the weights of the last round (or, without a
        full-resolution stage, from the start), start and end on the same weights; the start
        kept where the end is no lower."""
        prob = self.prob
        full = prob if prob is not None and prob.scale == 0 else self.problem(0.0, bool(self.o.robust))
        if full is not prob:
            _, r, g, _, _ = full.cost(R0, t0)
            full.set_weights(g, r)
        cost_start = full.cost(R0, t0)[0]
        R, t, converged, message = self.R, self.t, not self.left, self.message
        c_end, r, g, b, lp = full.cost(R, t)
        if c_end > cost_start:
            R, t, converged, message = R0.copy(), t0.copy(), False, "refinement did not lower the objective; start kept"
            c_end, r, g, b, lp = full.cost(R, t)
        cov, robust = self._covariance(full, R, t, g, lp, r, c_end, converged)
        rms = float(math.sqrt(np.mean(r * r)))
        return IntensityResult(
            R,
            t,
            cov,
            converged,
            cost_start,
            c_end,
            self.iterations,
            float(g),
            b,
            roi,
            rms,
            message,
            self.history,
            full.n_nuisance,
            self.mode,
            robust,
        )

    def _covariance(self, full: _Problem, R, t, g, lp, r, c_end: float, converged: bool):
        """Information of the pose with gain and background unknown (the weights the objective
        used, so that cost_end stays comparable), inverted; and the cluster-robust covariance
        (:func:`robust_covariance`). Each None where singular."""
        if self.o.central_covariance or self.J is None or full is not self.prob or not converged:
            L0, Jc = self.model.jacobian(R, t)
            Jc = full.project_jacobian(full.smooth(Jc).reshape(6, -1) * g, lp)
        else:
            Jc = self.J  # already projected at (R, t)'s last linearisation
        F = _dot(Jc * full.w, Jc)
        try:
            cov = np.linalg.inv((F + F.T) / 2)
            if not self.imaging.noisy:
                cov *= c_end / max(r.size - 6 - full.n_nuisance, 1)
        except np.linalg.LinAlgError:
            cov = None
        return cov, robust_covariance(Jc, full.w, r, full.Y.shape)


def robust_covariance(
    J: np.ndarray, w: np.ndarray, r: np.ndarray, shape: tuple[int, int], tile_px: int = ROBUST_TILE_PX
) -> np.ndarray | None:
    """The cluster-robust ("sandwich") covariance of a weighted least-squares fit: H⁻¹ M H⁻¹
    with H = J W Jᵀ and M = Σ_c s_c s_cᵀ, s_c the scores J_i w_i r_i summed over the pixels i of
    tile c (``tile_px`` square, from the ROI's corner).

    Where the residual is the model's white noise, M estimates the noise-scaled H and this is
    the model's covariance (scaled by the fitted χ² per degree of freedom); where it is not —
    a blur, a display chain's edge enhancement or a bone edge the model lacks leave residuals
    correlated over a few pixels — the tiles' summed scores spread by what the errors really
    are, and the covariance with them (the Huber–White estimator with clusters: Liang and
    Zeger, Biometrika 1986). A bias the model shares with every pixel (a wrong blur) it cannot
    see.

    Parameters
    ----------
    J : (6, n) the pose columns of the Jacobian (projected off the nuisance), rad and mm.
    w : (n,) the pixel weights of the objective.
    r : (n,) the residual at the pose.
    shape : (rows, cols) of the ROI, rows × cols = n.
    tile_px : side of the tiles, px.

    Returns
    -------
    (6, 6) ndarray, order rx ry rz tx ty tz (rad, mm), or None where H is singular.
    """
    h, wd = shape
    rows, cols = np.divmod(np.arange(h * wd), wd)
    tile = (rows // tile_px) * (-(-wd // tile_px)) + cols // tile_px
    scores = J * (w * r)[None, :]
    S = np.stack([np.bincount(tile, weights=s, minlength=int(tile.max()) + 1) for s in scores])
    H = _dot(J * w, J)
    try:
        Hi = np.linalg.inv((H + H.T) / 2)
    except np.linalg.LinAlgError:
        return None
    C = Hi @ (S @ S.T) @ Hi
    return (C + C.T) / 2 if np.all(np.isfinite(C)) else None


def refine_track_result(
    image: np.ndarray,
    features: Features,
    camera: Camera,
    result,
    imaging: ImagingModel | None = None,
    **options,
):
    """``ftrac-design track --refine intensity``: refine a converged
    :class:`ftrac_design.segment.TrackResult` on ``image`` (as stored) and return a
    copy whose pose is the refined one (``scales="auto"`` with a 1 px coarse scale), with the
    cluster-robust covariance (:func:`robust_covariance`: a real image's dose, blur and display
    chain are not the model's; where it cannot be formed, the pixel information's, scaled by
    the fitted χ²/dof when that exceeds 1). A result that did not converge is
    returned unchanged. ``options`` go to :func:`refine_intensity` (e.g. ``scales``, ``roi``).

    The refined pose is taken only where the fit converged and stayed inside the feature
    path's pose's own covariance (:data:`MOVE_CHI2`), every step of the way: a fit is stopped
    at the first step that leaves it. Otherwise the feature path's pose is given out as it
    was, the diagnostic saying why (``taken`` false). The model is the log
    image's: a display frame's window and gamma, clipping and dense anatomy break it, and
    on display frames the fit can walk far from a right pose (see :data:`MOVE_CHI2`)."""
    pose = result.pose
    if not pose.converged:
        return result
    polarity = "dense_dark" if "dark" in str(getattr(result, "polarity", "")) else "dense_bright"
    imaging = imaging or ImagingModel(image_shape=tuple(np.asarray(image).shape))
    res = refine_intensity(
        features,
        image,
        camera,
        pose.rotation,
        pose.translation_mm,
        imaging,
        polarity=polarity,
        **{"coarse_scales": (1.0,), "within": lambda R, t: _taken_from(pose, R, t), **options},
    )
    cov = res.covariance
    dof = max(res.roi[2] * res.roi[3] - 6 - res.n_nuisance, 1)
    chi2 = res.cost_end / dof
    if res.robust_covariance is not None:
        # a realism frame's residual is not the model's white noise: the model's covariance,
        # even scaled by χ²/dof, left the truth beyond χ²₆ 25.7 in 7 of 17 right refinements
        # of log and display frames (tuning seed 2137), the cluster-robust one in 2
        cov = res.robust_covariance
    elif cov is not None and imaging.noisy and chi2 > 1:
        cov = cov * chi2
    new_pose = replace(
        pose,
        rotation=res.rotation,
        translation_mm=res.translation_mm,
        covariance=cov if cov is not None else pose.covariance,
    )
    move = inside_covariance(pose, new_pose)
    taken = bool(res.converged) and move <= MOVE_CHI2
    message = res.message
    if not taken:
        why = "it did not converge" if not res.converged else f"it moved the pose χ²₆ = {move:.3g} > {MOVE_CHI2:g}"
        kept = f"the feature path's pose kept: {why} (beyond that pose's own covariance)"
        if not res.converged and move > MOVE_CHI2:
            kept = f"the feature path's pose kept: the fit left that pose's own covariance (χ²₆ > {MOVE_CHI2:g})"
        message = "; ".join(filter(None, (message, kept)))
    fit = IntensityFit(
        bool(res.converged), res.cost_start, res.cost_end, chi2, res.iterations, res.gain, list(res.roi), message, taken
    )
    return replace(result, pose=new_pose if taken else pose, diagnostics=replace(result.diagnostics, intensity=fit))


def _taken_from(pose, R: np.ndarray, t: np.ndarray) -> bool:
    """Whether :func:`refine_track_result` could take (R, t) in place of the feature path's
    ``pose``: inside that pose's own covariance (:data:`MOVE_CHI2`)."""
    return inside_covariance(pose, replace(pose, rotation=R, translation_mm=t)) <= MOVE_CHI2
