"""One bead labelling refined into a pose with every feature it can see, and its misfit.

A labelling hypothesis (:class:`~.identify.BeadHypothesis`: a pose from three balls) is
refined in stages — bead matching and contour gathering with wide tolerances, then tight
ones, then tight and thinned — each solved from the previous stage's pose; features whose
own residual is improbable under the measured noise are dropped and the pose re-solved.
The result is a :class:`Labelling`; its ``score`` (:func:`misfit`) compares labellings that
explain different numbers of features.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components

from ..pose import NoiseModel, Observation, Pose, SolverOptions, refine_pose
from ..pose.observation import CurveObservation
from . import evidence, identify
from .beads import Beads
from .detection import LEARNED_BALL, Scene
from .guided import guided_contours
from .noise import (
    calibrated_covariance,
    clean_contours,
    feature_p_values,
    measured_noise,
    residuals_at,
    unmodelled_covariance,
)
from .options import ContourOptions, LabellingOptions


class NoLabelling(Exception):
    """A labelling hypothesis that led to no pose (:func:`evaluate`): ``reason`` says why."""

    def __init__(self, reason: str):
        super().__init__(reason)
        self.reason = reason


@dataclass(frozen=True)
class Labelling:
    """A labelling's refined pose and what it explains."""

    pose: Pose
    obs: Observation
    noise: NoiseModel
    #: model bead id → blob index
    match: dict[str, int]
    contours: identify.Contours
    #: features left out before the solve (merged blobs, crowded contours), with why
    dropped: dict[str, str]
    #: features rejected by their own χ² test, with why
    removed: dict[str, str] = field(default_factory=dict)
    #: a-posteriori variance factor of the residuals (see :func:`~.noise.calibrated_covariance`)
    variance_factor: float | None = None
    #: misfit to the whole image (:func:`misfit`, plus :func:`with_agreement`'s charge)
    score: float = math.inf
    #: (unexplained ridge px, unsupported wire px) of :func:`~.evidence.image_agreement`
    agreement: tuple[float, float] | None = None
    #: whether the labelling explained a wire contour before the body's projection was
    #: subtracted (contours it found only after that are not counted as confirming it)
    wires_at_first: bool = True

    @property
    def confirmed_by_wires(self) -> bool:
        """Whether wire contours confirm the labelling: it explains one now, and did before
        the body was subtracted."""
        return bool(self.obs.lines or self.obs.ellipses) and self.wires_at_first

    @property
    def placed(self) -> bool:
        """Whether the pose is finite (it may still have failed its tests)."""
        return bool(np.all(np.isfinite(self.pose.rotation)) and np.all(np.isfinite(self.pose.translation_mm)))


def observation(camera, beads_uv: dict[str, np.ndarray], contours: identify.Contours) -> Observation:
    """The SPEC §3 observation of matched bead centres and gathered contours (pixels)."""
    return Observation(
        camera,
        dict(beads_uv),
        {k: CurveObservation(points=v) for k, v in contours.lines.items()},
        {k: CurveObservation(points=v) for k, v in contours.ellipses.items()},
        origin="<image>",
    )


def match_beads(
    scene: Scene, R: np.ndarray, t: np.ndarray, beads: Beads, tol: float, sep: float
) -> tuple[dict[str, int], dict[str, str]]:
    """Model bead id → blob index at pose (R, t): the nearest blob within ``tol`` px, one
    blob per bead; beads projected within ``sep`` px of another bead are left out (merged
    blobs). Returns the match and the beads left out with why."""
    features = scene.features
    out: dict[str, int] = {}
    if not features.points or beads is None or len(beads) == 0:
        return out, {}
    uv, _ = identify.project(scene.camera, R, t, features.point_centers())
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


def solve_from(scene: Scene, obs: Observation, noise: NoiseModel, R0, t0, max_noise_scale: float) -> Pose:
    """The pose of ``obs`` refined from (R0, t0) (frame F in frame X, mm), the solver's noise
    scale κ at most ``max_noise_scale``.

    No full no-guess solve (:func:`ftrac_design.pose.solve_pose`, its 96 starts) follows a
    refinement that fails: the hypothesis' own pose comes from three of its balls, so a
    labelling whose refinement from there does not converge is one the image does not bear
    out. On the realism benchmark's tuning seed 21 it ran for 215 ftrac_2005 labellings,
    ~60 ms each, and converged for 5; leaving it out changed no outcome of the 780 images of
    seeds 21 and 2113 each (the three presets)."""
    sopts = SolverOptions(noise=noise, max_noise_scale=max_noise_scale)
    return refine_pose(scene.features, obs, R0, t0, sopts)


