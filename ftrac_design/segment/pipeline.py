"""Image → observation → pose, with no initial guess: :func:`track_image`.

Steps, each in its own module: density image and background (:mod:`.image`); bead
candidates fitted with the blurred-sphere model and Steger ridge points (:mod:`.detection`,
:mod:`.beads`, :mod:`.ridges`); bead-labelling hypotheses and contours gathered by each
hypothesis's predicted image (:mod:`.identify`); each labelling refined into a pose with the
image's own measured noise model (:mod:`.labelling`, :mod:`.noise`); the body's projection
subtracted at the best pose (:mod:`.body`); the acceptance tests (:mod:`.acceptance`). The
fiducial is first looked for on a half-size image and tracked in its region
(:mod:`.region`).
"""

from __future__ import annotations

import math
import time
from dataclasses import replace
from typing import Any

import cv2
import numpy as np

from ..features.model import Features
from ..pose import Camera, Diagnostics, so3
from ..threads import beside, one_blas_thread
from . import acceptance, evidence, identify, learned, region
from .beads import Beads
from .body import merge_ridges, refit_beads_at_pose, ridges_without_body
from .conditioning import FORMATIONS, Cleaned, cleaned, condition, formation_of
from .detection import Scene, balls_at, detect, fitted_blur, scales
from .image import NoiseField, detect_polarity
from .labelling import Labelling, NoLabelling, evaluate, with_agreement
from .options import (
    AcceptanceOptions,
    FindOptions,
    LabellingOptions,
    SearchOptions,
    TrackOptions,
    TrackResult,
    ViewPrior,
    failed_result,
)
from .region import fiducial_regions, shifted, view_limited

#: blob triplets the first search over bead labellings tries (:func:`.identify.bead_hypotheses`)
FIRST_TRIPLETS = 24

#: the hypotheses first by their wires at their P3P poses that are ranked again with their
#: poses fitted to all their balls (:func:`ranked_hypotheses`, ``mirror_px``); at most 8 are
#: refined, and the right labelling of a display frame came 7th before this ranking
POLISHED = 32


class Budget:
    """The work one image may cost: searches (a polarity's region, or its whole image) and
    labellings refined, counted; wall-clock seconds only as a safety net.

    What an image is tracked to depends on the counts alone, so the same image gives the
    same answer on a fast machine, a slow one and one busy with other work; the seconds
    (``TrackOptions.time_budget_s``) stop the search only on an image so unusual that its
    counted work takes far longer than any benchmark image's (one of them being under way
    always finishes)."""

    def __init__(self, opts: SearchOptions, start: float | None = None):
        self.work = opts.max_work
        #: bead hypotheses refined per search, and per search whose best pose rests on little
        self.labellings = opts.labellings
        self.labellings_if_weak = max(opts.labellings, opts.labellings_if_weak)
        #: wider searches (:func:`_wider_search`) left: one per image, outside the counted work,
        #: so that the searches after it run as they would have without it
        self.wider_searches = 1
        self.deadline = (time.monotonic() if start is None else start) + opts.time_budget_s
        self.timed_out = False

    def spent(self) -> bool:
        """Whether no further search or labelling may start."""
        return self.work <= 0 or self.late()

    def late(self) -> bool:
        """Whether the wall-clock safety net is reached (the counted work aside)."""
        if time.monotonic() > self.deadline:
            self.timed_out = True
        return self.timed_out

    def charge(self, units: int = 1) -> None:
        """Count ``units`` of work done."""
        self.work -= units


def _rests_on_little(features: Features, labs: list[Labelling]) -> bool:
    """Whether the best converged labelling among ``labs`` (none: no) of a wire design leaves
    two or more of its balls unexplained, or explains fewer than half its wires: a pose a
    near-mirror labelling can give too, so the hypotheses ranked below the first few are worth
    refining.

    A bead-only design never: its poses need all its balls but two anyway, and no wire tells
    a near-mirror labelling apart there; refining more of nine_bead's hypotheses only found
    rivals among subsets of its balls (held-out seed 2044: 3 right poses of 260 refused as
    ambiguous, no wrong one among the old answers)."""
    n_curves = len(features.lines) + len(features.ellipses)
    done = [lab for lab in labs if lab.pose.converged]
    if not done or not n_curves:
        return False
    best = min(done, key=lambda lab: lab.score)
    return len(best.obs.points) < len(features.points) - 1 or _wires_unshown(features, best)


def _wires_unshown(features: Features, best: Labelling) -> bool:
    """Whether ``best``, a wire design's answer, explains fewer than half its wires as
    contours (none: balls alone): the answers that meet the wider search's labellings
    (:func:`_challenged`). The wrong answers that needed it showed no wire contour
    (ftrac_mini, 8 balls) and two of five (ftrac_2005, 6 balls and 2 lines); an answer that
    shows most of its wires but leaves two balls unexplained — half of ftrac_2005's over
    dense anatomy — is not challenged: there the wider search cost ~1 s an image and changed
    no outcome (tuning seeds 21 and 2113, 1,560 images). A bead-only design never."""
    n_curves = len(features.lines) + len(features.ellipses)
    return n_curves > 0 and 2 * (len(best.obs.lines) + len(best.obs.ellipses)) < n_curves


