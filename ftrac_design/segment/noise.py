"""The image path's own noise model, its contour cleaning, per-feature tests and covariance.

The solver's noise model is not a fixed default but the segmentation's measured accuracy:
each bead's centre uncertainty from its model fit and each curve's residual scatter about
its own fit, pooled per feature type, with floors and systematic terms measured on rendered
images (:class:`~.options.TrackOptions` ``floor_*``, ``sys_*``). Each feature's whitened
residual is then tested on its own (:func:`feature_p_values`), and the pose covariance is
rescaled to what the residuals showed (:func:`calibrated_covariance`).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial import cKDTree
from scipy.special import chdtrc

from ..features.model import Features
from ..pose import NoiseModel, Observation, Pose
from ..pose.fitting import fit_conic, fit_line, sampson_theta_jacobian
from ..pose.problem import compile_problem, evaluate
from . import identify
from .beads import Beads
from .options import NoiseOptions, TrackOptions


def measured_noise(
    obs: Observation, beads: Beads, match: dict[str, int], pix: float, blur_px: float, opts: NoiseOptions
) -> NoiseModel:
    """Per-feature-type σ (mm at the detector) measured on this image, with floors.

    Beside the random part measured here (each ball's own fit, see :func:`_ball_sigmas`;
    each curve type's scatter about its own fits, pooled with a prior from the balls, see
    :func:`_curve_prior`) every feature carries a systematic error that
    does not average away over its points — a bead centre pulled by a wire or a bone edge, a
    wire's contour shifted by the background's slope (``TrackOptions.sys_point_px`` /
    ``sys_curve_px``, measured against the truth on rendered images with anatomy; the curves'
    grows with the blur²). The solver's noise model is one σ per contour point of a curve
    type, so a curve's systematic part enters as ``n σ_sys²`` per point (n its typical number
    of points): then a curve's fitted parameters carry σ_sys as they should and the
    per-feature χ² test does not reject correct curves for a 0.05 px shift.

    Parameters
    ----------
    obs : the labelling's observation (pixels).
    beads : the fitted blobs; ``match`` maps bead id → blob index.
    pix : pixel pitch, mm.
    blur_px : the blur σ the image was detected at, px.
    opts : the floors and systematic errors (:attr:`~.options.LabellingOptions.noise`).

    Returns
    -------
    NoiseModel with each ball's σ (``points``), their median (``point_mm``), and the line and
    ellipse σ, mm at the detector.
    """
    point, points = _ball_sigmas(beads, match, pix, opts)
    prior = _curve_prior(beads, match, opts)
    # a curve's systematic shift comes mostly from what its ridge sits on and how it bends
    # (the curvature correction is ∝ the smoothing variance): it grows with the blur², and
    # a 2 px blur left an ellipse pose 4 mm off in depth with a χ² of 80 at the default
    sys_curve = opts.sys_curve_px * max(1.0, (blur_px / TrackOptions.blur_px) ** 2)
    out = []
    for store, fitter, floor in (
        (obs.lines, fit_line, opts.floor_line_mm),
        (obs.ellipses, fit_conic, opts.floor_ellipse_mm),
    ):
        rss, dof, ns = 0.0, 0, []
        for c in store.values():
            f = cached_fit(fitter, c.points)
            rss += float(f.rss)
            dof += int(f.dof)
            ns.append(len(c.points))
        # the scatter about a curve's own fit, pooled with the balls' prior (px²; its dof)
        s2, nu = rss + prior[1] * prior[0] ** 2, dof + prior[1]
        s = math.sqrt(s2 / nu) if ns and nu > 0 else 0.0
        n = float(np.median(ns)) if ns else 0.0
        out.append(max(math.sqrt(s * s + n * sys_curve**2) * pix, floor))
    return NoiseModel(point, out[0], out[1], points)


def _curve_prior(beads: Beads, match: dict[str, int], opts: NoiseOptions) -> tuple[float, float]:
    """The prior of a curve type's contour scatter: (σ px, degrees of freedom).

    ``curve_prior_scale`` × the median fit σ of the labelling's balls, worth
    ``curve_prior_dof`` degrees of freedom; none (0, 0) without a matched ball. The balls
    see the same image — its noise, its contrast, its blur — as the wires beside them, so
    they say what a curve's scatter should be where its own fit cannot: a conic through six
    contour points keeps one degree of freedom, and one χ²₁ draw is below a tenth of its σ
    one time in twelve. On tuning seed 21 (ftrac_2005 and ftrac_mini, 11 conditions, 481
    curves of converged poses, ``benchmarks/curve_sigma_fit.py``), the curves' RMS distance
    from the true curve over their model σ had a median of 1.99 and a 90th percentile of 15
    for curves of fewer than 2 degrees of freedom, against 1.15 and 1.55 for those of 10 or
    more; with this prior (4 dof, 1.25 ×), 0.96 and 2.1 against 1.12 and 1.5 (held-out seed
    2095: 1.05 and 5.7 → 1.16 and 1.9)."""
    if not match or opts.curve_prior_dof <= 0:
        return 0.0, 0.0
    s = float(np.median(np.asarray(beads.sigma_px, float)[list(match.values())]))
    if not (math.isfinite(s) and s > 0):
        return 0.0, 0.0
    return opts.curve_prior_scale * s, opts.curve_prior_dof


def _ball_sigmas(
    beads: Beads, match: dict[str, int], pix: float, opts: NoiseOptions
) -> tuple[float, tuple[tuple[str, float], ...]]:
    """Each matched ball's σ (mm at the detector, per axis) and their median.

    σᵢ² = (a sᵢ)² + (b |rᵢ − r̃|)² + (c |mᵢ − m_q|)² + σ_sys², with sᵢ the ball fit's own σ,
    rᵢ its fitted radius, mᵢ = √(rᵢ² / 5 + blurᵢ²) its apparent size (the blurred ball's
    second moment per axis), r̃ the median radius and m_q the ``point_size_quantile`` of the
    sizes over the labelling's balls (px), a = ``point_fit_scale``, b = ``point_radius_scale``,
    c = ``point_size_scale``, σ_sys = ``sys_point_px``; floored at ``floor_point_mm`` and
    capped at ``point_max_ratio`` × the median σᵢ. The size's reference is the sharper balls'
    (the lower third): a clipped shoulder, a bone edge, a wire or a tube's wall under a ball
    makes it look larger, never sharper, and when five of ``ftrac_mini``'s nine balls lay on
    a tube's two walls (seed 2121, round field 16) the median size was a disturbed ball's —
    two balls pulled 1.1 and 1.7 px along the wall got half the σ of the four undisturbed
    ones and the pose was 3.8° and 4.5 mm off at χ²₆ 48 (with the lower third: 3.3° and
    2.3 mm, χ²₆ 16).

    a, b and c are the maximum-likelihood values on 4,594 balls of right poses
    (``benchmarks/ball_sigma_fit.py``, seed 21, ftrac_2005, ftrac_mini and nine_bead, clean
    and 11 hard conditions, the median as the size's reference; σ_sys held): on held-out seed
    2091 the balls' errors against the truth had a per-axis RMS of 0.99 σᵢ and 1.1 % lay
    beyond χ²₂ = 13.8 (p = 10⁻³), against 1.15 σ and 3.1 % without the size term and 1.70 σ
    and 8.3 % for the median ball's σ given to every ball. With the lower third as the
    reference and the same scales, on seed 2121's 4,687 balls of right poses: 0.96 σ and
    1.43 % beyond, against 0.98 σ and 1.69 % with the median. Scales refitted to the lower
    third calibrate the balls better still (1.07 % with seed 21's fit), but the refit tried
    (b = 0.16 for 0.23) weights a ball merged with a wire more and left ftrac_2005's depth
    errors larger on 407 of 700 poses (seeds 21, 2113, 2121): the scales are kept. Weighting
    each ball by its own σ is what keeps a ball overlapped by a needle, a wire or an edge (its
    fit worse, its radius larger), or shown blurrier than its fellows, from pulling the pose in
    depth."""
    if not match:
        return opts.floor_point_mm, ()
    ids = list(match)
    idx = np.array([match[k] for k in ids])
    r = np.asarray(beads.radius, float)[idx]
    s = np.asarray(beads.sigma_px, float)[idx]
    m = np.sqrt(beads.second_moment_px2[idx])
    sig = np.sqrt(
        (opts.point_fit_scale * s) ** 2
        + (opts.point_radius_scale * (r - np.median(r))) ** 2
        + (opts.point_size_scale * (m - np.quantile(m, opts.point_size_quantile))) ** 2
        + opts.sys_point_px**2
    )
    sig = np.maximum(sig * pix, opts.floor_point_mm)
    med = float(np.median(sig))
    sig = np.minimum(sig, opts.point_max_ratio * med)
    return med, tuple((k, float(v)) for k, v in zip(ids, sig))


_FITS: dict = {}


def cached_fit(fitter, pts: np.ndarray):
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


def clean_contours(contours: identify.Contours, k: float = 4.0) -> None:
    """Drop contour points farther than ``k`` robust σ from their own curve fit (in place)."""
    for store in (contours.lines, contours.ellipses):
        for fid, pts in list(store.items()):
            for _ in range(2):
                if store is contours.lines:
                    f = cached_fit(fit_line, pts)
                    r = (pts - f.anchor) @ f.normal + f.offset
                else:
                    f = cached_fit(fit_conic, pts)
                    pn = (pts - f.center) / f.scale
                    r, _ = sampson_theta_jacobian(f.theta, pn[:, 0], pn[:, 1])
                    r = np.asarray(r) * f.scale
                s = 1.4826 * float(np.median(np.abs(r - np.median(r))))
                keep = np.abs(r) <= max(k * s, 0.05)
                if keep.all() or keep.sum() < 6:
                    break
                pts = pts[keep]
                snr = contours.snr[fid]
                contours.snr[fid] = snr[keep[: len(snr)]] if len(snr) == len(keep) else snr
            store[fid] = pts


_RESIDUALS: list = []


def residuals_at(features: Features, obs: Observation, noise: NoiseModel, R: np.ndarray, t: np.ndarray):
    """``(problem, evaluation)`` of ``obs`` at pose (R, t), the last one remembered: the
    per-feature test, the covariance's variance factor and the labelling's score all ask
    for the same observation at the same pose, and compiling it fits every contour again."""
    key = (R.tobytes(), t.tobytes())
    if (
        _RESIDUALS
        and _RESIDUALS[0] is features
        and _RESIDUALS[1] is obs
        and _RESIDUALS[2] is noise
        and _RESIDUALS[3] == key
    ):
        return _RESIDUALS[4], _RESIDUALS[5]
    prob = compile_problem(features, [obs], noise)
    ev = evaluate(prob, R[None], t[None], jac=False)
    _RESIDUALS[:] = [features, obs, noise, key, prob, ev]
    return prob, ev


def feature_p_values(features: Features, obs: Observation, pose: Pose, noise: NoiseModel) -> dict[str, float]:
    """Each feature's p-value: the probability of a whitened χ² at least as large as its own
    at ``pose``, with its rows as degrees of freedom."""
    prob, ev = residuals_at(features, obs, noise, pose.rotation, pose.translation_mm)
    out = {}
    for fid, sl in prob.row_groups():
        c2 = float(np.sum(ev.rho[0, sl] ** 2))
        # chdtrc is what scipy.stats.chi2.sf evaluates, without its per-call argument checks
        out[fid] = float(chdtrc(sl.stop - sl.start, c2))
    return out


def redundancy_numbers(features: Features, obs: Observation, pose: Pose, noise: NoiseModel) -> dict[str, float]:
    """Each feature's smallest redundancy number at ``pose``: over its rows, 1 − the diagonal
    of the whitened hat matrix J (JᵀJ)⁻¹ Jᵀ — the share of an error in that row that shows in
    the row's own residual (Baarda's internal reliability). Near 0, the feature alone fixes a
    direction of the pose: an error in it moves the pose and leaves no residual anywhere.
    Empty when the Jacobian is not finite or has fewer rows than the pose's 6 unknowns."""
    prob, _ = residuals_at(features, obs, noise, pose.rotation, pose.translation_mm)
    J = evaluate(prob, pose.rotation[None], pose.translation_mm[None], jac=True).J
    if J is None or J.shape[1] < 6 or not np.all(np.isfinite(J)):
        return {}
    Q, _ = np.linalg.qr(J[0])
    r = 1.0 - np.sum(Q * Q, axis=1)
    return {fid: float(r[sl].min()) for fid, sl in prob.row_groups()}


def calibrated_covariance(
    features: Features, obs: Observation, pose: Pose, noise: NoiseModel, opts: NoiseOptions | None = None
) -> float | None:
    """Rescale the pose covariance (in place) to the image path's noise model; returns s².

    The solver scales (JᵀJ)⁻¹ by κ², pooled over the pose residuals *and* the contour fits'
    scatter; here the contour scatter is only the random part of the noise model (the
    systematic part, see :func:`measured_noise`, does not show in a curve's scatter about
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
    cannot make every axis exact: rz stays conservative (its errors ~0.55–0.6 σ).

    s² comes from only ν = m − 6 residual degrees of freedom (m the pose residuals: two per
    ball, a curve's fitted parameters; ν is 7–40 on images). Given s², the scale's posterior
    (Jeffreys' prior) has mean ν s²/(ν − 2) and the pose error is Student-t with ν degrees of
    freedom, not normal: its covariance ν/(ν − 2) s² C is the one given (1.25 × at ν = 10,
    1.08 × at ν = 28); with ν ≤ 2 (no finite covariance) the solver's own is kept. Without
    the factor, eight ftrac_2005 balls under a 2 px blur (realism seed 2137) drew s² = 0.29
    from ν = 10 and a pose 1.0° off in a tilt read χ²₆ = 26.5 — improbable at p < 10⁻⁴ under
    a known scale, p = 0.019 under the scale's own uncertainty; with it, 21.4. Returns s²
    itself (the diagnostics' variance factor), not the factor's product."""
    if pose.covariance is None or not math.isfinite(pose.noise_scale) or pose.noise_scale <= 0:
        return None
    prob, ev = residuals_at(features, obs, noise, pose.rotation, pose.translation_mm)
    m = ev.rho.shape[1]
    nu = m - 6
    if nu <= 2:
        return None
    s2 = max(float(np.sum(ev.rho[0] ** 2)) / nu, 0.02)
    scale = s2 * nu / (nu - 2)
    opts = opts or TrackOptions().labelling.noise
    q = {"p": opts.variance_point, "l": opts.variance_line, "e": opts.variance_ellipse}
    J = evaluate(prob, pose.rotation[None], pose.translation_mm[None], jac=True).J
    if J is None or not np.all(np.isfinite(J)):
        pose.covariance = pose.covariance / pose.noise_scale**2 * scale
        return s2
    J = J[0]
    w = np.empty(m)
    for fid, sl in prob.row_groups():
        w[sl] = q["p"] if fid in obs.points else (q["l"] if fid in obs.lines else q["e"])
    try:
        Ai = np.linalg.inv(J.T @ J)
    except np.linalg.LinAlgError:
        pose.covariance = pose.covariance / pose.noise_scale**2 * scale
        return s2
    C = scale * Ai @ ((J * w[:, None]).T @ J) @ Ai
    pose.covariance = 0.5 * (C + C.T)
    return s2


def distortion_modes(camera, uv: np.ndarray, radius_mm: float) -> list[np.ndarray]:
    """Image displacements (px, one (n, 2) array per mode) of points ``uv`` (n, 2) px under
    the distortions an image intensifier adds, each 1 mm at ``radius_mm`` from the principal
    point: pincushion (radial, cubic in the radius), S-distortion (a rotation growing with
    the square of the radius), and the pincushion's centre off the principal point along u
    and along v (its derivative with respect to the centre: quadratic fields, scaled to 1 mm
    at ``radius_mm`` too — an intensifier's distortion centre is not its principal point)."""
    pix = float(np.mean(camera.pixel_size_mm))
    c = np.asarray(camera.principal_point_px, float)
    d = np.asarray(uv, float) - c
    r0 = radius_mm / pix
    r2 = np.sum(d * d, axis=-1, keepdims=True)
    g = (r2 / r0**3) / pix
    modes = [d * g, np.stack([-d[:, 1], d[:, 0]], -1) * g]
    for axis in range(2):
        e = np.zeros(2)
        e[axis] = 1.0
        # −∂/∂c of |p − c|² (p − c) along the axis: 2 (p − c)(p − c)ᵢ + |p − c|² eᵢ; 3 r0² at r0
        field = 2 * d * d[:, axis : axis + 1] + r2 * e
        modes.append(field / (3 * r0**2) / pix)
    return modes


def _displaced_by_modes(obs: Observation, radius_mm: float) -> list[Observation]:
    """``obs`` displaced by each of the four modes of :func:`distortion_modes`, in order."""
    from ..pose.observation import CurveObservation

    pts = {k: distortion_modes(obs.camera, np.asarray(v, float)[None], radius_mm) for k, v in obs.points.items()}
    lines = {k: distortion_modes(obs.camera, c.points, radius_mm) for k, c in obs.lines.items()}
    ells = {k: distortion_modes(obs.camera, c.points, radius_mm) for k, c in obs.ellipses.items()}
    return [
        Observation(
            obs.camera,
            {k: v + pts[k][m][0] for k, v in obs.points.items()},
            {k: CurveObservation(points=c.points + lines[k][m]) for k, c in obs.lines.items()},
            {k: CurveObservation(points=c.points + ells[k][m]) for k, c in obs.ellipses.items()},
            obs.origin,
        )
        for m in range(4)
    ]


def ellipses_moved_out(features: Features, obs: Observation, pose: Pose, step_px: float) -> Observation:
    """``obs`` with every ellipse contour point moved ``step_px`` outward along the normal of the
    ellipse the pose projects (its nearest dense sample's, away from the curve's centre)."""
    from ..pose.observation import CurveObservation

    curves = identify.curve_samples(features, obs.camera, pose.rotation, pose.translation_mm)
    moved = {}
    for fid, c in obs.ellipses.items():
        pts = np.asarray(c.points, float)
        model = curves.get(fid, (None, np.zeros((0, 2))))[1]
        if len(model) < 8:
            moved[fid] = CurveObservation(points=pts)
            continue
        if np.isfinite(model).all() and np.isfinite(pts).all():
            j = cKDTree(model).query(pts)[1]
        else:
            j = np.argmin(((pts[:, None, :] - model[None]) ** 2).sum(-1), axis=1)
        tangent = np.roll(model, -1, 0)[j] - np.roll(model, 1, 0)[j]
        normal = np.stack([-tangent[:, 1], tangent[:, 0]], 1)
        normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-12)
        normal *= np.sign(((model[j] - model.mean(0)) * normal).sum(1, keepdims=True))
        moved[fid] = CurveObservation(points=pts + step_px * normal)
    return Observation(obs.camera, dict(obs.points), dict(obs.lines), moved, obs.origin)