def _contours(scene: Scene, R, t, blur: float, stage: int, opts: ContourOptions) -> identify.Contours:
    """Contours gathered at pose (R, t) with the tolerances of ``stage`` (0 wide, 1 tight,
    2 tight and thinned)."""
    features, sc = scene.features, scene.scales
    if scene.ridges is None or not (features.lines or features.ellipses):
        return identify.Contours()
    tol = opts.contour_tol_px if stage == 0 else opts.final_contour_tol_px
    mag = scene.camera.focal_length_mm / float(t[2]) if t[2] > 0 else opts.magnification
    wr = (
        max([ln.wire_diameter for ln in features.lines] + [e.wire_diameter for e in features.ellipses])
        / 2
        * mag
        / sc.pixel_mm
    )
    var = sc.ridge_sigma_px**2 + blur**2 + wr * wr / 4
    excl = np.full(len(features.points), sc.bead_radius_px + 3 * sc.blur_px + 1.5)
    if opts.contours == "guided":
        cont = guided_contours(
            scene,
            R,
            t,
            excl,
            tol,
            opts.separation_px,
            opts.guided_min_snr,
            spacing_px=opts.thin_factor * sc.ridge_sigma_px if stage == 2 else 1.0,
            ridge_var_px2=var,
            pool_px=opts.guided_pool * opts.thin_factor * sc.ridge_sigma_px,
            corr_px=opts.thin_factor * sc.ridge_sigma_px,
            pool_min_snr=opts.guided_pool_min_snr,
        )
    else:
        cont = identify.gather_contours(
            features,
            scene.camera,
            R,
            t,
            scene.ridges,
            excl,
            tol,
            opts.separation_px,
            ridge_var_px2=var,
            thin_px=opts.thin_factor * sc.ridge_sigma_px if stage == 2 else 0.0,
        )
    clean_contours(cont)
    return cont


def _staged_solve(
    scene: Scene, h: identify.BeadHypothesis, first_stage: int, opts: LabellingOptions
) -> tuple[Labelling, tuple[np.ndarray, np.ndarray] | None]:
    """The stages of :func:`evaluate` up to the per-feature tests: a Labelling (NoLabelling
    saying why none), and the pose its last solve started from where that solve did not
    converge (None where it did)."""
    sc, beads = scene.scales, scene.beads
    R, t = h.R, h.t
    rb = sc.bead_radius_px
    blur = float(np.median(beads.blur)) if len(beads) else sc.blur_px
    sep = sc.touching_px
    out: Labelling | None = None
    start = None
    for stage in (first_stage, 2) if first_stage < 2 and opts.fast else range(first_stage, 3):
        why = implausible(scene, R, t, opts.depth_range)
        if why is not None:
            # before anything is projected: a pose near the source projects the wires over
            # millions of pixels
            raise NoLabelling(why)
        match, dropped_beads = match_beads(
            scene, R, t, beads, opts.match_tol_px if stage else max(opts.match_tol_px, rb), sep
        )
        cont = _contours(scene, R, t, blur, stage, opts.contour)
        obs = observation(scene.camera, {fid: beads.uv[j] for fid, j in match.items()}, cont)
        if not (obs.points or obs.lines or obs.ellipses):
            break
        noise = measured_noise(obs, beads, match, sc.pixel_mm, sc.blur_px, opts.noise)
        try:
            pose = solve_from(scene, obs, noise, R0 := R, t0 := t, opts.max_noise_scale)
        except Exception as exc:  # an unusable observation (e.g. collinear contour): stop here
            raise NoLabelling(f"segmented features unusable: {exc}") from None
        if not np.all(np.isfinite(pose.rotation)):
            break
        R, t = pose.rotation, pose.translation_mm
        start = None if pose.converged else (R0, t0)
        if not pose.converged:
            # the next stage starts where the balls alone put the fiducial, when they agree
            # and the contours gathered at this stage's pose do not: a contour point on the
            # wrong wire had pulled a right hypothesis (ftrac_mini, raw) 36 mm away, where
            # the next stage matched 4 of its 7 balls
            rescued = _balls_alone(scene, obs, noise, R0, t0, opts)
            if rescued is not None:
                R, t = rescued.rotation, rescued.translation_mm
        out = Labelling(pose, obs, noise, match, cont, {**dropped_beads, **cont.dropped})
    if out is None:
        raise NoLabelling("no usable features for this labelling")
    return out, start


