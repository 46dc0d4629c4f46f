"""Image → observation → pose, with no initial guess: :func:`track_image`.

Steps (each in its own module): density image and background (:mod:`.image`), bead
candidates fitted with the blurred-sphere model (:mod:`.beads`), Steger ridge points at
the wire's scale (:mod:`.ridges`), bead-labelling hypotheses and contours gathered by each
hypothesis's predicted image (:mod:`.identify`), then the pose solver.

Safety: the solver's noise model is not the fixed default but the segmentation's own
measured accuracy — each bead's centre uncertainty from its model fit and each curve's
residual scatter about its own fit, pooled per feature type, with floors measured on
rendered images (``TrackOptions.floor_*``). Every feature's whitened residual is then
tested on its own (χ², p < ``feature_p_value``); a feature that fails is dropped and the
pose re-solved (at most ``max_dropped`` times). Two labellings that explain the image
equally well, or a pose that fails the solver's checks, give ``converged = False`` with
the reason — never a confident wrong pose.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import cv2
import numpy as np
from scipy.special import chdtrc

from ..features.model import Features
from ..pose import Camera, NoiseModel, Observation, Pose, SolverOptions, refine_pose, solve_pose
from ..pose.observation import CurveObservation
from ..pose import so3
from ..pose.fitting import fit_conic, fit_line
from ..pose.problem import compile_problem, evaluate
from . import identify
from .beads import Beads, blob_candidates, fit_beads
from .image import detect_polarity, noise_sigma, to_density, top_hat
from .ridges import RidgePoints, ridge_points


@dataclass(frozen=True)
class TrackOptions:
    """Settings of the image path; lengths in pixels unless named ``_mm``."""

    #: "auto", "dense-dark" (raw detector counts) or "dense-bright" (log/display image)
    polarity: str = "auto"
    #: source-to-fiducial over source-to-detector distance assumed to size the filters
    #: (SPEC §1 workspace: the fiducial at 2/3 of f, magnification 1.5)
    magnification: float = 1.5
    #: starting value of the Gaussian blur σ (fitted on the beads)
    blur_px: float = 0.8
    ridge_min_snr: float = 5.0
    bead_min_snr: float = 8.0
    #: first bead-matching tolerance (× the bead radius), then the refined one (px)
    hypothesis_tol_radii: float = 1.0
    match_tol_px: float = 2.0
    #: contour points within this of a predicted curve belong to it (px); a second curve
    #: within ``separation_px`` makes a point ambiguous
    contour_tol_px: float = 2.0
    final_contour_tol_px: float = 1.0
    separation_px: float = 3.0
    #: contour points are thinned to one per ``thin_factor`` × the ridge scale of arc (the
    #: correlation length of Steger points' noise, ≈ 2√π σ for Gaussian-smoothed white noise)
    thin_factor: float = 3.5
    #: floors of the measured segmentation σ per axis (mm at the detector), from rendered
    #: images at the default imaging model (benchmarks/track_accuracy.py)
    floor_point_mm: float = 0.02
    #: systematic error per feature (px per axis / along the normal), see :func:`_noise_model`
    sys_point_px: float = 0.07
    sys_curve_px: float = 0.04
    floor_line_mm: float = 0.01
    floor_ellipse_mm: float = 0.01
    #: a feature whose own residual is this improbable under the noise model is dropped
    feature_p_value: float = 1e-6
    max_dropped: int = 2
    #: a second labelling whose misfit (χ² + charges, see :func:`_score`) is within this of
    #: the best's, and that is far enough away, makes the answer ambiguous (one unexplained
    #: feature's charge: ftrac_mini's near-mirror labellings came within 24)
    ambiguity_chi2: float = 25.0
    #: a predicted wire whose median density along its prediction is below this fraction of
    #: the best-supported wire's is absent: the labelling is not confirmed
    wire_support: float = 0.3
    #: χ² charged for each predicted, unobstructed feature a labelling does not explain
    unexplained_chi2: float = 25.0
    #: look for the fiducial on a half-size image first and work in its region only
    roi: bool = True
    #: χ² charged per pixel of ridge the pose leaves unexplained and of predicted wire the
    #: image does not show (:func:`identify.image_agreement`)
    agreement_chi2_per_px: float = 1.0
    #: two refinement stages (wide, then tight and thinned) instead of three
    fast: bool = True
    #: a converged pose may leave at most this many balls in view, well clear of the others
    #: (> 4 radii + 2 px), without their blob or rejected
    max_unexplained_beads: int = 1
    #: a confident labelling uses at least this many balls
    min_beads: int = 5
    #: redundant constraints (2 per bead and line, 5 per ellipse, minus 6) a confident
    #: labelling needs
    min_redundancy: int = 6
    #: the solver's maximum noise scale κ for an image pose (the model is measured here)
    max_noise_scale: float = 3.0
    #: variance components qₖ of the pose covariance per feature type, relative to the
    #: residuals' variance factor (see :func:`_calibrated_covariance`); chosen against the
    #: truth on rendered images (600 ftrac_2005, 180 ftrac_mini, 200 nine_bead; clean and
    #: over anatomy): the error over its σ has an RMS of 0.55–1.2 on every axis
    variance_point: float = 2.0
    variance_line: float = 2.0
    variance_ellipse: float = 1.0


@dataclass
class TrackResult:
    """What :func:`track_image` found: the pose (SPEC §4, converged or not, with the
    reason), the observation it segmented (SPEC §3), per-feature quality, the raw
    detections (for the overlay) and diagnostics."""

    pose: Pose
    observation: Observation | None
    quality: dict[str, Any]
    beads: Beads | None
    ridges: RidgePoints | None
    polarity: str
    noise: NoiseModel | None
    diagnostics: dict[str, Any] = field(default_factory=dict)

    def pose_dict(self) -> dict[str, Any]:
        """SPEC §4 object plus diagnostics (readers ignore unknown keys)."""
        d = self.pose.to_dict()
        d["segmentation"] = {
            "polarity": self.polarity,
            "noise_model_mm": None if self.noise is None else
            {"point": self.noise.point_mm, "line": self.noise.line_mm, "ellipse": self.noise.ellipse_mm},
            **self.diagnostics,
        }
        return d

    def observation_dict(self) -> dict[str, Any] | None:
        """SPEC §3 object plus ``quality`` (per feature; readers ignore unknown keys)."""
        if self.observation is None:
            return None
        d = self.observation.to_dict()
        d["quality"] = self.quality
        return d


def _failed(reason: str, **diag) -> Pose:
    nan = np.full(3, np.nan)
    return Pose(np.full((3, 3), np.nan), nan, False, float("nan"), None, {}, 0, reason)


def scales(features: Features, camera: Camera, opts: TrackOptions) -> dict[str, float]:
    """Expected sizes in pixels at the assumed magnification: bead radius, wire width."""
    pix = float(np.mean(camera.pixel_size_mm))
    m = opts.magnification
    bead = max((p.diameter for p in features.points), default=0.0) / 2 * m / pix
    wires = [ln.wire_diameter for ln in features.lines] + [e.wire_diameter for e in features.ellipses]
    wire = (max(wires) if wires else 0.0) * m / pix
    return {"bead_radius_px": bead, "wire_px": wire, "pixel_mm": pix, "ridge_sigma_px": max(1.0, 0.5 * wire + 0.5)}


def detect(g: np.ndarray, features: Features, camera: Camera, opts: TrackOptions):
    """Background-free image, noise σ, fitted bead candidates and ridge points."""
    sc = scales(features, camera, opts)
    rb, wpx = sc["bead_radius_px"], sc["wire_px"]
    disc = int(math.ceil(max(rb, wpx) + 3 * opts.blur_px + 2))
    T = top_hat(g, disc)
    noise = max(noise_sigma(T), 1e-9)
    beads = None
    if features.points:
        P = len(features.points)
        cand, resp = blob_candidates(T, rb, noise, 3 * P + 6, opts.bead_min_snr)
        if len(cand):
            # the beads are the strongest blobs; anything far weaker is a wire crossing or clutter
            ref = np.sort(resp)[::-1][: P]
            keep = resp >= 0.25 * float(np.median(ref))
            cand, resp = cand[keep], resp[keep]
        b = fit_beads(T, cand, rb, opts.blur_px, noise, resp)
        # a fit that ran off (amplitude far from the others', radius or blur at a bound) is
        # redone with priors 25× stronger (σ_prior / 5)
        if len(b) > 2:
            med = float(np.median(b.amplitude))
            bad = ~((b.amplitude > 0.2 * med) & (b.amplitude < 5 * med) & np.isfinite(b.sigma_px))
            if bad.any():
                b2 = fit_beads(T, cand[bad], rb, opts.blur_px, noise, resp[bad], prior_scale=25.0)
                for k in b.__dataclass_fields__:
                    getattr(b, k)[bad] = getattr(b2, k)
        H, W = g.shape
        edge = rb + 2 * opts.blur_px + 1
        ok = (np.isfinite(b.uv).all(1) & (b.radius > 0.5 * rb) & (b.radius < 2.0 * rb) & (b.blur < 3.0)
              & (b.amplitude > 0)
              & (b.uv[:, 0] > edge) & (b.uv[:, 1] > edge) & (b.uv[:, 0] < W - 1 - edge)
              & (b.uv[:, 1] < H - 1 - edge) & np.isfinite(b.sigma_px))
        beads = b.take(ok)
    ridges = None
    if features.lines or features.ellipses:
        ridges = ridge_points(T, sc["ridge_sigma_px"], noise, opts.ridge_min_snr)
    return T, noise, beads, ridges, sc


def _observation(camera: Camera, beads_uv: dict[str, np.ndarray], contours: identify.Contours) -> Observation:
    return Observation(camera, dict(beads_uv),
                       {k: CurveObservation(points=v) for k, v in contours.lines.items()},
                       {k: CurveObservation(points=v) for k, v in contours.ellipses.items()}, origin="<image>")


def _match_beads(features: Features, camera: Camera, R, t, beads: Beads, tol: float, sep: float):
    """Model bead id → blob index at pose (R, t): the nearest blob within ``tol``, one blob
    per bead; beads projected within ``sep`` of another bead are left out (merged blobs)."""
    out: dict[str, int] = {}
    if not features.points or beads is None or len(beads) == 0:
        return out, {}
    uv, _ = identify._project(camera, R, t, features.point_centers())
    dropped = {}
    dd = np.linalg.norm(uv[:, None] - uv[None], axis=-1) + np.eye(len(uv)) * 1e9
    for k, p in enumerate(features.points):
        if dd[k].min() < sep:
            dropped[p.id] = f"projects within {dd[k].min():.1f} px of another bead"
            continue
        d = np.linalg.norm(beads.uv - uv[k], axis=1)
        j = int(np.argmin(d))
        if d[j] <= tol:
            out[p.id] = j
    # one blob per bead
    used: dict[int, str] = {}
    for fid, j in list(out.items()):
        if j in used:
            dropped[fid] = "shares its blob with another bead"
            dropped[used[j]] = "shares its blob with another bead"
            out.pop(fid, None)
            out.pop(used[j], None)
        else:
            used[j] = fid
    return out, dropped


def _resolvable_beads(features: Features, camera: Camera, pose: Pose, sc: dict, opts: TrackOptions) -> int:
    """How many balls a perfect segmentation could use at ``pose``: those projected inside
    the image (clear of its edge as :func:`detect` requires) and not within the merging
    distance of another ball (:func:`_match_beads` leaves those out). A bound set by the
    view alone, whatever the noise or the region searched."""
    if not features.points:
        return 0
    uv, _ = identify._project(camera, pose.rotation, pose.translation_mm, features.point_centers())
    H, W = sc.get("shape", (np.inf, np.inf))
    edge = sc["bead_radius_px"] + 2 * opts.blur_px + 1
    sep = 2 * sc["bead_radius_px"] + 2 * opts.blur_px
    inside = np.isfinite(uv).all(1) & (uv[:, 0] > edge) & (uv[:, 1] > edge) & (uv[:, 0] < W - 1 - edge) \
        & (uv[:, 1] < H - 1 - edge)
    dd = np.linalg.norm(uv[:, None] - uv[None], axis=-1) + np.eye(len(uv)) * 1e9
    return int((inside & (dd.min(1) >= sep)).sum())


def _noise_model(obs: Observation, beads: Beads, match: dict[str, int], pix: float, opts: TrackOptions):
    """Per-feature-type σ (mm at the detector) measured on this image, with floors.

    Beside the random part measured here (each bead fit's own σ; each curve's scatter about
    its own fit) every feature carries a systematic error that does not average away over
    its points — a bead centre pulled by a wire or a bone edge, a wire's contour shifted by
    the background's slope (``TrackOptions.sys_point_px`` / ``sys_curve_px``, measured
    against the truth on rendered images with anatomy). The solver's noise model is one σ
    per point of a type, so a curve's systematic part enters as ``n σ_sys²`` per point (n
    its typical number of points): then a curve's fitted parameters carry σ_sys as they
    should and the per-feature χ² test does not reject correct curves for a 0.05 px shift."""
    sig_p = [float(beads.sigma_px[j]) for j in match.values()] if match else []
    # the median: one poorly fitted ball (σ of a pixel) must not loosen every other bead;
    # it fails its own χ² test instead
    sp = float(np.median(sig_p)) if sig_p else 0.0
    point = max(math.hypot(sp, opts.sys_point_px) * pix, opts.floor_point_mm)
    out = []
    for store, fitter, floor in ((obs.lines, fit_line, opts.floor_line_mm),
                                 (obs.ellipses, fit_conic, opts.floor_ellipse_mm)):
        rss, dof, ns = 0.0, 0, []
        for c in store.values():
            f = _fit(fitter, c.points)
            rss += float(f.rss)
            dof += int(f.dof)
            ns.append(len(c.points))
        s = math.sqrt(rss / dof) if dof > 0 else 0.0
        n = float(np.median(ns)) if ns else 0.0
        out.append(max(math.sqrt(s * s + n * opts.sys_curve_px ** 2) * pix, floor))
    return NoiseModel(point, out[0], out[1])


_FITS: dict = {}


def _fit(fitter, pts: np.ndarray):
    """``fitter(pts)`` (fit_line or fit_conic), remembered for the contours of the current
    labelling: the cleaning's last fit and the noise model's are of the same points."""
    pts = np.ascontiguousarray(pts, dtype=float)
    key = (fitter.__name__, pts.shape, pts.tobytes())
    f = _FITS.get(key)
    if f is None:
        if len(_FITS) >= 64:
            _FITS.clear()
        f = _FITS[key] = fitter(pts)
    return f


def _clean_contours(contours: identify.Contours, k: float = 4.0) -> None:
    """Drop contour points farther than k robust σ from their own curve fit (in place)."""
    for store in (contours.lines, contours.ellipses):
        for fid, pts in list(store.items()):
            for _ in range(2):
                if store is contours.lines:
                    f = _fit(fit_line, pts)
                    r = (pts - f.anchor) @ f.normal + f.offset
                else:
                    f = _fit(fit_conic, pts)
                    from ..pose.fitting import conic_rows, sampson_theta_jacobian
                    pn = (pts - f.center) / f.scale
                    r, _ = sampson_theta_jacobian(f.theta, pn[:, 0], pn[:, 1])
                    r = np.asarray(r) * f.scale
                s = 1.4826 * float(np.median(np.abs(r - np.median(r))))
                keep = np.abs(r) <= max(k * s, 0.05)
                if keep.all() or keep.sum() < 6:
                    break
                pts = pts[keep]
                contours.snr[fid] = contours.snr[fid][keep[: len(contours.snr[fid])]] if len(contours.snr[fid]) == len(keep) else contours.snr[fid]
            store[fid] = pts


_RESIDUALS: list = []


def _residuals(features: Features, obs: Observation, noise: NoiseModel, R: np.ndarray, t: np.ndarray):
    """``(problem, evaluation)`` of ``obs`` at pose (R, t), the last one remembered: the
    per-feature test, the covariance's variance factor and the labelling's score all ask
    for the same observation at the same pose, and compiling it fits every contour again."""
    key = (R.tobytes(), t.tobytes())
    if _RESIDUALS and _RESIDUALS[0] is features and _RESIDUALS[1] is obs and _RESIDUALS[2] is noise \
            and _RESIDUALS[3] == key:
        return _RESIDUALS[4], _RESIDUALS[5]
    prob = compile_problem(features, [obs], noise)
    ev = evaluate(prob, R[None], t[None], jac=False)
    _RESIDUALS[:] = [features, obs, noise, key, prob, ev]
    return prob, ev


def _feature_chi2(features: Features, obs: Observation, pose: Pose, noise: NoiseModel) -> dict[str, float]:
    """Each feature's whitened χ² at the pose, with its degrees of freedom's p-value."""
    prob, ev = _residuals(features, obs, noise, pose.rotation, pose.translation_mm)
    out = {}
    for fid, sl in prob.row_groups():
        c2 = float(np.sum(ev.rho[0, sl] ** 2))
        # chdtrc is what scipy.stats.chi2.sf evaluates, without its per-call argument checks
        out[fid] = float(chdtrc(sl.stop - sl.start, c2))
    return out


def _calibrated_covariance(features: Features, obs: Observation, pose: Pose, noise: NoiseModel,
                           opts: TrackOptions | None = None) -> float | None:
    """Rescale the pose covariance (in place) to the image path's noise model.

    The solver scales (JᵀJ)⁻¹ by κ², pooled over the pose residuals *and* the contour fits'
    scatter; here the contour scatter is only the random part of the noise model (the
    systematic part, see :func:`_noise_model`, does not show in a curve's scatter about
    its own fit). The scale is χ²/dof of the pose residuals alone — the a-posteriori
    variance factor s²: the model's systematic terms are sized for cluttered images
    (anatomy), and on a clean image the residuals are ~5× smaller than they allow, which
    this factor follows (floored at 0.02, i.e. σ at ≥ 14 % of the model's).

    That alone left the tilts' σ 1.3–1.5× too small on 600 tracked ftrac_2005 images (errors
    a pose absorbs show in no residual) while rz's was 1.3× too large. The covariance is
    therefore the sandwich ``s² A⁻¹ (Σₖ qₖ Jₖᵀ Jₖ) A⁻¹`` (A = JᵀJ, whitened; k = points,
    lines, ellipses) with the components qₖ of ``TrackOptions.variance_*``, chosen against
    the truth on rendered images of the three presets, clean and over anatomy
    (benchmarks/track_accuracy.py); the estimate itself is unchanged. Per-type components
    cannot make every axis exact: rz stays conservative (its errors ~0.55–0.6 σ). Returns s²."""
    if pose.covariance is None or not math.isfinite(pose.noise_scale) or pose.noise_scale <= 0:
        return None
    prob, ev = _residuals(features, obs, noise, pose.rotation, pose.translation_mm)
    m = ev.rho.shape[1]
    if m <= 6:
        return None
    s2 = max(float(np.sum(ev.rho[0] ** 2)) / (m - 6), 0.02)
    opts = opts or TrackOptions()
    q = {"p": opts.variance_point, "l": opts.variance_line, "e": opts.variance_ellipse}
    J = evaluate(prob, pose.rotation[None], pose.translation_mm[None], jac=True).J
    if J is None or not np.all(np.isfinite(J)):
        pose.covariance = pose.covariance / pose.noise_scale ** 2 * s2
        return s2
    J = J[0]
    w = np.empty(m)
    for fid, sl in prob.row_groups():
        w[sl] = q["p"] if fid in obs.points else (q["l"] if fid in obs.lines else q["e"])
    try:
        Ai = np.linalg.inv(J.T @ J)
    except np.linalg.LinAlgError:
        pose.covariance = pose.covariance / pose.noise_scale ** 2 * s2
        return s2
    C = s2 * Ai @ ((J * w[:, None]).T @ J) @ Ai
    pose.covariance = 0.5 * (C + C.T)
    return s2


def _absent_wires(features: Features, camera: Camera, pose: Pose, T: np.ndarray, noise: float, sc: dict,
                  opts: TrackOptions) -> tuple[list[str], dict[str, float]]:
    """Curves the pose predicts on bare background (see :func:`identify.wire_support`):
    those whose median density along the prediction is below ``wire_support`` × the
    best-supported curve's, or below 4 noise σ; also returns each curve's support in
    noise σ."""
    excl = np.full(len(features.points), sc["bead_radius_px"] + 2 * opts.blur_px + 1.0)
    sup = identify.wire_support(features, camera, pose.rotation, pose.translation_mm, T, excl)
    if not sup:
        return [], {}
    top = max(v for v, _ in sup.values())
    thr = max(4.0 * noise, opts.wire_support * top)
    return [fid for fid, (v, _) in sup.items() if v < thr], {fid: round(v / max(noise, 1e-12), 1)
                                                             for fid, (v, _) in sup.items()}


def _refit_beads_off_wires(T: np.ndarray, beads: Beads, features: Features, camera: Camera, pose: Pose, sc: dict,
                           noise: float, opts: TrackOptions) -> Beads:
    """The bead fits again with the pixels of the pose's predicted wires left out (a
    wire passing under a ball biases its centre; two crossing there, by ~0.4 px)."""
    if len(beads) == 0:
        return beads
    H, W = T.shape
    mask = np.zeros((H, W), np.uint8)
    half = 0.5 * sc["wire_px"] + 1.5 * float(np.median(beads.blur))
    for kind, pts in identify._curve_samples(features, camera, pose.rotation, pose.translation_mm).values():
        p = np.round(pts[np.isfinite(pts).all(1)]).astype(np.int32)
        if len(p) > 1:
            cv2.polylines(mask, [p.reshape(-1, 1, 2)], kind == "ellipse", 1, thickness=max(1, int(round(2 * half))))
    refit = fit_beads(T, beads.uv, sc["bead_radius_px"], float(np.median(beads.blur)), noise, beads.response,
                      exclude=mask.astype(bool))
    # keep the first fit where the mask left too little of a ball to fit
    ok = np.isfinite(refit.uv).all(1) & (np.linalg.norm(refit.uv - beads.uv, axis=1) < 1.0) & \
        np.isfinite(refit.sigma_px) & (refit.radius > 0.5 * sc["bead_radius_px"])
    return Beads(*(np.where(ok[:, None] if getattr(beads, k).ndim == 2 else ok, getattr(refit, k), getattr(beads, k))
                   for k in beads.__dataclass_fields__))


def _add_agreement(r: dict, features: Features, camera: Camera, T: np.ndarray, ridges: RidgePoints | None,
                   noise: float, sc: dict, opts: TrackOptions) -> None:
    """Add the label-free image agreement (:func:`identify.image_agreement`) to a
    labelling's misfit: ``agreement_chi2_per_px`` per pixel of unexplained ridge and of
    unsupported predicted wire."""
    p = r["pose"]
    if not np.all(np.isfinite(p.rotation)) or not (features.lines or features.ellipses) or ridges is None:
        return
    excl = np.full(len(features.points), sc["bead_radius_px"] + 2 * opts.blur_px + 1.0)
    ux, us = identify.image_agreement(features, camera, p.rotation, p.translation_mm, T, ridges, excl, noise,
                                      max(1.5, 0.5 * sc["wire_px"] + 1.0))
    r["agreement"] = (ux, us)
    r["score"] = r.get("score", 0.0) + opts.agreement_chi2_per_px * (ux + us)


def _solve(features: Features, obs: Observation, noise: NoiseModel, R0, t0, opts: TrackOptions,
           rescue: bool = True) -> Pose:
    """Refine from (R0, t0); if that fails and ``rescue``, the full no-guess solve."""
    sopts = SolverOptions(noise=noise, max_noise_scale=opts.max_noise_scale)
    p = refine_pose(features, obs, R0, t0, sopts)
    if not p.converged and rescue:
        # the identification's pose was not close enough: the full robust solve
        q = solve_pose(features, obs, sopts)
        if q.converged or not math.isfinite(p.noise_scale):
            p = q
    return p


def _evaluate_hypothesis(features: Features, camera: Camera, h: identify.BeadHypothesis, beads: Beads,
                         ridges: RidgePoints | None, sc: dict, opts: TrackOptions, first_stage: int = 0
                         ) -> dict[str, Any]:
    """Refine one labelling into a pose with every feature it can see: matching and
    contour gathering with wide tolerances (stage 0), tight ones (1), then tight and
    thinned (2); ``first_stage`` = 2 when the hypothesis's pose is already refined."""
    R, t = h.R, h.t
    rb = sc["bead_radius_px"]
    blur = float(np.median(beads.blur)) if len(beads) else opts.blur_px
    pix = sc["pixel_mm"]
    sep = 2 * rb + 2 * opts.blur_px
    excl = np.full(len(features.points), rb + 3 * opts.blur_px + 1.5)
    result: dict[str, Any] = {}
    pose = None
    for stage in (first_stage, 2) if first_stage < 2 and opts.fast else range(first_stage, 3):
        match, dropped_beads = _match_beads(features, camera, R, t, beads,
                                            opts.match_tol_px if stage else max(opts.match_tol_px, rb), sep)
        tol = opts.contour_tol_px if stage == 0 else opts.final_contour_tol_px
        if ridges is not None and (features.lines or features.ellipses):
            mag = camera.focal_length_mm / float(t[2]) if t[2] > 0 else opts.magnification
            wr = max([ln.wire_diameter for ln in features.lines] + [e.wire_diameter for e in features.ellipses]) \
                / 2 * mag / pix
            var = sc["ridge_sigma_px"] ** 2 + blur ** 2 + wr * wr / 4
            cont = identify.gather_contours(features, camera, R, t, ridges, excl, tol, opts.separation_px,
                                            ridge_var_px2=var,
                                            thin_px=opts.thin_factor * sc["ridge_sigma_px"] if stage == 2 else 0.0)
            _clean_contours(cont)
        else:
            cont = identify.Contours()
        obs = _observation(camera, {fid: beads.uv[j] for fid, j in match.items()}, cont)
        if not (obs.points or obs.lines or obs.ellipses):
            break
        noise = _noise_model(obs, beads, match, pix, opts)
        try:
            # the full solve rescues a poor starting pose: the labelling's own, in its first
            # stage; a later stage starts from that stage's solution, and on the accuracy
            # benchmark's images (60 + 60 ftrac_2005, 30 + 30 ftrac_mini and nine_bead) its
            # full solve never converged where the refinement had not (0 of 77; ~40 ms each)
            pose = _solve(features, obs, noise, R, t, opts, rescue=stage == first_stage)
        except Exception as exc:  # an unusable observation (e.g. collinear contour): stop here
            result["error"] = f"segmented features unusable: {exc}"
            pose = None
            break
        if not np.all(np.isfinite(pose.rotation)):
            break
        R, t = pose.rotation, pose.translation_mm
        result.update(pose=pose, obs=obs, noise=noise, match=match, contours=cont,
                      dropped={**dropped_beads, **cont.dropped})
    if pose is None or "obs" not in result:
        result.setdefault("error", "no usable features for this labelling")
        return result
    # per-feature test: drop the worst inconsistent feature and re-solve
    removed: dict[str, str] = {}
    obs, noise = result["obs"], result["noise"]
    for _ in range(opts.max_dropped + 1):
        pv = _feature_chi2(features, obs, pose, noise)
        worst = min(pv, key=pv.get) if pv else None
        if worst is None or pv[worst] >= opts.feature_p_value:
            break
        if len(removed) >= opts.max_dropped:
            pose.converged = False
            pose.error = (f"features inconsistent with the pose: {worst} (p = {pv[worst]:.1e}) after dropping "
                          f"{', '.join(removed)}; wrong identification or segmentation")
            break
        removed[worst] = f"residual improbable under the measured noise (p = {pv[worst]:.1e})"
        if len(obs.points) + len(obs.lines) + len(obs.ellipses) <= 1:
            pose.converged = False
            pose.error = f"no feature consistent with the pose ({worst}: p = {pv[worst]:.1e})"
            break
        obs = Observation(obs.camera, {k: v for k, v in obs.points.items() if k != worst},
                          {k: v for k, v in obs.lines.items() if k != worst},
                          {k: v for k, v in obs.ellipses.items() if k != worst}, obs.origin)
        # from the pose the dropped feature had pulled: a local solve (the full no-guess solve
        # here cost ~40 ms per drop, mostly on rival labellings, and changed no pose on 440
        # track_accuracy images: 100 ftrac_2005, 60 ftrac_mini, 60 nine_bead, clean and anatomy)
        pose = _solve(features, obs, noise, pose.rotation, pose.translation_mm, opts, rescue=False)
    result["variance_factor"] = _calibrated_covariance(features, obs, pose, noise, opts)
    result.update(pose=pose, obs=obs, removed=removed)
    result["score"] = _score(features, camera, obs, pose, noise, result.get("dropped", {}), removed,
                             result["contours"], sc, opts)
    return result