def ranked_hypotheses(
    scene: Scene,
    hyps: list[identify.BeadHypothesis],
    wire_weight: float,
    always: bool = False,
    mirror_px: float = 0.0,
) -> list[identify.BeadHypothesis]:
    """``hyps`` ranked for refining, best first: by ``rank``, the matched ball count plus
    ``wire_weight`` × the ridge evidence along the hypothesis' predicted wires
    (:func:`.evidence.ranking_support`), then as :func:`.identify.bead_hypotheses` ranked
    them (count, then RMS, then the labelling).

    Over dense anatomy or on a display frame a few balls are all the blob detector finds,
    and clutter lines up with five or six balls of hundreds of wrong poses: ranked by count
    alone, a right hypothesis of four balls came 8th to 252nd (tuning seed 21, ftrac_2005),
    never refined. Those wrong poses put wire on bare background, which no pose may do
    (:func:`.acceptance.absent_wires`); the right one's wires show plainly. A bead-only
    design keeps the order by count, and so does a list whose first hypothesis explains every
    ball — unless ``always``: where an answer that explained every ball showed no wire, a
    hypothesis of fewer balls whose wires the image shows must come before it.

    With ``mirror_px`` > 0 the first :data:`POLISHED` are ranked again, each with its wires read
    where all its balls put them (:func:`.identify.polished_poses`) rather than where the P3P
    pose of three of them does — where perspective sets that pose's view at least
    ``mirror_px`` apart from its mirror image (:func:`.region.mirror_signal_px`). Elsewhere the
    balls fit a near-mirror pose as well as the right one, and reading the wires at the fitted
    poses only reshuffled which near-mirror rivals were refined (ftrac_mini, seeds 2135–2136:
    three right poses refused as ambiguous or resting on too little, none gained)."""
    f = scene.features
    full = bool(hyps) and hyps[0].count >= len(f.points) and not always
    if not hyps or not (f.lines or f.ellipses) or wire_weight <= 0 or full:
        # a hypothesis that explains every ball needs no help from the wires to come first
        return hyps
    R, t = np.stack([h.R for h in hyps]), np.stack([h.t for h in hyps])
    ranked = _by_wires(hyps, evidence.ranking_support(scene, R, t, scene.bead_exclusion()), wire_weight)
    first = ranked[:POLISHED]
    if not (mirror_px > 0 and first):
        return ranked
    R, t = identify.polished_poses(scene.camera, f.point_centers(), scene.beads.uv, first)
    for i, h in enumerate(first):
        if not region.mirror_signal_px(f, scene.camera, R[i], t[i]) >= mirror_px:
            R[i], t[i] = h.R, h.t
    return (
        _by_wires(first, evidence.ranking_support(scene, R, t, scene.bead_exclusion()), wire_weight) + ranked[POLISHED:]
    )


def _by_wires(
    hyps: list[identify.BeadHypothesis], support: np.ndarray, wire_weight: float
) -> list[identify.BeadHypothesis]:
    """``hyps`` ranked by their count plus ``wire_weight`` × ``support``, ties in their order."""
    scored = [replace(h, rank=h.count + wire_weight * float(w)) for h, w in zip(hyps, support)]
    order = sorted(range(len(scored)), key=lambda i: (-scored[i].rank, i))
    return [scored[i] for i in order]


def with_predicted_balls(
    scene: Scene, hyps: list[identify.BeadHypothesis], find: FindOptions, accept: AcceptanceOptions
) -> Scene:
    """``scene`` with the balls the hypotheses predict and the search did not keep: a ball
    fitted where a hypothesis puts a model ball that has no blob within the hypotheses'
    tolerance, kept when it is a ball as the search would have kept it
    (:func:`.detection.balls_at`, ``find.bead_min_snr``) and shaped like one
    (:func:`.acceptance.misshapen`). Every hypothesis refined gets them, so a rival gains
    what the right labelling gains; they are appended, so the hypotheses' matches stand. None
    are looked for when the first hypothesis has a blob for every ball."""
    beads = scene.beads
    if not hyps or beads is None or hyps[0].count >= len(scene.features.points):
        return scene
    tol = find.hypothesis_tol_radii * max(scene.scales.bead_radius_px, 2.0)
    centers = scene.features.point_centers()
    uv = identify.project(scene.camera, np.stack([h.R for h in hyps]), np.stack([h.t for h in hyps]), centers)[0]
    uv = uv.reshape(-1, 2)
    uv = uv[scene.readable(uv, margin_px=scene.scales.bead_radius_px)]
    if len(beads) and len(uv):
        uv = uv[np.linalg.norm(uv[:, None] - beads.uv[None], axis=-1).min(1) > tol]
    if not len(uv):
        return scene
    # one start per 2-px cell: the hypotheses that agree on a ball predict it within a pixel or two
    uv = uv[np.unique(np.rint(uv / 2.0), axis=0, return_index=True)[1]]
    found = balls_at(scene, uv, find.bead_min_snr, tol)
    found = found.take(~acceptance.misshapen(found, accept))
    if not len(found):
        return scene
    merged = Beads(*(np.concatenate([getattr(beads, k), getattr(found, k)]) for k in beads.__dataclass_fields__))
    return scene.with_detections(scene.T, merged, scene.ridges)


def _hypotheses(
    scene: Scene,
    find: FindOptions,
    budget: Budget,
    tried: list[identify.BeadHypothesis],
    fewest_balls: int = 0,
    by_wires: bool = False,
    mirror_px: float = 0.0,
    **search,
) -> list[identify.BeadHypothesis]:
    """The bead hypotheses of the scene's blobs (:func:`.identify.bead_hypotheses` with the
    ``search`` settings) that match at least ``fewest_balls`` balls, less the labellings of
    ``tried``, ranked for refining (:func:`ranked_hypotheses`, ``by_wires`` its ``always``,
    ``mirror_px`` its own) and cut to what ``budget`` may refine."""
    hyps = identify.bead_hypotheses(
        scene.features.point_centers(),
        scene.beads.uv,
        scene.camera,
        find.hypothesis_tol_radii * max(scene.scales.bead_radius_px, 2.0),
        keep=None,
        max_extent_px=scene.scales.max_bead_spread_px,
        view=find.view,
        **search,
    )
    seen = {tuple(sorted(h.match.items())) for h in tried}
    hyps = [h for h in hyps if tuple(sorted(h.match.items())) not in seen and h.count >= fewest_balls]
    return ranked_hypotheses(scene, hyps, find.hypothesis_wire_weight, by_wires, mirror_px)[: budget.labellings_if_weak]