def _balls_alone(scene: Scene, obs: Observation, noise: NoiseModel, R, t, opts: LabellingOptions) -> Pose | None:
    """The pose ``obs``'s balls alone give, refined from (R, t), for a stage whose solve with
    its contours did not converge: where three or more balls converge alone, the contours are
    what misled it. None where there are no contours to blame, fewer than three balls, or the
    balls do not converge either."""
    if not (obs.lines or obs.ellipses) or len(obs.points) < 3:
        return None
    balls = Observation(obs.camera, dict(obs.points), {}, {}, obs.origin)
    try:
        p = solve_from(scene, balls, noise, R, t, opts.max_noise_scale)
    except Exception:  # degenerate ball geometry: nothing to rescue with
        return None
    return p if p.converged and np.all(np.isfinite(p.rotation)) else None


def _drop_inconsistent(
    scene: Scene, lab: Labelling, opts: LabellingOptions, start: tuple[np.ndarray, np.ndarray] | None = None
) -> Labelling:
    """Drop the worst feature whose residual is improbable under the noise model and
    re-solve, at most ``max_dropped`` times; the pose fails when more would be needed.

    ``start``: the pose the labelling's last solve started from, where that solve did not
    converge. The features are judged there and the first re-solve starts there: at the pose
    a failed solve wandered to, every feature looks improbable, the culprit no more than the
    rest."""
    removed: dict[str, str] = {}
    obs, noise, pose = lab.obs, lab.noise, lab.pose
    at = pose if start is None or pose.converged else replace(pose, rotation=start[0], translation_mm=start[1])
    for _ in range(opts.max_dropped + 1):
        pv = feature_p_values(scene.features, obs, at, noise)
        worst = min(pv, key=pv.get) if pv else None
        if worst is None or pv[worst] >= opts.feature_p_value:
            break
        if len(removed) >= opts.max_dropped:
            pose = replace(
                pose,
                converged=False,
                error=f"features inconsistent with the pose: {worst} (p = {pv[worst]:.1e}) after dropping "
                f"{', '.join(removed)}; wrong identification or segmentation",
            )
            break
        removed[worst] = f"residual improbable under the measured noise (p = {pv[worst]:.1e})"
        if len(obs.points) + len(obs.lines) + len(obs.ellipses) <= 1:
            pose = replace(
                pose, converged=False, error=f"no feature consistent with the pose ({worst}: p = {pv[worst]:.1e})"
            )
            break
        obs = Observation(
            obs.camera,
            {k: v for k, v in obs.points.items() if k != worst},
            {k: v for k, v in obs.lines.items() if k != worst},
            {k: v for k, v in obs.ellipses.items() if k != worst},
            obs.origin,
        )
        # from the pose the dropped feature had pulled: a local solve (the full no-guess solve
        # here cost ~40 ms per drop, mostly on rival labellings, and changed no pose on 440
        # track_accuracy images: 100 ftrac_2005, 60 ftrac_mini, 60 nine_bead, clean and anatomy)
        pose = at = solve_from(scene, obs, noise, at.rotation, at.translation_mm, opts.max_noise_scale)
    return replace(lab, pose=pose, obs=obs, removed=removed)