def _score(features: Features, camera: Camera, obs: Observation, pose: Pose, noise: NoiseModel, dropped: dict,
           removed: dict, cont: identify.Contours, sc: dict, opts: TrackOptions) -> float:
    """A labelling's misfit to the whole image: the χ² of the features it explains plus
    ``unexplained_chi2`` for each feature it predicts in view and clear of others but does
    not explain (a ball with no blob under it, a wire with no ridge, a feature rejected by
    its own χ²). Labellings that use different numbers of features are compared on this,
    not on the feature count or κ alone: a near-mirror labelling of ftrac_mini matched one
    ball more at a worse fit, and "more features" picked it."""
    if not np.all(np.isfinite(pose.rotation)):
        return math.inf
    prob, ev = _residuals(features, obs, noise, pose.rotation, pose.translation_mm)
    chi = float(np.sum(ev.rho[0] ** 2))
    H, W = sc.get("shape", (np.inf, np.inf))
    uv, _ = identify._project(camera, pose.rotation, pose.translation_mm, features.point_centers()) \
        if features.points else (np.zeros((0, 2)), None)
    m = sc["bead_radius_px"] + 2
    unexplained, isolated = 0, 0
    # a ball whose blob may be blended with a neighbour's (within 2 bead widths) is
    # not counted as clearly unexplained
    dd = np.linalg.norm(uv[:, None] - uv[None], axis=-1) + np.eye(len(uv)) * 1e9 if len(uv) else np.zeros((0, 0))
    for k, p in enumerate(features.points):
        inside = m <= uv[k, 0] <= W - 1 - m and m <= uv[k, 1] <= H - 1 - m
        if inside and p.id not in obs.points and (p.id not in dropped or p.id in removed):
            unexplained += 1
            isolated += bool(dd[k].min() > 4 * sc["bead_radius_px"] + 2)
    cont.unexplained_beads = isolated
    unexplained += len(set(cont.missing) | {k for k in removed if k not in {p.id for p in features.points}})
    return chi + opts.unexplained_chi2 * unexplained