def _wider_search(
    scene: Scene,
    tried: list[identify.BeadHypothesis],
    budget: Budget,
    find: FindOptions,
    labelling: LabellingOptions,
    accept: AcceptanceOptions,
    fewest_balls: int = 0,
    labelled: dict[int, int] | None = None,
) -> tuple[Scene, list[Labelling]]:
    """A wider search where no labelling of the first search gave a pose, or where the best
    pose shows fewer than half its wires (:func:`_wires_unshown`, see :func:`_challenged`): the blob triplets
    after the first search's (``find.wide_triplets`` of the ``find.wide_blobs`` strongest
    blobs, with no stop on a labelling that explains all balls but one or two: the first
    search's were refused), and ``find.own_triplets`` triplets of an answer's ``labelled`` blobs
    (blob → model bead index; see :func:`.identify.bead_hypotheses`), their new labellings
    ranked and refined as the first ones were — only those of hypotheses that match at least
    ``fewest_balls`` balls; with ``labelled``, ranked by their wires even where one explains
    every ball (the answer may explain every ball, and its wires did not show). One per image
    (``budget.wider_searches``) and not counted in ``budget``'s work: where an image gave a
    pose without it (in a later region, or the other polarity) it still does. Returns the
    scene with the balls the new hypotheses predict and the labellings refined; none where the
    image had its wider search, the clock's net is reached, or every blob was in the first
    search's triplets. On the learned detector's blobs only: it orders them by its
    ball probability alone, and brachytherapy seeds seen end-on outrank balls there; the
    classical search orders its blobs by their ball fits' shape and size, and a refused image
    already costs its second pass seconds."""
    beads = scene.beads
    if (
        scene.learned is None
        or find.wide_triplets <= 0
        or beads is None
        or len(beads) <= 3
        or budget.wider_searches <= 0
        or budget.late()
    ):
        return scene, []
    budget.wider_searches -= 1
    more = _hypotheses(
        scene,
        find,
        budget,
        tried,
        fewest_balls,
        image_triplets=find.wide_triplets,
        blobs=find.wide_blobs,
        after=FIRST_TRIPLETS,
        patience=None,
        labelled=labelled,
        labelled_triplets=find.own_triplets,
        by_wires=bool(labelled),
        mirror_px=accept.mirror_signal_px,
    )
    if not more:
        return scene, []
    scene = with_predicted_balls(scene, more, find, accept)
    return scene, _labellings(scene, more, budget, labelling, accept, counted=False)


def _judged(
    g: np.ndarray,
    scene: Scene,
    evaluated: list[Labelling],
    challengers: list[Labelling],
    diag: Diagnostics,
    find: FindOptions,
    labelling: LabellingOptions,
    accept: AcceptanceOptions,
) -> tuple[Labelling, Scene]:
    """The answer among the labellings ``evaluated`` on ``scene`` (density image ``g``): the
    least misfit or the one the pixels prefer in a tie (:func:`.acceptance.pixel_preferred`),
    refined again with the body's projection subtracted where that helps
    (:func:`_with_body_subtracted`), then judged with the rest and ``challengers`` as its
    rivals (:func:`accept_best`). Returns it and the scene it was judged on; ``diag`` gets what
    the judging found (anything an earlier judging wrote there is cleared first)."""
    diag.body_subtracted = diag.alternatives = diag.settled_by_pixels = diag.wire_support = None
    evaluated = sorted(evaluated, key=lambda lab: (not lab.pose.converged, lab.score))
    best, others = acceptance.pixel_preferred(scene, evaluated[0], evaluated[1:], accept)
    first, unsubtracted = best, None
    if scene.features.body is not None and best.placed:
        redone = _with_body_subtracted(g, scene, best, labelling, find.ridge_min_snr)
        # kept whenever it converged: refitted with the predicted wires modelled under them,
        # the balls there are the truer evidence (see :func:`_with_body_subtracted`) — but it
        # does not lift a refusal for an ellipse on bare background (:func:`_revives_unshown`)
        if redone is not None and not _revives_unshown(scene, best, redone[0], accept):
            unsubtracted, (best, scene) = scene, redone
            diag.body_subtracted = True
    return accept_best(scene, best, others + challengers, diag, accept, first, unsubtracted), scene


def _revives_unshown(scene: Scene, best: Labelling, redone: Labelling, accept: AcceptanceOptions) -> bool:
    """Whether ``redone``, ``best`` refitted on the image with the body subtracted, would revive
    a labelling refused for putting an ellipse on bare background
    (:func:`.acceptance.no_wire_there`) without a contour of that ellipse found there.

    An ellipse is the design's longest wire: a wrong labelling puts the ellipses on bare
    background (:func:`.acceptance.unshown_curves`), and a wire the image never showed is no
    evidence the subtraction can add. A ftrac_2005 labelling of a round field (tuning seed
    2142, image 195: four balls, one of them a burned-in crosshair's end, 136° off) was
    refused for no wire where it put E1; refitted there it found no contour of E1, yet E1 read
    1.2 noise units on the subtracted image and the pose passed every test, confidently wrong.
    A straight wire is the faintest feature, and the body's limb and blur hide it: the same
    seed's right labelling of a blurred image (9 balls and an ellipse) was refused for L3
    alone and revived without L3's contour, and it is kept."""
    if not str(best.pose.error or "").startswith(acceptance.NO_WIRE_THERE):
        return False
    absent, _ = acceptance.unshown_curves(scene, best.pose, accept)
    ellipses = {c.id for c in scene.features.ellipses}
    return not (set(absent) & ellipses) <= set(redone.obs.ellipses)