def contour_offset_covariance(
    features: Features, obs: Observation, pose: Pose, noise: NoiseModel, sigma_px: float
) -> np.ndarray | None:
    """The pose covariance (6 × 6, SPEC §4 order) that an offset of ``sigma_px`` (σ, px) shared by
    the ellipse contours along their normals adds: σ² Δθ Δθᵀ, Δθ how far moving them all 1 px
    outward moves the least-squares pose (:func:`pose_shifts`, as :func:`distortion_covariance`
    reads a distortion). An ellipse's size
    is the pose's depth: a contour 0.01 px inside moves ftrac_2005 ~0.1 mm away, and with its
    balls fitted to 0.02 px on a clean frame the covariance said ±0.05 mm. None without
    ellipse contours or where the pose's Jacobian is unusable."""
    if sigma_px <= 0 or not obs.ellipses:
        return None
    shifts = pose_shifts(features, obs, [ellipses_moved_out(features, obs, pose, 1.0)], noise, pose)
    return None if shifts is None else _offset_term(shifts[0], sigma_px)


def _offset_term(shift: np.ndarray, sigma_px: float) -> np.ndarray:
    """:func:`contour_offset_covariance` of the pose's shift per px of outward offset."""
    return sigma_px**2 * np.outer(shift, shift)