def body_density(features: Features, camera: Camera, R: np.ndarray, t: np.ndarray, body, blur_px: float,
                 margin_px: int = 8):
    """The acetal body's modelled density (−ln of its blurred transmission) over its
    bounding box at pose (R, t): ``(box image, (row0, col0))``; uses the simulator's exact
    hollow-cylinder chords (:func:`ftrac_design.xray.line_integral_box`)."""
    from scipy.ndimage import gaussian_filter
    from ..xray import ImagingModel, line_integral_box

    p, (v0, u0) = line_integral_box(features.subset(set()), R, t, camera, ImagingModel(supersample=2), body,
                                    margin_px=margin_px)
    # the bead fit's blur includes the pixel's own width (variance 1/12), which the
    # pixel-integrated line integral already has
    s = math.sqrt(max(blur_px ** 2 - 1.0 / 12.0, 0.0))
    I = gaussian_filter(np.exp(-p), s, mode="nearest") if s > 0 else np.exp(-p)
    return -np.log(np.maximum(I, 1e-12)), (v0, u0)


def _ridges_without_body(g: np.ndarray, T: np.ndarray, noise: float, features: Features, camera: Camera,
                         R: np.ndarray, t: np.ndarray, body, blur: float, sc: dict, opts: TrackOptions):
    """Ridge points over the body's box after subtracting its modelled projection.

    The body's silhouette is a √-shaped ramp under the ellipse wires (they sit 0.3 mm
    inside the surface); a top-hat keeps part of that ramp under a wire whose profile it
    cannot separate from it, and the ridges shift inward — ellipses shrink (~0.3 px at σ =
    0.8 px) and the depth comes out 1–2 mm short. With the body subtracted first (its
    density scale fitted to the image, so display images work too) the wire sits on a flat
    background again."""
    B, (v0, u0) = body_density(features, camera, R, t, body, blur)
    H, W = g.shape
    r0, r1 = max(v0, 0), min(v0 + B.shape[0], H)
    c0, c1 = max(u0, 0), min(u0 + B.shape[1], W)
    if r1 - r0 < 8 or c1 - c0 < 8:
        return None, None
    gb = g[r0:r1, c0:c1].astype(np.float64)
    Bb = B[r0 - v0:r1 - v0, c0 - u0:c1 - u0]
    quiet = T[r0:r1, c0:c1] < 3 * noise                 # not a wire or a bead
    if quiet.sum() < 50 or np.ptp(Bb[quiet]) <= 0:
        return None, None
    A = np.stack([Bb[quiet], np.ones(int(quiet.sum()))], -1)
    (scale, off), *_ = np.linalg.lstsq(A, gb[quiet], rcond=None)
    if not scale > 0:
        return None, None
    g2 = (gb - scale * Bb).astype(np.float32)
    disc = int(math.ceil(max(sc["bead_radius_px"], sc["wire_px"]) + 3 * opts.blur_px + 2))
    T2 = top_hat(g2, disc)
    rp = None
    if features.lines or features.ellipses:
        rp = ridge_points(T2, sc["ridge_sigma_px"], noise, opts.ridge_min_snr)
        rp.uv = rp.uv + np.array([c0, r0], float)
    Tb = T.copy()
    Tb[r0:r1, c0:c1] = T2
    return rp, Tb