def _challenged(
    scene: Scene,
    hyps: list[identify.BeadHypothesis],
    answer: Labelling,
    budget: Budget,
    find: FindOptions,
    labelling: LabellingOptions,
    accept: AcceptanceOptions,
) -> tuple[Scene, list[Labelling], list[Labelling]]:
    """The labellings that meet ``answer``, an answer of the first search's ``hyps`` that
    shows fewer than half its wires (:func:`_wires_unshown`): the wider search's (:func:`_wider_search`) of
    other views, as ``(scene, able, challengers)`` — ``able``, those that converged and stand
    on the acceptance tests' evidence (:func:`.acceptance.too_little_evidence`), join the first
    search's labellings (on the returned scene, with the balls the wider hypotheses predict);
    ``challengers``, the rest, can tie with the answer and refuse it but never be it. Only
    hypotheses that match at least the answer's balls less two are refined (one that explains
    far fewer balls is no rival for it, and refining them all cost a third of ftrac_mini's
    time), and only labellings turned more than :data:`.identify.SAME_POSE_RAD` from the
    answer are kept: one of the answer's own view, a ball traded, is no view the first search
    failed to form, and two such tied with right answers on clean images of the independent
    renderer (0.3–0.4° and 3.0–3.6 mm away).

    The first search stops at a labelling that explains all balls but one or two, and one
    that puts a line's balls on their neighbours' blobs can: ftrac_mini at fluoroscopy dose
    (fresh seed 2116) gave 8 balls and no wire contour 28° and 32 mm off, with one ball's blob
    missed and another fitted 4.6 px off, and the right labelling was never formed; ftrac_2005
    through a round field (held-out seed 2036) gave 6 balls and 2 lines 13° and 40 mm off.
    The wider search formed the right ones (misfit 73 against 233, and 813 against 1,197).
    Its labellings may not simply join the rest: a labelling of three or four balls can fit
    the misfit better than the right one's nine and then be refused for its little evidence,
    losing the image (tuning seed 21, ftrac_2005 under blur and ftrac_mini in log form).

    The answer's own blobs are searched too (``find.own_triplets`` of their triplets), and the
    new hypotheses ranked by their wires even where one explains every ball: among seeds the
    learned detector ranks above the balls, ftrac_mini (fresh seed 2123) was given 17° and
    9 mm off, its line of three on seeds 8.7 px from their own blobs and all nine balls
    explained; six of its blobs were right balls, but no triplet of the strongest blobs held
    three of them. Three of its own give the right labelling — seven balls, as this view lays
    two of the line's on other balls — which fits the image better (misfit 1,001 against
    1,035) and cannot stand alone: a tie, no pose."""
    balls, R = len(answer.obs.points), answer.pose.rotation
    index = {p.id: i for i, p in enumerate(scene.features.points)}
    own = {blob: index[bid] for bid, blob in answer.match.items() if bid in index}
    wide, more = _wider_search(scene, hyps, budget, find, labelling, accept, fewest_balls=balls - 2, labelled=own)
    more = [
        lab
        for lab in _in_view(more, find.view)
        if np.all(np.isfinite(lab.pose.rotation)) and so3.angle(lab.pose.rotation, R) > identify.SAME_POSE_RAD
    ]
    able = [lab for lab in more if lab.pose.converged and acceptance.too_little_evidence(wide, lab, accept) is None]
    return wide, able, [lab for lab in more if not any(lab is x for x in able)]


def _labellings(
    scene: Scene,
    hyps: list[identify.BeadHypothesis],
    budget: Budget,
    labelling: LabellingOptions,
    accept: AcceptanceOptions,
    counted: bool = True,
) -> list[Labelling]:
    """The best distinct labellings refined, each with its agreement with the image (one unit
    of ``budget`` each; none once it is spent, but the first): the first ``budget.labellings``
    hypotheses, and up to ``budget.labellings_if_weak`` while the best pose so far rests on
    little (:func:`_rests_on_little`). Not ``counted``: none is charged to ``budget``, and
    only its clock stops them."""
    out: list[Labelling] = []
    seen: list[tuple[np.ndarray, np.ndarray]] = []
    for i, h in enumerate(hyps[: budget.labellings_if_weak]):
        if i >= budget.labellings and not _rests_on_little(scene.features, out):
            break
        if out and (budget.spent() if counted else budget.late()):
            break
        if h.rank < hyps[0].rank - 2:
            continue
        if counted:
            budget.charge()
        try:
            lab = evaluate(scene, h, labelling)
        except (NoLabelling, ArithmeticError, ValueError, np.linalg.LinAlgError, MemoryError):
            # one labelling that breaks the numerics is one labelling less, not a lost image
            continue
        p = lab.pose
        if any(
            so3.angle(p.rotation, R0) < math.radians(0.5) and np.linalg.norm(p.translation_mm - t0) < 2.0
            for R0, t0 in seen
        ):
            continue
        seen.append((p.rotation, p.translation_mm))
        if p.converged:
            # a labelling that puts wire on bare background is no candidate, and no rival
            lab = replace(lab, pose=acceptance.refuse(p, acceptance.absent_wires(scene, p, accept)))
        out.append(with_agreement(scene, lab, labelling))
    return out


def _in_view(labs: list[Labelling], view: ViewPrior | None) -> list[Labelling]:
    """The labellings whose refined rotation ``view`` admits (all without one): a labelling
    outside it is neither an answer nor a rival to one."""
    if view is None:
        return labs
    return [lab for lab in labs if np.all(np.isfinite(lab.pose.rotation)) and bool(view.admits(lab.pose.rotation))]


def _with_body_subtracted(
    g: np.ndarray, scene: Scene, best: Labelling, labelling: LabellingOptions, ridge_min_snr: float
) -> tuple[Labelling, Scene] | None:
    """The best labelling again, on the image with the body's modelled projection subtracted
    at its pose (:mod:`.body`): the new labelling (``wires_at_first`` saying whether ``best``
    explained a wire contour) and the scene it was found on, or None when that did not help
    (the body cannot be modelled there, or the new pose fails where the old one had converged).

    The subtraction uncovers what the body hid and what its edge spoiled (a ftrac_2005 ellipse
    contour on the body's edge had pulled a pose 3 mm off), and the balls refitted there, with
    the wires the pose predicts modelled under them, are truer than the first fits; so its
    labelling replaces the first even where it explains the same features at a worse misfit
    (tuning seed 21 and fresh seed 2108, 780 images each: ftrac_mini 258 → 274 of 520 right,
    far-but-honest 74 → 55; ftrac_2005 484 → 484, nine_bead 461 → 460, none confidently wrong;
    fresh seed 2111: the same counts within 2, ftrac_2005's depth error 0.74 → 0.64 mm RMS).
    Balls refitted with the wires' pixels masked out instead were no better evidence: kept
    always, they moved ftrac_mini's balls-only poses 2–6 mm in depth, mostly away from the
    truth."""
    blur = float(np.median(scene.beads.blur))
    p0 = best.pose
    inner = ridges_without_body(g, scene, p0, blur, ridge_min_snr)
    if inner is None:
        return None
    merged = merge_ridges(scene.ridges, inner.ridges)
    h2 = identify.BeadHypothesis(p0.rotation, p0.translation_mm, {}, 0, 0.0)
    beads2 = refit_beads_at_pose(scene, inner.T, scene.beads, p0)
    try:
        lab = evaluate(inner.with_detections(inner.T, beads2, merged), h2, labelling, first_stage=2)
    except NoLabelling:
        return None
    # judged on the same ridges as the other labellings; wire contours it finds only here do
    # not confirm it (:attr:`.labelling.Labelling.confirmed_by_wires`)
    lab = replace(with_agreement(scene, lab, labelling), wires_at_first=best.confirmed_by_wires)
    if not (lab.pose.converged or not best.pose.converged):
        return None
    return lab, inner.with_detections(inner.T, beads2, merged if merged is not None else scene.ridges)