def pose_shifts(
    features: Features, obs: Observation, moved: list[Observation], noise: NoiseModel, pose: Pose
) -> np.ndarray | None:
    """How far each observation of ``moved`` (``obs`` with its features displaced) moves the
    least-squares pose (k, 6), SPEC §4 order: one Gauss–Newton step from ``pose`` of each, its
    whitened Jacobian J and residuals ρ evaluated on it, −(JᵀJ)⁻¹ Jᵀ ρ, less the same step of
    ``obs`` (≈ 0 at a converged pose); all compiled and evaluated as one batch (one batched
    contour fit). None where a Jacobian is unusable."""
    n = 1 + len(moved)
    R, t = pose.rotation, pose.translation_mm
    ev = evaluate(
        compile_problem(features, [obs, *moved], noise, same_structure=True),
        np.repeat(R[None], n, 0),
        np.repeat(t[None], n, 0),
        jac=True,
    )
    J, rho = ev.J, ev.rho
    if J is None or J.shape[0] != n or not (np.all(np.isfinite(J)) and np.all(np.isfinite(rho))):
        return None
    try:
        steps = -np.linalg.solve(np.einsum("bri,brj->bij", J, J), np.einsum("bri,br->bi", J, rho)[..., None])[..., 0]
    except np.linalg.LinAlgError:
        return None
    return steps[1:] - steps[0]