def track_image(image: np.ndarray, features: Features, camera: Camera, options: TrackOptions | None = None,
                polarity_hint: str | None = None, body="auto") -> TrackResult:
    """Segment, identify and solve one image with no initial guess.

    ``image`` (H, W) as stored (raw counts or a log/display image; see
    ``TrackOptions.polarity``); ``camera`` its intrinsics (SPEC §1). Never raises for an
    image in which the fiducial cannot be found: the pose then has ``converged = False``
    and the reason. ``body`` (an :class:`ftrac_design.xray.Body`, None, or "auto": from the
    design file named in ``features.source``) lets the ridges be found on the image with the
    body's modelled projection subtracted (see :func:`_ridges_without_body`).
    """
    if isinstance(body, str):
        from ..xray.scene import body_from_source
        body = body_from_source(features.source)
    opts = options or TrackOptions()
    img = np.asarray(image)
    if img.dtype != np.float32:
        img = img.astype(np.float32)
    sc = scales(features, camera, opts)
    disc = int(math.ceil(max(sc["bead_radius_px"], sc["wire_px"]) + 3 * opts.blur_px + 2))
    # everything first on a half-size image: polarity, and where the fiducial is
    small = cv2.resize(img, (img.shape[1] // 2, img.shape[0] // 2), interpolation=cv2.INTER_AREA) \
        if min(img.shape) >= 64 else img
    pol = opts.polarity
    if pol == "auto":
        pol = {"dense_dark": "dense-dark", "dense_bright": "dense-bright"}.get(polarity_hint or "", "")
        if not pol:
            pol = detect_polarity(small, max(disc // 2, 2))
    roi = fiducial_roi(to_density(small, pol), features, sc, opts) if small is not img and opts.roi else None
    if roi is not None:
        r0, r1, c0, c1 = roi
        res = _track_density(to_density(img[r0:r1, c0:c1], pol), features,
                             replace(camera, principal_point_px=(camera.principal_point_px[0] - c0,
                                                                 camera.principal_point_px[1] - r0)),
                             opts, body, pol)
        res = _shifted(res, camera, c0, r0)
        res.diagnostics["roi"] = [int(c0), int(r0), int(c1 - c0), int(r1 - r0)]
        if res.pose.converged or _view_limited(res, features, camera, img.shape, opts):
            return res
        # not found in the region the coarse look picked: the whole image, once
    res = _track_density(to_density(img, pol), features, camera, opts, body, pol)
    return res


def _view_limited(res: TrackResult, features: Features, camera: Camera, shape: tuple[int, int],
                  opts: TrackOptions) -> bool:
    """Whether a region's unconfirmed answer is limited by the view itself, so that searching
    the whole image (``shape``, seen with ``camera``) again cannot confirm it: too few balls
    could be used, and even a perfect segmentation of the whole image at that pose could
    use no more (:func:`_resolvable_beads`: the others overlap or leave the image). The
    whole-image retry cost ~200 ms and ended the same way."""
    need = min(opts.min_beads, len(features.points))
    p = res.pose
    if p.converged or res.observation is None or not np.all(np.isfinite(p.rotation)) or \
            not str(p.error or "").startswith("too little evidence") or len(res.observation.points) >= need:
        return False
    sc = {**scales(features, camera, opts), "shape": shape}
    n = _resolvable_beads(features, camera, p, sc, opts)
    res.diagnostics["beads_resolvable"] = n
    return n < need


def fiducial_roi(gs: np.ndarray, features: Features, sc: dict, opts: TrackOptions):
    """Where the fiducial is, from a half-size density image ``gs``: the full-size box
    ``(row0, row1, col0, col1)`` around the densest cluster of bead-like blobs, wide enough
    for the whole fiducial's projection from any of them; None when nothing bead-like is
    found (then the whole image is searched)."""
    if not features.points:
        return None
    rb = sc["bead_radius_px"] / 2
    disc = int(math.ceil(max(rb, sc["wire_px"] / 2) + 1.5 * opts.blur_px + 2))
    T = top_hat(gs, disc)
    noise = max(noise_sigma(T), 1e-9)
    P = len(features.points)
    cand, resp = blob_candidates(T, rb, noise, 3 * P + 6, opts.bead_min_snr)
    if len(cand) < 3:
        return None
    # the fiducial's largest extent in pixels at a generous magnification
    pts = [features.point_centers()]
    pts += [np.array([ln.start, ln.end]) for ln in features.lines]
    pts += [e.sample(np.linspace(0, 2 * np.pi, 16, endpoint=False)) for e in features.ellipses]
    X = np.concatenate(pts)
    ext = float(np.max(np.linalg.norm(X[:, None] - X[None], axis=-1)))
    D = ext * opts.magnification * 1.25 / sc["pixel_mm"]
    uv = 2 * cand + 0.5                                     # half-size pixel i covers full-size 2i, 2i + 1
    near = np.linalg.norm(uv[:, None] - uv[None], axis=-1) <= D
    k = int(np.argmax(near.astype(float) @ resp))
    cl = uv[near[k]]
    lo = cl.min(0) - 0.5 * D - 8
    hi = cl.max(0) + 0.5 * D + 8
    H, W = 2 * gs.shape[0], 2 * gs.shape[1]
    c0, r0 = max(int(lo[0]), 0), max(int(lo[1]), 0)
    c1, r1 = min(int(math.ceil(hi[0])) + 1, W), min(int(math.ceil(hi[1])) + 1, H)
    if (r1 - r0) * (c1 - c0) > 0.6 * H * W:
        return None
    return r0, r1, c0, c1


def _shifted(res: TrackResult, camera: Camera, du: int, dv: int) -> TrackResult:
    """``res`` found on a crop whose corner is at (du, dv) px, in the full image's pixels."""
    off = np.array([du, dv], float)
    if res.observation is not None:
        o = res.observation
        res.observation = Observation(camera, {k: v + off for k, v in o.points.items()},
                                      {k: CurveObservation(points=c.points + off) for k, c in o.lines.items()},
                                      {k: CurveObservation(points=c.points + off) for k, c in o.ellipses.items()},
                                      origin=o.origin)
    if res.beads is not None:
        res.beads = Beads(*(getattr(res.beads, k) + off if k == "uv" else getattr(res.beads, k)
                            for k in res.beads.__dataclass_fields__))
    if res.ridges is not None:
        res.ridges = RidgePoints(res.ridges.uv + off, res.ridges.normal, res.ridges.strength, res.ridges.snr)
    return res


def _track_density(g: np.ndarray, features: Features, camera: Camera, opts: TrackOptions, body, pol: str
                   ) -> TrackResult:
    """:func:`track_image` on a density image (dense = bright) seen with ``camera``."""
    T, noise_px, beads, ridges, sc = detect(g, features, camera, opts)
    sc["shape"] = g.shape
    diag: dict[str, Any] = {"blobs": 0 if beads is None else len(beads),
                            "ridge_points": 0 if ridges is None else len(ridges)}
    if not features.points:
        return TrackResult(_failed("identification needs beads; this design has none"), None, {}, beads, ridges,
                           pol, None, diag)
    if beads is None or len(beads) < 3:
        return TrackResult(_failed(f"no fiducial found: {0 if beads is None else len(beads)} bead-like blobs "
                                   f"(need at least 3 of {len(features.points)})"), None, {}, beads, ridges, pol,
                           None, diag)
    hyps = identify.bead_hypotheses(features.point_centers(), beads.uv, camera,
                                    opts.hypothesis_tol_radii * max(sc["bead_radius_px"], 2.0))
    if not hyps:
        return TrackResult(_failed(f"no fiducial found: {len(beads)} blobs, none matching the bead layout"), None,
                           {}, beads, ridges, pol, None, diag)
    # refine the best distinct labellings; the winner must beat the others clearly
    evaluated = []
    seen_poses: list[tuple[np.ndarray, np.ndarray]] = []
    for h in hyps[:4]:
        if h.count < max(4, hyps[0].count - 2):
            continue
        r = _evaluate_hypothesis(features, camera, h, beads, ridges, sc, opts)
        if "pose" not in r:
            continue
        p = r["pose"]
        if any(so3.angle(p.rotation, R0) < math.radians(0.5) and np.linalg.norm(p.translation_mm - t0) < 2.0
               for R0, t0 in seen_poses):
            continue
        seen_poses.append((p.rotation, p.translation_mm))
        if p.converged:
            # a labelling that puts wire on bare background is no candidate, and no rival
            absent, _ = _absent_wires(features, camera, p, T, noise_px, sc, opts)
            if absent:
                p.converged = False
                p.error = (f"identification not confirmed: the image shows no wire where the pose puts "
                           f"{', '.join(absent)}")
        _add_agreement(r, features, camera, T, ridges, noise_px, sc, opts)
        evaluated.append(r)
    if not evaluated:
        return TrackResult(_failed("no bead labelling led to a pose"), None, {}, beads, ridges, pol, None, diag)

    def key(r):
        return (not r["pose"].converged, r["score"])

    evaluated.sort(key=key)
    best = evaluated[0]
    if body is not None and np.all(np.isfinite(best["pose"].rotation)):
        # the body's modelled projection out of the image, then the balls refitted and the
        # wires found again there: the body's curved silhouette under a ball or a wire
        # shifts it toward the body's middle (ellipses shrank; nine_bead's depth was biased)
        blur = float(np.median(beads.blur))
        p0 = best["pose"]
        rp2, Tb = _ridges_without_body(g, T, noise_px, features, camera, p0.rotation, p0.translation_mm, body, blur,
                                       sc, opts)
        if Tb is not None:
            merged = None
            if ridges is not None and rp2 is not None and len(rp2):
                # ridge points outside the body's box stay as they were
                lo, hi = rp2.uv.min(0) - 1, rp2.uv.max(0) + 1
                outside = ~((ridges.uv >= lo) & (ridges.uv <= hi)).all(1)
                merged = RidgePoints(np.concatenate([ridges.uv[outside], rp2.uv]),
                                     np.concatenate([ridges.normal[outside], rp2.normal]),
                                     np.concatenate([ridges.strength[outside], rp2.strength]),
                                     np.concatenate([ridges.snr[outside], rp2.snr]))
            h2 = identify.BeadHypothesis(p0.rotation, p0.translation_mm, {}, 0, 0.0)
            beads2 = _refit_beads_off_wires(Tb, beads, features, camera, p0, sc, noise_px, opts)
            r2 = _evaluate_hypothesis(features, camera, h2, beads2, merged, sc, opts, first_stage=2)
            if "pose" in r2:
                # judged on the same ridges as the other labellings
                _add_agreement(r2, features, camera, T, ridges, noise_px, sc, opts)
            if "pose" in r2 and (r2["pose"].converged or not best["pose"].converged):
                others = [e for e in evaluated[1:]]
                best = r2
                ridges = merged if merged is not None else ridges
                beads = beads2
                evaluated = [best] + others
                diag["body_subtracted"] = True
    pose = best["pose"]
    if pose.converged and len(evaluated) > 1:
        for other in evaluated[1:]:
            q = other["pose"]
            # a rival need not have converged: the right labelling of a poorly segmented
            # image can fail its own χ² tests (ftrac_mini, benchmark image 27: the right one
            # dropped a ball and an ellipse and failed; a 136° one fitted 24 χ² better) — only
            # a labelling that puts wire on bare background is no rival, unless it still
            # explains the whole image better than the winner (its misfit includes the
            # unsupported wire): over anatomy ftrac_mini's 0.3 mm wire can look absent under
            # the right labelling, and a near-mirror won (track_accuracy 200-pose sample,
            # seed 1, images 1 and 96: 172° and 152° off, confident)
            if not math.isfinite(other.get("score", math.inf)) or not np.all(np.isfinite(q.rotation)) or \
                    (str(q.error or "").startswith("identification not confirmed")
                     and other["score"] >= best["score"]):
                continue
            if other["score"] - best["score"] >= opts.ambiguity_chi2:
                continue
            dang = math.degrees(float(so3.angle(q.rotation, pose.rotation)))
            dt = float(np.linalg.norm(q.translation_mm - pose.translation_mm))
            if dang > 1.0 or dt > 3.0:
                # both answers go out, so a user with a prior (e.g. the C-arm's own angles)
                # can choose; a design with a symmetry (nine_bead's helix has a two-fold
                # axis) is ambiguous by construction
                diag["alternatives"] = [
                    {"rotation": x["pose"].rotation.tolist(), "translation_mm": x["pose"].translation_mm.tolist(),
                     "noise_scale": float(x["pose"].noise_scale)} for x in (best, other)]
                pose.converged = False
                pose.error = (f"ambiguous identification: another labelling {dang:.1f}° and {dt:.1f} mm away "
                              f"explains the image as well (misfit {other['score']:.1f} vs {best['score']:.1f}, "
                              f"noise scale {q.noise_scale:.2f} vs {pose.noise_scale:.2f})")
                break
    obs = best["obs"]
    cont = best["contours"]
    if pose.converged:
        absent = _absent_wires(features, camera, pose, T, noise_px, sc, opts)
        diag["wire_support"] = absent[1]
        if absent[0]:
            pose.converged = False
            pose.error = (f"identification not confirmed: the image shows no wire where the pose puts "
                          f"{', '.join(absent[0])}")
    n_curves = len(features.lines) + len(features.ellipses)
    if pose.converged and n_curves and len(cont.missing) >= max(2, (n_curves + 1) // 2):
        # the labelling predicts wires where the image has none: the beads were misread
        pose.converged = False
        pose.error = (f"identification not confirmed: no wire found where the pose puts "
                      f"{', '.join(cont.missing)}")
    if pose.converged and n_curves and not (obs.lines or obs.ellipses):
        # the wires are what confirms a bead labelling; beads alone of a wire design
        # gave ftrac_mini's wrong poses (4 of 8 in 300 images)
        pose.converged = False
        pose.error = ("identification not confirmed: no wire contour could be used to verify the bead "
                      "labelling (wires crowded or hidden in this view)")
    nub = getattr(cont, "unexplained_beads", 0)
    if pose.converged and nub > opts.max_unexplained_beads:
        # balls in view, clear of the others, that the labelling leaves without a blob (or
        # rejects): a near-mirror labelling of ftrac_mini (image 142) matched 6 of 9
        pose.converged = False
        pose.error = (f"identification not confirmed: {nub} beads in view and well clear of the others are "
                      f"not explained (at most {opts.max_unexplained_beads})")
    if pose.converged and len(obs.points) < min(opts.min_beads, len(features.points)):
        # the balls carry the labelling; with fewer, a near-mirror of a small fiducial fits
        # its wires as well (ftrac_mini, benchmark images 242 and 165: 3 and 4 balls and both
        # ellipses, 173° and 168° off)
        pose.converged = False
        pose.error = (f"too little evidence: {len(obs.points)} beads could be used (need "
                      f"{min(opts.min_beads, len(features.points))} to confirm the labelling)")
    if pose.converged:
        m = 2 * len(obs.points) + 2 * len(obs.lines) + 5 * len(obs.ellipses)
        if m - 6 < opts.min_redundancy:
            pose.converged = False
            pose.error = (f"too little evidence: {len(obs.points)} beads, {len(obs.lines)} lines and "
                          f"{len(obs.ellipses)} ellipses leave {m - 6} redundant constraints (need "
                          f"{opts.min_redundancy} to verify a labelling)")
    if pose.converged and len(obs.points) < 6 and not (obs.lines or obs.ellipses):
        pose.converged = False
        pose.error = (f"too little evidence: {len(obs.points)} beads and no wires cannot verify a labelling "
                      f"(need ≥ 6 beads, or wires)")
    match = best.get("match", {})
    quality: dict[str, Any] = {"points": {}, "lines": {}, "ellipses": {}}
    pix = sc["pixel_mm"]
    for fid, j in match.items():
        if fid in obs.points:
            quality["points"][fid] = {"sigma_px": float(beads.sigma_px[j]), "radius_px": float(beads.radius[j]),
                                      "blur_px": float(beads.blur[j]), "snr": float(beads.response[j])}
    for store, name in ((obs.lines, "lines"), (obs.ellipses, "ellipses")):
        for fid, c in store.items():
            quality[name][fid] = {"snr": [round(float(x), 1) for x in cont.snr.get(fid, [])][: len(c.points)]}
    diag.update({
        "hypotheses": len(hyps),
        "labellings_tested": len(evaluated),
        "beads_matched": len(obs.points),
        "dropped": best.get("dropped", {}),
        "rejected": best.get("removed", {}),
        "pixel_noise": float(noise_px),
        # the residuals' own scale relative to the noise model (the covariance uses it)
        "variance_factor": best.get("variance_factor"),
    })
    return TrackResult(pose, obs, quality, beads, ridges, pol, best["noise"], diag)