def accept_best(
    scene: Scene,
    best: Labelling,
    others: list[Labelling],
    diag: Diagnostics,
    opts: AcceptanceOptions,
    first: Labelling | None = None,
    unsubtracted: Scene | None = None,
) -> Labelling:
    """Run the acceptance tests on the best labelling: the labelling with its pose refused for the
    first reason found, or as it was.

    Parameters
    ----------
    scene : what the image shows (:class:`.detection.Scene`).
    best : the labelling given out, unless refused here.
    others : the rival labellings (a far one that explains the image about as well refuses it).
    diag : the result's diagnostics: gets ``alternatives``, ``settled_by_pixels`` and ``wire_support``.
    opts : what the acceptance tests read (:attr:`~.options.TrackOptions.acceptance`).
    first : ``best`` as it was before the body's projection was subtracted at its pose, when
        it was: the rivals are judged against it too, on the same image as they were refined
        on. Only ``best`` had the subtraction, which found it more balls; a rival that had
        tied with it would have gained as much at its own pose (ftrac_mini, a corrected
        pincushion of the tuning seed: a labelling 180° off won by 4 χ², then the subtraction
        found it two balls more and it passed).
    unsubtracted : the scene before the body's subtraction, when ``scene`` is after it: a
        wire either image shows is there. The modelled body's limb, subtracted a little too
        strongly, took the ridge of a straight wire lying along it (ftrac_2005 under 2 px of
        blur: 3.4 noise units before, −0.2 after, at the true pose).

    Returns
    -------
    Labelling : ``best``, its pose refused (``converged`` false, the reason as its error) or not.
    """
    pose = best.pose
    if pose.converged:
        settled = []
        for other in others:
            r = acceptance.rival(scene, best, other, opts)
            if r is None and first is not None and first is not best:
                r = acceptance.rival(scene, first, other, opts)
            won = None if r is None else acceptance.settled_by_pixels(scene, best, other, others, opts)
            if won is not None:
                settled.append(won)
                continue
            if r is not None:
                diag.alternatives = r[1]
                pose = acceptance.refuse(pose, r[0])
                break
        diag.settled_by_pixels = settled if settled and pose.converged else None
    if pose.converged:
        absent, support = acceptance.unshown_curves(scene, pose, opts, also=unsubtracted)
        diag.wire_support = support
        pose = acceptance.refuse(pose, acceptance.no_wire_there(absent))
    if pose.converged:
        pose = acceptance.refuse(pose, acceptance.too_little_evidence(scene, best, opts))
    if pose.converged:
        pose = acceptance.refuse(pose, acceptance.misshapen_balls(scene, best, opts))
    if pose.converged:
        pose = acceptance.refuse(pose, acceptance.small_balls(scene, best, opts))
    if pose.converged:
        pose = acceptance.refuse(pose, acceptance.stray_balls(scene, best, opts))
    if pose.converged:
        pose = acceptance.refuse(pose, acceptance.displaced_balls(scene, best, opts))
    if pose.converged:
        pose = acceptance.refuse(pose, acceptance.uncontrolled(scene, best, opts))
    if pose.converged:
        pose = acceptance.refuse(pose, acceptance.undetermined(scene, best))
    return best if pose is best.pose else replace(best, pose=pose)


def feature_quality(scene: Scene, best: Labelling) -> dict[str, Any]:
    """Per-feature quality of what the pose used: bead fit σ (px), radius (px), blur (px) and
    SNR; each contour point's SNR.

    Parameters
    ----------
    scene : what the image shows.
    best : the labelling given out.

    Returns
    -------
    dict : ``{"points": {id: {...}}, "lines": {id: {"snr": [...]}}, "ellipses": {...}}``.
    """
    beads, obs, cont = scene.beads, best.obs, best.contours
    quality: dict[str, Any] = {"points": {}, "lines": {}, "ellipses": {}}
    for fid, j in best.match.items():
        if fid in obs.points:
            quality["points"][fid] = {
                "sigma_px": float(beads.sigma_px[j]),
                "radius_px": float(beads.radius[j]),
                "blur_px": float(beads.blur[j]),
                "snr": float(beads.response[j]),
            }
    for store, name in ((obs.lines, "lines"), (obs.ellipses, "ellipses")):
        for fid, c in store.items():
            quality[name][fid] = {"snr": [round(float(x), 1) for x in cont.snr.get(fid, [])][: len(c.points)]}
    return quality