def implausible(scene: Scene, R: np.ndarray, t: np.ndarray, depth_range: tuple[float, float]) -> str | None:
    """Why pose (R, t) cannot be the fiducial's (it puts the fiducial's origin outside
    ``depth_range``, fractions of the source-to-detector distance, or a ball behind or at
    the source), or None."""
    lo, hi = depth_range
    f = scene.camera.focal_length_mm
    if not (np.all(np.isfinite(R)) and np.all(np.isfinite(t))):
        return "no finite pose"
    Z = scene.features.point_centers() @ R[2] + t[2] if scene.features.points else np.array([t[2]])
    if not lo * f <= t[2] <= hi * f or np.any(Z <= 0.05 * f):
        return (
            f"implausible pose: the fiducial at {t[2]:.0f} mm from the source (between {lo * f:.0f} and "
            f"{hi * f:.0f} mm expected for a source-to-detector distance of {f:.0f} mm)"
        )
    return None


def evaluate(scene: Scene, h: identify.BeadHypothesis, opts: LabellingOptions, first_stage: int = 0) -> Labelling:
    """Refine one labelling into a pose with every feature it can see: matching and contour
    gathering with wide tolerances (stage 0), tight ones (1), then tight and thinned (2);
    ``first_stage`` = 2 when the hypothesis's pose is already refined. Then the per-feature
    tests, the calibrated covariance and the misfit, with the settings ``opts``
    (:attr:`~.options.TrackOptions.labelling`).

    Returns
    -------
    Labelling (its pose converged or not, with the reason).

    Raises
    ------
    NoLabelling : no pose came of the hypothesis (its ``reason`` says why).
    """
    lab, start = _staged_solve(scene, h, first_stage, opts)
    why = implausible(scene, lab.pose.rotation, lab.pose.translation_mm, opts.depth_range)
    if why is not None:
        raise NoLabelling(why)
    lab = _drop_inconsistent(scene, lab, opts, start)
    vf = calibrated_covariance(scene.features, lab.obs, lab.pose, lab.noise, opts.noise)
    if lab.pose.covariance is not None:
        offset_px = opts.noise.contour_offset_px if scene.features.body is not None else 0.0
        for extra in unmodelled_covariance(
            scene.features, lab.obs, lab.pose, lab.noise, offset_px, opts.noise.distortion_prior_mm
        ):
            if extra is not None:
                lab.pose.covariance = lab.pose.covariance + extra
    lab = replace(lab, variance_factor=vf)
    return replace(lab, score=misfit(scene, lab, opts))


def misfit(scene: Scene, lab: Labelling, opts: LabellingOptions) -> float:
    """A labelling's misfit to the whole image: the χ² of the features it explains plus
    ``unexplained_chi2`` for each feature it predicts in view and clear of others but does
    not explain (a ball with no blob under it, a wire with no ridge, a feature rejected by
    its own χ²). Labellings that use different numbers of features are compared on this,
    not on the feature count or κ alone: a near-mirror labelling of ftrac_mini matched one
    ball more at a worse fit, and "more features" picked it.

    Also sets ``lab.contours.unexplained_beads``: balls in view whose blurred discs touch no
    other's that the labelling leaves without a blob (or rejects), where the image could have
    shown them (no more than half the ball's disc hidden: :meth:`.detection.Scene.hidden_fraction`),
    and each group of touching balls that is bare in every member (:func:`bare_groups`);
    and ``lab.contours.crowded_shown``: balls it does not use within two bead widths of a
    neighbour (in its fit's window), where the image shows a ball all the same.

    A ball the labelling did not use but the image does show where it is predicted (the
    blob detector reads ``bead_present_snr`` noise units or more there: a faint ball under
    a display window, or one a wire pulled off its fit) is charged but not counted as
    unexplained: the charge keeps rival labellings comparable (a near-mirror one puts its
    balls where other balls are, and is shown them too)."""
    features, sc = scene.features, scene.scales
    pose, obs, cont = lab.pose, lab.obs, lab.contours
    if not np.all(np.isfinite(pose.rotation)):
        return math.inf
    prob, ev = residuals_at(features, obs, lab.noise, pose.rotation, pose.translation_mm)
    chi = float(np.sum(ev.rho[0] ** 2))
    uv, _ = (
        identify.project(scene.camera, pose.rotation, pose.translation_mm, features.point_centers())
        if features.points
        else (np.zeros((0, 2)), None)
    )
    m = sc.bead_radius_px + 2
    unexplained, isolated = 0, 0
    # a ball whose blob may be blended with a neighbour's (their discs, blurred, touch) is
    # not counted as clearly unexplained: one further off would show as a blob of its own
    # (ftrac_mini at 40 px, balls 7-11 px apart, each found: a near-mirror labelling 147° off
    # put two balls on bare background there, and a rule of two bead widths let it pass).
    # Within two bead widths of a neighbour its fit may still fail (the neighbour is in its
    # window), and one the image shows there counts for the labelling (``crowded_shown``)
    sep = sc.touching_px
    window = 4 * sc.bead_radius_px + 2
    dd = np.linalg.norm(uv[:, None] - uv[None], axis=-1) + np.eye(len(uv)) * 1e9 if len(uv) else np.zeros((0, 0))
    inside = scene.readable(uv, margin_px=m) if len(uv) else np.zeros(0, bool)
    ev = scene.ball_evidence(uv) if len(uv) else np.zeros(0)
    network = scene.learned_ball(uv) >= LEARNED_BALL if len(uv) else np.zeros(0, bool)
    shown = (ev >= opts.bead_present_snr) | network
    # a ball most of whose disc is clipped could not have shown: a display window that clips
    # dense hardware to black took the balls over it, flanks and all, while the balls beside
    # it kept their readable flanks around a clipped core
    hidden = scene.hidden_fraction(uv, m) > 0.5
    crowded = 0
    for k, p in enumerate(features.points):
        if not inside[k] or p.id in obs.points:
            continue
        # a ball left out for its crowding (dropped, not rejected) is not charged
        crowded += bool(dd[k].min() <= window and shown[k])
        if p.id not in lab.dropped or p.id in lab.removed:
            unexplained += 1
            isolated += bool(dd[k].min() > sep and not shown[k] and not hidden[k])
    if len(uv):
        used = np.array([p.id in obs.points for p in features.points])
        isolated += bare_groups(dd <= sep, inside & ~used & (ev < opts.bare_group_snr) & ~network & ~hidden)
    cont.unexplained_beads, cont.crowded_shown = isolated, crowded
    unexplained += len(set(cont.missing) | {k for k in lab.removed if k not in {p.id for p in features.points}})
    return chi + opts.unexplained_chi2 * unexplained