#: where the distortion modes of :func:`distortion_covariance` are 1 mm: 100 mm from the
#: principal point
DISTORTION_RADIUS_MM = 100.0


def distortion_covariance(
    features: Features,
    obs: Observation,
    pose: Pose,
    noise: NoiseModel,
    sigma_mm: float,
    radius_mm: float = DISTORTION_RADIUS_MM,
) -> np.ndarray | None:
    """The pose covariance (6 × 6, SPEC §4 order) that an unmodelled image distortion of
    ``sigma_mm`` (σ of the pincushion and S modes of :func:`distortion_modes`, 0.4 σ of the
    centre's, at ``radius_mm`` from the principal point) adds: Σ σ² Δθ Δθᵀ over the modes,
    Δθ how far each mode's displacement of the observed features moves the least-squares pose.
    A pinhole pose from an intensifier's image is biased mostly in depth (a pincushion
    magnifies the fiducial's image: 3–5 mm at 667 mm for 2 mm at 100 mm), which no residual
    shows; this term makes the covariance say so. None where the pose's Jacobian is unusable.

    Δθ is :func:`pose_shifts` of the displaced observation. The Jacobian must be the displaced
    observation's: a
    contour seen as a short arc has a fitted conic, and so a whitening, that the displacement
    changes. With the undisplaced observation's Jacobian, one ellipse's arc (ftrac_2005,
    held-out seed 2050, image 169) gave 0.23 mm in depth per mm of pincushion where the solver
    moved 3.4 mm (and the image's pincushion of 1.3 mm, 5.0 mm: a confident wrong pose)."""
    if sigma_mm <= 0 or not (obs.points or obs.lines or obs.ellipses):
        return None
    shifts = pose_shifts(features, obs, _displaced_by_modes(obs, radius_mm), noise, pose)
    return None if shifts is None else _distortion_term(shifts, sigma_mm)