def _track_density(
    g: np.ndarray,
    features: Features,
    camera: Camera,
    find: FindOptions,
    labelling: LabellingOptions,
    accept: AcceptanceOptions,
    pol: str,
    valid: np.ndarray | None,
    noise: NoiseField,
    budget: Budget,
    det=None,
    hidden: np.ndarray | None = None,
    censored: np.ndarray | None = None,
) -> TrackResult:
    """:func:`track_image` on a density image (dense = bright) seen with ``camera``, readable
    where ``valid``, with local noise ``noise``; ``det`` the learned detector's detections in
    ``g``'s pixels, or None for the classical path; ``hidden`` where its pixels show nothing
    and ``censored`` where they are clipped on the dense side
    (:class:`.conditioning.Conditioned`)."""
    budget.charge()
    scene = detect(g, features, camera, find, valid, noise, det, hidden, censored)
    blur = fitted_blur(scene)
    if blur is not None and blur > max(find.blur_px * find.blur_redetect, 1.1):
        # a blurrier image than the filters are sized for: detected again at its own blur
        find = replace(find, blur_px=blur)
        scene = detect(g, features, camera, find, valid, noise, det, hidden, censored)
    beads, ridges = scene.beads, scene.ridges
    diag = Diagnostics(blobs=0 if beads is None else len(beads), ridge_points=0 if ridges is None else len(ridges))
    if not features.points:
        return failed_result("identification needs beads; this design has none", pol, beads, ridges, diag)
    if beads is None or len(beads) < 3:
        return failed_result(
            f"no fiducial found: {0 if beads is None else len(beads)} bead-like blobs "
            f"(need at least 3 of {len(features.points)})",
            pol,
            beads,
            ridges,
            diag,
        )
    hyps = _hypotheses(scene, find, budget, [], mirror_px=accept.mirror_signal_px, image_triplets=FIRST_TRIPLETS)
    scene = with_predicted_balls(scene, hyps, find, accept)
    within = "" if find.view is None else f" within {math.degrees(find.view.within_rad):.0f}° of the expected view"
    if not hyps:
        return failed_result(
            f"no fiducial found: {len(beads)} blobs, none matching the bead layout{within}", pol, beads, ridges, diag
        )
    evaluated = _in_view(_labellings(scene, hyps, budget, labelling, accept), find.view)
    if not any(lab.pose.converged for lab in evaluated):
        scene, more = _wider_search(scene, hyps, budget, find, labelling, accept)
        evaluated += _in_view(more, find.view)
    if not evaluated:
        return failed_result(f"no bead labelling{within} led to a pose", pol, beads, ridges, diag)
    best, judged = _judged(g, scene, evaluated, [], diag, find, labelling, accept)
    if best.pose.converged and _wires_unshown(features, best):
        # an answer its wires do not confirm meets the labellings the first search never formed
        wide, able, challengers = _challenged(scene, hyps, best, budget, find, labelling, accept)
        if able or challengers:
            evaluated += able
            best, judged = _judged(g, wide if able else scene, evaluated, challengers, diag, find, labelling, accept)
    scene = judged
    diag.blur_px, diag.hypotheses, diag.labellings_tested = scene.scales.blur_px, len(hyps), len(evaluated)
    # the residuals' own scale relative to the noise model (the covariance uses it)
    diag.labelled(len(best.obs.points), best.dropped, best.removed, scene.pixel_noise, best.variance_factor)
    return TrackResult(
        best.pose,
        best.obs,
        feature_quality(scene, best),
        scene.beads,
        scene.ridges,
        pol,
        best.noise,
        diag,
        noise_levels=noise.levels(scene.scales.ridge_sigma_px),
    )


def track_image(
    image: np.ndarray,
    features: Features,
    camera: Camera,
    options: TrackOptions | None = None,
    polarity_hint: str | None = None,
    formation_hint: str | None = None,
) -> TrackResult:
    """Segment, identify and solve one image with no initial guess.

    Parameters
    ----------
    image : (H, W) pixels as stored (raw counts, a log image or a display frame).
    features : the design's features (mm, frame F); where they carry the body
        (``features.body``), the ridges are found again on the image with the body's modelled
        projection subtracted (:mod:`.body`).
    camera : the image's intrinsics (SPEC §1).
    options : the image path's settings (default :class:`TrackOptions`).
    polarity_hint : "dense-dark" / "dense-bright" (or "dense_dark" / "dense_bright") when the
        file says how dense matter looks; with ``TrackOptions.polarity`` "auto" and no hint,
        the more likely polarity is tried first and the other when the first finds no pose.
    formation_hint : "linear", "log" or "display" when the file says (see
        :mod:`.conditioning`); else found from the pixels.

    Returns
    -------
    TrackResult. Never raises for an image: where the fiducial cannot be found, or the
    numerics fail on what the image shows, the pose has ``converged = False`` and the reason.
    """
    try:
        with one_blas_thread():
            return _track(image, features, camera, options, polarity_hint, formation_hint)
    except (ArithmeticError, ValueError, np.linalg.LinAlgError, MemoryError, cv2.error) as exc:
        return failed_result(f"tracking failed on this image: {type(exc).__name__}: {' '.join(str(exc).split())}")