def bare_groups(touch: np.ndarray, bare: np.ndarray) -> int:
    """How many groups of two or more balls whose blurred discs touch (``touch``: (n, n) bool,
    ball by ball, false on the diagonal; a group is a connected set) are bare in every member
    (``bare``: (n,) bool — in view, not used, and the image shows no ball there, not even a
    faint one, nor hides one: ``LabellingOptions.bare_group_snr``).

    A ball beside another may have no blob of its own (their discs blend into one), so it is
    not counted as unexplained alone; but where the image shows nothing at any ball of the
    group, the group is missing as surely as a ball on its own. ``ftrac_mini`` taken from a
    ``ftrac_2005`` frame (``no_fiducial.py --seed 2128``, another fiducial 117) put two of its
    balls 1.7 px apart on bare background (blob evidence −1.3 and −5.3 noise units) beside one
    isolated ball without a blob, and passed on three balls.
    """
    n = len(bare)
    if n < 2 or not bare.any():
        return 0
    _, label = connected_components(csr_matrix(touch), directed=False)
    sizes = np.bincount(label, minlength=n)
    bare_count = np.bincount(label, weights=bare.astype(float), minlength=n)
    return int(np.sum((sizes >= 2) & (bare_count == sizes)))


def with_agreement(scene: Scene, lab: Labelling, opts: LabellingOptions) -> Labelling:
    """``lab`` with the label-free image agreement (:func:`~.evidence.image_agreement`) added
    to its misfit: ``agreement_chi2_per_px`` per pixel of unexplained ridge and of unsupported
    predicted wire."""
    features, sc = scene.features, scene.scales
    p = lab.pose
    if not np.all(np.isfinite(p.rotation)) or not (features.lines or features.ellipses) or scene.ridges is None:
        return lab
    ux, us = evidence.image_agreement(
        scene,
        p.rotation,
        p.translation_mm,
        scene.bead_exclusion(),
        max(1.5, 0.5 * sc.wire_px + 1.0),
        opts.agreement_min_snr,
    )
    return replace(lab, agreement=(ux, us), score=lab.score + opts.agreement_chi2_per_px * (ux + us))