def _distortion_term(shifts: np.ndarray, sigma_mm: float) -> np.ndarray:
    """:func:`distortion_covariance` of the pose's shifts (4, 6) per mm of each mode."""
    out = np.zeros((6, 6))
    # the centre's modes at 0.4 σ: a pincushion of 2 mm at 100 mm whose centre is 1 cm off the
    # principal point differs from the centred one by 0.6 mm there (3 k r² δ)
    for dth, weight in zip(shifts, (1.0, 1.0, 0.4, 0.4)):
        out += (weight * sigma_mm) ** 2 * np.outer(dth, dth)
    return out


def unmodelled_covariance(
    features: Features, obs: Observation, pose: Pose, noise: NoiseModel, offset_px: float, distortion_mm: float
) -> tuple[np.ndarray | None, np.ndarray | None]:
    """:func:`contour_offset_covariance` (``offset_px``; 0: none) and :func:`distortion_covariance`
    (``distortion_mm`` at :data:`DISTORTION_RADIUS_MM`; 0: none) of one pose, their shifts from one batch of
    :func:`pose_shifts` (the observation compiled and its conics fitted once for both: a
    run's frame spends ~1 ms on each compilation); each the same numbers as its own function
    gives, which it falls back on where a displaced observation's Jacobian is unusable."""
    moved = []
    if offset_px > 0 and obs.ellipses:
        moved.append(ellipses_moved_out(features, obs, pose, 1.0))
    first = len(moved)
    if distortion_mm > 0 and (obs.points or obs.lines or obs.ellipses):
        moved += _displaced_by_modes(obs, DISTORTION_RADIUS_MM)
    shifts = pose_shifts(features, obs, moved, noise, pose) if moved else None
    if shifts is None:
        return (
            contour_offset_covariance(features, obs, pose, noise, offset_px),
            distortion_covariance(features, obs, pose, noise, distortion_mm),
        )
    offset = _offset_term(shifts[0], offset_px) if first else None
    return offset, (_distortion_term(shifts[first:], distortion_mm) if len(moved) > first else None)