def _polarities(
    polarity: str,
    hint: str | None,
    small: np.ndarray,
    sc,
    form: str,
    img: np.ndarray,
    det,
    balls: int,
) -> list[str]:
    """The polarities to try, in order: the one asked for or the file's; else both — linear
    counts (integers beyond 8 bits) dense-dark first and a log image (non-integer values)
    dense-bright first, as detectors and log converters write them; a display frame's in the
    polarity in which compact structures stand out more first (:func:`.image.detect_polarity`:
    over a patient it picked a raw image's polarity wrongly in 7 of 20)."""
    known = _known_polarities(polarity, hint, form)
    if known is not None:
        return known
    if det is not None:
        # the learned detector's balls, darker or brighter than around them
        order = learned.polarity_order(img, det, sc, balls)
        if order is not None:
            return order
    first = detect_polarity(small, max(sc.disc_px // 2, 2))
    return [first, "dense-bright" if first == "dense-dark" else "dense-dark"]


def _known_polarities(polarity: str, hint: str | None, form: str) -> list[str] | None:
    """The polarities to try where neither the learned detector's balls nor the pixels' own
    polarity test decide them: the one asked for or the file's, else linear counts
    dense-dark first and a log image dense-bright first; None for a display frame."""
    if polarity != "auto":
        return [polarity]
    pol = str(hint or "").replace("_", "-")
    if pol in ("dense-dark", "dense-bright"):
        return [pol]
    if form == "linear":
        return ["dense-dark", "dense-bright"]
    if form == "log":
        return ["dense-bright", "dense-dark"]
    return None


def _line_integrals(img: np.ndarray) -> bool:
    """Whether the pixels look like a log image's line integrals rather than counts: not
    integers, and none above 64 (a line integral of 64 is e⁻⁶⁴ of the beam); counts, even
    resampled ones, run to hundreds or thousands."""
    a = img[:: max(1, img.shape[0] // 64)]
    return bool(float(np.max(np.abs(a))) <= 64.0 and not np.all(a == np.round(a)))


def _blank(img: np.ndarray) -> bool:
    """Whether every finite pixel of ``img`` has the same value (or none is finite)."""
    finite = np.isfinite(img)
    vals = img if finite.all() else img[finite]
    return vals.size == 0 or float(vals.min()) == float(vals.max())


def _track(
    image: np.ndarray,
    features: Features,
    camera: Camera,
    options: TrackOptions | None,
    polarity_hint: str | None,
    formation_hint: str | None,
) -> TrackResult:
    opts = options or TrackOptions()
    find = opts.finding
    img = np.asarray(image)
    if img.dtype != np.float32:
        img = img.astype(np.float32)
    if _blank(img):
        # a frame grabber's frames between exposures: nothing to find, and both detectors'
        # searches over both polarities found that in ~0.3 s each
        return failed_result("no fiducial found: the image is blank (every readable pixel has the same value)")
    sc = scales(features, camera, find)
    # everything first on a half-size image: polarity, and where the fiducial may be
    small = (
        cv2.resize(img, (img.shape[1] // 2, img.shape[0] // 2), interpolation=cv2.INTER_AREA)
        if min(img.shape) >= 64
        else img
    )
    # the formation is a property of the pixels (their range and type), not of the polarity
    # tried: 8-bit integers are a display frame either way
    form = formation_hint if formation_hint in FORMATIONS else formation_of(image, "dense-dark", None)
    if form == "linear" and formation_hint not in FORMATIONS and _line_integrals(img):
        form = "log"
    prepared: Prepared = {}
    clean, det = _prepared_and_detected(img, form, polarity_hint, features, sc, opts, prepared)
    args = (img, clean, small, form, polarity_hint, features, camera, sc, opts, prepared)
    res = _balls_read(_each_polarity(*args, det), det, features)
    if det is None or res.pose.converged or find.detector != "auto":
        return res
    # the network and the classical detectors miss different images (on display frames of the
    # tuning seed each found some the other refused); the classical search gets its own
    # budget and the same acceptance tests, so a second look adds recall, not a looser gate
    other = _balls_read(_each_polarity(*args, None), det, features)
    tried = ["learned", "classical"]
    other.diagnostics.detector_tried = tried
    if other.pose.converged and res.diagnostics.alternatives:
        # an ambiguity the network's pass found stands: the classical search may score the
        # tie apart on its own blobs, but the image has shown both answers
        other.pose = acceptance.refuse(other.pose, acceptance.among_rivals(other.pose, res.diagnostics.alternatives))
        if not other.pose.converged:
            other.diagnostics.alternatives = res.diagnostics.alternatives
    if other.pose.converged:
        return other
    res.pose = replace(res.pose, error=f"{res.pose.error}; with the classical detectors: {other.pose.error}")
    res.diagnostics.detector_tried = tried
    return res


def _balls_read(res: TrackResult, det, features: Features) -> TrackResult:
    """``res``, refused where a bead-only design's pose rests on balls the learned detector
    ``det`` reads none of (:func:`.acceptance.unseen_balls`), whichever detector's pass gave it.
    Balls alone confirm such a pose, and blobs where anatomy's edges cross are shaped like
    balls: the network's own pass fitted nine_bead's helix to seven blobs of a frame with no
    fiducial at all, each read 0.01–0.21 (``no_fiducial.py --seed 2109``, anatomy 60; its
    depth σ 108 mm). A wire design's pose is confirmed by its wires, and where the network
    sees no ball at all the classical detectors stand in for it."""
    bead_only = not (features.lines or features.ellipses)
    if det is None or not bead_only or not res.pose.converged or res.observation is None:
        return res
    if res.observation.points:
        uv = np.array(list(res.observation.points.values()), float)
        res.pose = acceptance.refuse(res.pose, acceptance.unseen_balls(det.ball_probability(uv)))
    return res


#: the conditioned image and its noise field by polarity, made once per image and shared by
#: the learned and the classical detectors' passes
Prepared = dict[str, tuple[Any, NoiseField]]


def _prepared(img: np.ndarray, clean: Cleaned, form: str, pol: str, sc, prepared: Prepared):
    """``img`` conditioned in polarity ``pol`` (linear counts read dense-bright are line
    integrals) and its noise field, from ``prepared`` or made and kept there."""
    if pol not in prepared:
        cond = condition(img, pol, form if form != "linear" or pol == "dense-dark" else "log", sc.disc_px, clean=clean)
        prepared[pol] = (cond, NoiseField(cond.density, cond.valid, sc.disc_px))
    return prepared[pol]


def _prepared_and_detected(
    img: np.ndarray, form: str, hint: str | None, features: Features, sc, opts: TrackOptions, prepared: Prepared
) -> tuple[Cleaned, Any]:
    """The image cleaned (:func:`.conditioning.cleaned`: what neither polarity nor detector
    changes — the clipped regions, a display frame's graphics filled in — done once for every
    try) and the learned detector's detections (:func:`.learned.detections`; None for the
    classical path or a design without balls). The network runs on a thread of its own while
    this one cleans the image and, where the first polarity to try does not wait for the
    detections (counts, log images, a file's or the caller's polarity), conditions it in that
    polarity and measures its noise at the ridge scale into ``prepared``: the network and
    OpenCV's filters let go of the interpreter, so on a second core the cleaning (1–10 ms for
    1024² counts, 57–89 ms for a display frame's graphics) and the noise map (~20 ms) cost no wall
    time. The same work is done either way, so the answers do not change."""
    if opts.finding.detector_threads <= 1:
        # one thread: a process among as many workers as cores (the same answers)
        det = learned.detections(img, sc, opts.finding) if features.points else None
        return cleaned(img, form == "display", sc.disc_px), det
    det = beside(learned.detections, img, sc, opts.finding) if features.points else None
    try:
        clean = cleaned(img, form == "display", sc.disc_px)
        known = _known_polarities(opts.search.polarity, hint, form)
        if det is not None and known is not None and opts.finding.detector != "classical":
            _prepared(img, clean, form, known[0], sc, prepared)[1].at(sc.ridge_sigma_px)
    finally:
        found = None if det is None else det.result()
    return clean, found


def _each_polarity(
    img: np.ndarray,
    clean: Cleaned,
    small: np.ndarray,
    form: str,
    polarity_hint: str | None,
    features: Features,
    camera: Camera,
    sc,
    opts: TrackOptions,
    prepared: Prepared,
    det,
) -> TrackResult:
    """The image tracked in each polarity to try until one gives a pose, with the learned
    detector's detections ``det`` (None: the classical detectors), under one counted budget;
    ``clean`` is ``img`` cleaned (:func:`.conditioning.cleaned`); each polarity's conditioned
    image and noise taken from ``prepared`` or kept there."""
    find, search = opts.finding, opts.search
    budget = Budget(search)
    tried: list[TrackResult] = []
    stages = (find, search, opts.labelling, opts.acceptance)
    pols = _polarities(search.polarity, polarity_hint, small, sc, form, img, det, len(features.points))
    for pol in pols:
        if tried and budget.spent():
            break
        cond, noise = _prepared(img, clean, form, pol, sc, prepared)
        res = _track_conditioned(cond, noise, small, features, camera, sc, budget, det, *stages)
        diag = res.diagnostics
        diag.detector = "classical" if det is None else "learned"
        diag.formation = cond.formation
        diag.work = search.max_work - budget.work
        if budget.timed_out:
            diag.time_budget_spent = True
        if res.pose.converged:
            if tried:
                diag.polarity_tried = [t.polarity for t in tried] + [pol]
            return res
        tried.append(res)
    if len(tried) > 1:
        first = tried[0]
        why = f"{first.pose.error} (as {first.polarity}; as {tried[1].polarity}: {tried[1].pose.error})"
        first.pose = replace(first.pose, error=why)
        first.diagnostics.polarity_tried = [t.polarity for t in tried]
    return tried[0]


def _classical_regions(
    img, valid, small: np.ndarray, noise: NoiseField, features, sc, find: FindOptions, search: SearchOptions
) -> list:
    """The classical guess of where the fiducial may be (:func:`.region.fiducial_regions`), on
    the half-size image when its balls survive halving, else at full size."""
    if small.shape == img.shape or not search.roi:
        return []
    if sc.bead_radius_px / 2 >= search.min_region_bead_px:
        vs = (
            None
            if valid is None
            else cv2.resize(
                valid.astype(np.uint8), (small.shape[1], small.shape[0]), interpolation=cv2.INTER_NEAREST
            ).astype(bool)
        )
        gs = cv2.resize(img, (small.shape[1], small.shape[0]), interpolation=cv2.INTER_AREA)
        return fiducial_regions(gs, features, sc, find, vs, search.max_regions)
    # balls too small to survive halving (ftrac_mini's 1 mm: 0.85 px): looked for at full size
    return fiducial_regions(
        img, features, sc, find, valid, search.max_regions, factor=1, noise=noise.at(sc.ridge_sigma_px)
    )


def _progress(res: TrackResult) -> tuple[bool, bool, int, int]:
    """How far a refused search of one region got, to choose the refusal an image is given:
    two answers (an ambiguity, whose poses a user with a prior can choose between and which
    the classical second look must not undercut), then a labelling refined to a pose, then the
    balls it used, then the blobs found. The first region is not always the one: behind
    collimator blades the network's likeliest cluster lay where the conditioned image had no
    readable pixel, and the fiducial's region after it was refused as ambiguous (nine_bead,
    fresh seed 2108, blades 10: the image was given "0 bead-like blobs")."""
    d = res.diagnostics
    return (d.alternatives is not None, (d.labellings_tested or 0) > 0, d.beads_matched or 0, d.blobs or 0)


def _track_conditioned(
    cond,
    noise: NoiseField,
    small: np.ndarray,
    features: Features,
    camera: Camera,
    sc,
    budget: Budget,
    det,
    find: FindOptions,
    search: SearchOptions,
    labelling: LabellingOptions,
    accept: AcceptanceOptions,
) -> TrackResult:
    """:func:`track_image` on a conditioned image ``cond`` with its noise field ``noise``: in
    each region where the fiducial may be (most likely first) until one gives a pose; the
    whole image when none is found. With the
    learned detector's detections ``det``, its regions and ball candidates, and no whole-image
    search: where it sees no cluster of balls there is no fiducial to find."""
    img, valid, pol = cond.density, cond.valid, cond.polarity
    if det is not None:
        regions = learned.regions(det, features, sc, img.shape, find.magnification, search.max_regions)
        if not regions:
            return failed_result(
                f"no fiducial found: the learned detector saw {len(det.beads_uv)} ball candidates, "
                "no cluster of three that could be the fiducial's",
                pol,
            )
    else:
        regions = _classical_regions(img, valid, small, noise, features, sc, find, search)
    told: TrackResult | None = None
    for r0, r1, c0, c1 in regions:
        if told is not None and budget.spent():
            return told
        crop_cam = replace(
            camera, principal_point_px=(camera.principal_point_px[0] - c0, camera.principal_point_px[1] - r0)
        )
        res = _track_density(
            img[r0:r1, c0:c1],
            features,
            crop_cam,
            find,
            labelling,
            accept,
            pol,
            None if valid is None else valid[r0:r1, c0:c1],
            noise.crop(r0, r1, c0, c1),
            budget,
            None if det is None else det.crop(r0, c0),
            None if cond.hidden is None else cond.hidden[r0:r1, c0:c1],
            None if cond.censored is None else cond.censored[r0:r1, c0:c1],
        )
        res = shifted(res, camera, c0, r0)
        res.diagnostics.roi = [int(c0), int(r0), int(c1 - c0), int(r1 - r0)]
        if res.pose.converged or view_limited(res, features, camera, img.shape, sc, accept):
            return res
        told = res if told is None or _progress(res) > _progress(told) else told
    if regions:
        # the regions looked at gave nothing: the answer of the one that got furthest, unless a
        # whole-image search is cheap enough to be worth it (a small image)
        if det is not None or img.size > search.whole_image_px or budget.spent():
            return told
    return _track_density(
        img, features, camera, find, labelling, accept, pol, valid, noise, budget, None, cond.hidden, cond.censored
    )
