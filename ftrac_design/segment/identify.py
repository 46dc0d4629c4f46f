"""Which detected blob is which bead, which ridge points belong to which wire.

Identification is hypothesis testing with the fiducial's own geometry, the same for every
design: each labelling hypothesis is a pose, and a pose predicts the whole image.

1. **Bead hypotheses** (RANSAC over triplets, exhaustive over the model): three detected
   blobs spread over the image are matched with every ordered, non-collinear triplet of
   model beads; P3P (:mod:`ftrac_design.pose.p3p`, all model triplets at once) gives up to four poses for each; every
   pose projects all the model beads, and a hypothesis scores the number of beads that
   land on a distinct detected blob. Line designs need no special case (their 4/3/2 beads
   per line make the labelling unique), and free-bead designs such as ``nine_bead`` work
   the same way. A few image triplets are tried, strongest blobs first.
2. **Contours by prediction**: a pose projects each wire piece and each ellipse; ridge
   points within a tolerance of exactly one projected curve, with a normal that agrees,
   away from every bead and from every other curve, are that curve's contour points.
   Where two features project onto one another (two lines on one image line, a bead on
   another wire, two beads merged into one blob) the points cannot be told apart, so they
   are left out and the pose is solved from the rest.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from scipy.spatial import cKDTree

from ..features.model import Features
from ..pose import Camera, so3
from ..pose.p3p import bearings, p3p
from ..pose.smallmat import spd_solve
from .ridges import RidgePoints

if TYPE_CHECKING:
    from .options import ViewPrior


def outward_shift(pts: np.ndarray, var_px2: float) -> np.ndarray:
    """The outward displacement σ²κ/2 of a blurred curved wire's ridge peak from its centre-line.

    Parameters
    ----------
    pts : (n, 2) ndarray
        Samples of a closed curve in the image (px), in order.
    var_px2 : float
        The ridge filter's and the image's blur variance σ² (px²).

    Returns
    -------
    (n, 2) ndarray
        Per sample, the displacement (px) away from the centre of curvature; κ from the
        samples 4 apart (the chord's sagitta); 0 where the curve is straight.
    """
    a, b = np.roll(pts, 4, 0), np.roll(pts, -4, 0)
    sag = pts - 0.5 * (a + b)
    half = 0.5 * np.linalg.norm(b - a, axis=1)
    sl = np.linalg.norm(sag, axis=1)
    with np.errstate(all="ignore"):
        kappa = 2 * sl / (sl * sl + half * half)
        outward = sag / sl[:, None]
    shift = np.where(np.isfinite(kappa), 0.5 * var_px2 * kappa, 0.0)
    return np.where(np.isfinite(outward), outward, 0.0) * shift[:, None]


#: poses of one bead labelling closer than this (rad) are one hypothesis; P3P's two
#: solutions of a near-affine view lie tens of degrees apart, its noise a degree or two
SAME_POSE_RAD = math.radians(10.0)


@dataclass
class BeadHypothesis:
    """A pose F → X from a bead labelling: ``match`` maps model bead index → detected blob
    index; ``count`` beads matched; ``rms_px`` their reprojection RMS; ``rank`` what orders
    the hypotheses for refining: the count (when not given), and what the image shows of the
    pose's wires once :func:`.pipeline.ranked_hypotheses` has looked."""

    R: np.ndarray
    t: np.ndarray
    match: dict[int, int]
    count: int
    rms_px: float
    rank: float | None = None

    def __post_init__(self) -> None:
        if self.rank is None:
            self.rank = float(self.count)


def project(camera: Camera, R: np.ndarray, t: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pixels (..., n, 2) and depths (..., n) of model points P (n, 3) at poses R (..., 3, 3), t (..., 3)."""
    X = np.einsum("...ij,nj->...ni", R, P) + t[..., None, :]
    Z = X[..., 2]
    with np.errstate(all="ignore"):
        uv = np.stack(
            [
                camera.fx * X[..., 0] / Z + camera.principal_point_px[0],
                camera.fy * X[..., 1] / Z + camera.principal_point_px[1],
            ],
            -1,
        )
    return uv, Z


def _image_triplets(
    uv: np.ndarray, limit: int, max_extent_px: float = np.inf, k: int = 12, skip: frozenset = frozenset()
) -> list[tuple[int, int, int]]:
    """Up to ``limit`` triplets of the ``k`` strongest blobs (``uv`` strongest first) that
    could all be balls of one fiducial: no side longer than ``max_extent_px`` and not
    nearly collinear; the strongest blobs first (the sum of their ranks), then the larger
    triangle; none of ``skip`` (triplets tried before). Over anatomy or on a display frame a
    few clutter blobs rank among the balls; the largest triangles of the first eight (the
    earlier rule) all held the one far away."""
    k = min(len(uv), k)
    tri = []
    for a, b, c in itertools.combinations(range(k), 3):
        e1, e2, e3 = uv[b] - uv[a], uv[c] - uv[a], uv[c] - uv[b]
        side = max(float(np.hypot(*e1)), float(np.hypot(*e2)), float(np.hypot(*e3)))
        area = abs(e1[0] * e2[1] - e1[1] * e2[0]) / 2
        if side > max_extent_px or not area > 0.05 * side * side or (a, b, c) in skip:
            continue
        tri.append((a + b + c, -area, (a, b, c)))
    tri.sort()
    return [abc for _, _, abc in tri[:limit]]


def _model_triplets(P: np.ndarray) -> np.ndarray:
    """Ordered triplets (m, 3) of model beads that are not (nearly) collinear."""
    n = len(P)
    trip = np.array(list(itertools.permutations(range(n), 3)), int).reshape(-1, 3)
    if len(trip) == 0:
        return trip
    a, b, c = P[trip[:, 0]], P[trip[:, 1]], P[trip[:, 2]]
    area = np.linalg.norm(np.cross(b - a, c - a), axis=1)
    scale = max(float(np.ptp(P, axis=0).max()), 1e-9)
    return trip[area > 0.02 * scale * scale]


def _p3p_poses(objs: np.ndarray, img: np.ndarray, K: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """Every P3P pose (R (k, 3, 3), t (k, 3)) of the model triplets ``objs`` (m, 3, 3) seen at
    the image triplet ``img`` (3, 2) px (:func:`ftrac_design.pose.p3p.p3p`), or None."""
    R, t, _ = p3p(objs, bearings(img, K))
    return (R, t) if len(R) else None


def _admitted(
    poses: tuple[np.ndarray, np.ndarray] | None, view: ViewPrior | None
) -> tuple[np.ndarray, np.ndarray] | None:
    """The poses (R, t) that ``view`` admits within :data:`SAME_POSE_RAD` (all without one),
    or None for none."""
    if poses is None or view is None:
        return poses
    ok = view.admits(poses[0], SAME_POSE_RAD)
    return (poses[0][ok], poses[1][ok]) if ok.any() else None


def _triplets_among(
    uv: np.ndarray, among: tuple[int, ...], limit: int, max_extent_px: float
) -> list[tuple[int, int, int]]:
    """Up to ``limit`` triplets of the blobs ``among`` (indices into ``uv``) that pass
    :func:`_image_triplets`' shape tests, the largest triangles first (the best-conditioned
    P3P), as indices into ``uv``."""
    idx = np.array(sorted({b for b in among if 0 <= b < len(uv)}), int)
    if len(idx) < 3:
        return []
    sub = _image_triplets(uv[idx], math.comb(len(idx), 3), max_extent_px, k=len(idx))
    e1 = np.array([uv[idx[b]] - uv[idx[a]] for a, b, _ in sub]).reshape(-1, 2)
    e2 = np.array([uv[idx[c]] - uv[idx[a]] for a, _, c in sub]).reshape(-1, 2)
    area = np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    order = sorted(range(len(sub)), key=lambda i: (-area[i], sub[i]))[:limit]
    return [tuple(int(idx[i]) for i in sub[j]) for j in order]


def _one_relabelled(labels: tuple[int, int, int], allowed: np.ndarray) -> np.ndarray:
    """The rows of ``allowed`` (model triplets, (m, 3): :func:`_model_triplets`) that keep at
    least two of ``labels`` in place: the labelling itself and every one with any other bead
    in one place."""
    allowed = np.asarray(allowed, int).reshape(-1, 3)
    return allowed[(allowed == np.asarray(labels, int)).sum(1) >= 2]


def _relabelled_poses(
    model: np.ndarray,
    uv: np.ndarray,
    K: np.ndarray,
    labelled: dict[int, int],
    limit: int,
    max_extent_px: float,
    mtri: np.ndarray,
    view: ViewPrior | None = None,
) -> tuple[np.ndarray, np.ndarray] | None:
    """The P3P poses (R (k, 3, 3), t (k, 3)) of up to ``limit`` triplets of ``labelled``'s
    blobs (blob index into ``uv`` → model bead index; :func:`_triplets_among`), each matched
    with the model triplets of ``mtri`` that keep two of its labels (:func:`_one_relabelled`),
    all solved at once, that ``view`` admits (:func:`_admitted`); None for none.

    ``labelled`` is an answer its wires did not confirm: most of its balls may be right and
    the rest on clutter that outranks the other balls, so that no triplet of the strongest
    blobs holds three right ones; and a right ball's blob may be two balls' in this view (the
    answer gave it one of them), whence the third label left free."""
    objs, rays = [], []
    for itri in _triplets_among(uv, tuple(labelled), limit, max_extent_px):
        rows = _one_relabelled(tuple(labelled[i] for i in itri), mtri)
        if len(rows):
            objs.append(model[rows])
            rays.append(np.broadcast_to(bearings(uv[list(itri)], K), (len(rows), 3, 3)))
    if not objs:
        return None
    R, t, _ = p3p(np.concatenate(objs), np.concatenate(rays))
    return _admitted((R, t), view) if len(R) else None


class _BlobLookup:
    """Blobs ``uv`` (n, 2) px for many nearest-blob look-ups within ``tol_px``: a k-d tree, and
    a raster of the pixels within ``tol_px`` + 1 px of a blob, so that only the points that can
    have a blob that near are looked up in the tree (most balls a bead search projects fall
    nowhere near one: their pose came from a wrong model triplet). A point within ``tol_px``
    of a blob rounds to a pixel within ``tol_px`` + √2/2 of it, so none is missed; the others'
    answer is the tree's for a point with no blob within reach (∞, n)."""

    #: the raster is left out (every point looked up) above this many pixels
    MAX_RASTER_PX = 1 << 22

    def __init__(self, uv: np.ndarray, tol_px: float):
        self.tree, self.n, self.tol = cKDTree(uv), len(uv), float(tol_px)
        reach = self.tol + 1.0
        r = int(math.ceil(reach))
        self.lo = np.floor(uv.min(0)).astype(int) - r - 1
        hi = np.ceil(uv.max(0)).astype(int) + r + 1
        w, h = (hi - self.lo + 1).tolist()
        self.mask = None
        if w * h > self.MAX_RASTER_PX:
            return
        self.mask = np.zeros((h, w), bool)
        dy, dx = np.mgrid[-r - 1 : r + 2, -r - 1 : r + 2]
        for u, v in uv:
            cu, cv = int(round(u)) - self.lo[0], int(round(v)) - self.lo[1]
            # the disc about the blob itself (not its rounded pixel), a pixel more than needed
            disc = (dx + cu + self.lo[0] - u) ** 2 + (dy + cv + self.lo[1] - v) ** 2 <= (reach + 0.5) ** 2
            self.mask[cv - r - 1 : cv + r + 2, cu - r - 1 : cu + r + 2] |= disc

    def query(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Distance (px) to the nearest blob within ``tol_px`` and its index, per point (m, 2);
        ∞ and n where none is (as :meth:`scipy.spatial.cKDTree.query` gives them)."""
        if self.mask is None:
            return self.tree.query(q, distance_upper_bound=self.tol)
        h, w = self.mask.shape
        x, y = q[:, 0] - self.lo[0], q[:, 1] - self.lo[1]
        cand = np.flatnonzero((x > -0.5) & (y > -0.5) & (x < w - 0.5) & (y < h - 0.5))
        cand = cand[self.mask[np.rint(y[cand]).astype(int), np.rint(x[cand]).astype(int)]]
        d, j = np.full(len(q), np.inf), np.full(len(q), self.n)
        if len(cand):
            d[cand], j[cand] = self.tree.query(q[cand], distance_upper_bound=self.tol)
        return d, j


def _labellings_of(
    model: np.ndarray, camera: Camera, lookup: _BlobLookup, R: np.ndarray, t: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The bead labelling of each pose (R (k, 3, 3), t (k, 3)): per model bead the blob of
    ``lookup`` within its tolerance of its projection (−1 for none), one blob per bead — a blob two
    beads land on goes to the nearer, the lower bead index on a tie. Returns the labellings
    (k, P), their matched counts (k,) and RMS distances (k,) px (counts are worked out only
    where at least four beads land on a blob; the rest read 0)."""
    P = len(model)
    proj, Z = project(camera, R, t, model)
    front = (Z > 0).all(1) & np.isfinite(proj).all((1, 2))
    proj = np.where(np.isfinite(proj), proj, 1e9)  # a degenerate pose matches nothing
    d, j = lookup.query(proj.reshape(-1, 2))
    d, j = d.reshape(len(R), P), j.reshape(len(R), P)
    hit = np.isfinite(d) & front[:, None]
    lab = np.full((len(R), P), -1)
    count = np.zeros(len(R), int)
    rms = np.full(len(R), np.inf)
    # a pose with fewer than four beads on blobs keeps fewer still: the one-blob-per-bead rule
    # is worked out only for the others (a few of the hundreds of P3P poses)
    many = np.flatnonzero(hit.sum(1) >= 4)
    if len(many) == 0:
        return lab, count, rms
    d, j, hit = d[many], j[many], hit[many]
    idx = np.arange(P)
    same = (j[:, :, None] == j[:, None, :]) & hit[:, :, None] & hit[:, None, :]
    nearer = (d[:, None, :] < d[:, :, None]) | ((d[:, None, :] == d[:, :, None]) & (idx[None, :] < idx[:, None]))
    keep = hit & ~(same & nearer).any(-1)
    count[many] = keep.sum(1)
    with np.errstate(invalid="ignore"):
        rms[many] = np.sqrt(np.where(keep, d * d, 0.0).sum(1) / np.maximum(count[many], 1))
    lab[many] = np.where(keep, j, -1)
    return lab, count, rms


def _collect_matches(
    best: dict, model: np.ndarray, camera: Camera, lookup: _BlobLookup, R: np.ndarray, t: np.ndarray
) -> int:
    """Add to ``best`` (labelling → its distinct poses, each the lowest-RMS hypothesis of
    those within :data:`SAME_POSE_RAD` of it) the labellings of the poses (R, t) that put at
    least four model beads on distinct blobs of ``lookup``; returns the most beads any of them
    matched (0 for none: a labelling's count is its own, so the best count in ``best`` is the
    running largest of these).

    Every such labelling is kept, whatever the order or the number of the poses that give it:
    P3P solutions of one triplet that are the same pose give the same labelling, and which
    of them was listed first decides nothing (a cut to the first 64 poses by matched count
    once let the solver's order pick among ties). One labelling can come with two poses far
    apart: a small fiducial is seen in near-affine projection, where P3P's second solution
    puts every ball on the same blob as the first (ftrac_mini over anatomy: the right pose
    and one 58° off, 0.2 and 0.15 px RMS); kept as one hypothesis, the lower RMS chose the
    wrong one, the right pose was never refined, and a labelling 178° off won."""
    lab, count, rms = _labellings_of(model, camera, lookup, R, t)
    sel = np.flatnonzero(count >= 4)
    if len(sel) == 0:
        return 0
    # lowest RMS first within each labelling (ties: the pose listed first)
    o = sel[np.lexsort((rms[sel],) + tuple(lab[sel].T[::-1]))]
    for r, row in zip(o, lab[o].tolist()):
        key = tuple(row)
        poses = best.setdefault(key, [])
        near = next((k for k, h in enumerate(poses) if so3.angle(h.R, R[r]) < SAME_POSE_RAD), None)
        if near is not None and rms[r] >= poses[near].rms_px:
            continue
        match = {b: x for b, x in enumerate(row) if x >= 0}
        h = BeadHypothesis(R[r], t[r], match, int(count[r]), float(rms[r]))
        if near is None:
            poses.append(h)
        else:
            poses[near] = h
    return int(count[sel].max())


def bead_hypotheses(
    model: np.ndarray,
    uv: np.ndarray,
    camera: Camera,
    tol_px: float,
    image_triplets: int = 24,
    keep: int | None = 8,
    max_extent_px: float = np.inf,
    blobs: int = 12,
    after: int = 0,
    patience: int | None = 5,
    view: ViewPrior | None = None,
    labelled: dict[int, int] | None = None,
    labelled_triplets: int = 0,
) -> list[BeadHypothesis]:
    """Distinct bead labellings ranked by matched count, then RMS (best first).

    Parameters
    ----------
    model : (P, 3) bead centres in F (mm).
    uv : (n, 2) detected blob centres (px), strongest first.
    camera : intrinsics.
    tol_px : a projected bead matches a blob within this distance.
    image_triplets : how many triplets of blobs are tried at most (see :func:`_image_triplets`);
        the search stops early once a labelling explains every ball, or five triplets after
        the best one (explaining all but one or two) was last improved.
    keep : how many labellings are returned (None: all).
    max_extent_px : the largest distance two balls of the fiducial can be apart in the image.
    blobs : the triplets are of this many of the strongest blobs.
    after : the first ``after`` triplets of the 12 strongest blobs (a search with the
        defaults tried them) are not tried again.
    patience : triplets tried without a better labelling before a search that explains all
        balls but one or two stops; None: it goes on (where the labellings such a search
        found were refused, their count is no sign that the right one is among them).
    view : the view as known beforehand (:class:`.options.ViewPrior`): only P3P poses it
        admits within :data:`SAME_POSE_RAD` more are labelled (three balls' pose is a few
        degrees off the refined one), so that the search's stops count only those; None: all.
    labelled : an answer's labelling (blob index → model bead index) its wires did not confirm:
        up to ``labelled_triplets`` triplets of its blobs are tried first, outside the stops,
        with every model triplet that keeps two of their labels (:func:`_relabelled_poses`).

    Returns
    -------
    list of BeadHypothesis
    """
    uv = np.asarray(uv, float)
    uv = uv[np.isfinite(uv).all(1)] if not np.isfinite(uv).all() else uv
    P, n = len(model), len(uv)
    if P < 3 or n < 3:
        return []
    K = camera.K
    mtri = _model_triplets(model)
    lookup = _BlobLookup(uv, tol_px)
    best: dict[tuple, list[BeadHypothesis]] = {}
    objs = np.ascontiguousarray(model[mtri], dtype=np.float64)  # (m, 3, 3), once for every image triplet
    if labelled:
        poses = _relabelled_poses(model, uv, K, labelled, labelled_triplets, max_extent_px, mtri, view)
        if poses is not None:
            _collect_matches(best, model, camera, lookup, *poses)
    top, stale, tried = 0, 0, 0
    skip = frozenset(_image_triplets(uv, after, max_extent_px)) if after > 0 else frozenset()
    for itri in _image_triplets(uv, image_triplets, max_extent_px, k=blobs, skip=skip):
        poses = _admitted(_p3p_poses(objs, np.ascontiguousarray(uv[list(itri)], dtype=np.float64), K), view)
        if poses is None:
            continue
        top_now = max(top, _collect_matches(best, model, camera, lookup, *poses))
        stale = 0 if top_now > top else stale + 1
        top = top_now
        # every ball explained; or nearly all (a ball or two too faint or merged) and the
        # last few triplets found nothing better: the rest would only cost time
        nearly = patience is not None and top >= max(4, min(P, n) - 2) and stale >= patience
        if top >= min(P, n) or nearly:
            break
        tried += 1
        if tried >= 8 and top < 4:
            # eight triplets of the strongest blobs and not four balls in a row: not here
            break
    return _ranked(best, keep)


#: Gauss–Newton steps of :func:`polished_poses`: from poses ~2° and 15 mm off, three reach
#: the matched balls' reprojection minimum to within 1e-5° and 1e-4 mm of SciPy's
#: ``least_squares`` (tests/test_hypothesis_ranking.py)
POLISH_STEPS = 3


def polished_poses(
    camera: Camera, model: np.ndarray, uv: np.ndarray, hyps: list[BeadHypothesis], steps: int = POLISH_STEPS
) -> tuple[np.ndarray, np.ndarray]:
    """Each hypothesis' pose moved to the reprojection minimum of all the balls it matched
    (Gauss–Newton on every hypothesis at once): R (H, 3, 3), t (H, 3), F → X (SPEC §1).

    A hypothesis' pose is the P3P pose of three of its balls; three balls a few millimetres
    apart leave the pose off by degrees and tens of millimetres in depth, so that its wires are
    predicted beside the ridges that show them, and a hypothesis of four right balls was
    ranked behind hundreds of clutter hypotheses by the wire evidence at that pose (ftrac_2005,
    display-dark frame of tuning seed 2135: P3P pose 1.5° and 30 mm off, 0.4° and 20 mm once
    fitted to its four balls; its wires' evidence 3.7 → 5.3 noise units, 7th → 1st). A row
    keeps its pose where the steps did not lower its matched balls' squared residuals.

    Parameters
    ----------
    camera : the intrinsics of ``uv``'s pixels.
    model : (P, 3) ball centres in F, mm.
    uv : (n, 2) blob centres, px; the hypotheses' ``match`` values index it.
    hyps : the hypotheses (``match``: model ball → blob; four or more balls each).
    steps : Gauss–Newton steps.
    """
    R = np.stack([h.R for h in hyps]).astype(float)
    t = np.stack([h.t for h in hyps]).astype(float)
    H, P = len(hyps), len(model)
    lab = np.full((H, P), -1)
    for i, h in enumerate(hyps):
        for a, b in h.match.items():
            lab[i, a] = b
    w = (lab >= 0).astype(float)[..., None]
    obs = np.asarray(uv, float)[np.maximum(lab, 0)] * w
    model = np.asarray(model, float)
    fx, fy = camera.fx, camera.fy
    c = np.asarray(camera.principal_point_px, float)

    def residual(R, t):
        # the pinhole of :func:`project`, written out to keep the points X for the Jacobian
        X = model @ np.swapaxes(R, 1, 2) + t[:, None, :]
        px = np.stack([fx * X[..., 0], fy * X[..., 1]], -1) / X[..., 2:] + c
        return (px - obs) * w, X

    r, X = residual(R, t)
    cost0 = (r * r).sum((1, 2))
    R1, t1 = R, t
    with np.errstate(all="ignore"):
        for _ in range(steps):
            iz = 1.0 / X[..., 2]
            zero = np.zeros_like(iz)
            # d(u, v)/dX of the pinhole, then dX/d(ω, t) = (−[R P]ₓ, I) for R → exp(ω) R
            JX = np.stack(
                [
                    np.stack([fx * iz, zero, -fx * X[..., 0] * iz * iz], -1),
                    np.stack([zero, fy * iz, -fy * X[..., 1] * iz * iz], -1),
                ],
                -2,
            )
            q = X - t1[:, None, :]
            Jw = np.cross(q[..., None, :], JX)
            J = (np.concatenate([Jw, JX], -1) * w[..., None]).reshape(H, 2 * P, 6)
            JT = np.swapaxes(J, 1, 2)
            d = -spd_solve(JT @ J + 1e-9 * np.eye(6), JT @ r.reshape(H, 2 * P, 1))[..., 0]
            R1 = so3.exp(d[:, :3]) @ R1
            t1 = t1 + d[:, 3:]
            r, X = residual(R1, t1)
        better = np.isfinite(r).all((1, 2)) & ((r * r).sum((1, 2)) < cost0) & (X[..., 2] > 0).all(1)
    return np.where(better[:, None, None], R1, R), np.where(better[:, None], t1, t)


def _ranked(best: dict[tuple, list[BeadHypothesis]], keep: int | None) -> list[BeadHypothesis]:
    """The first ``keep`` (None: all) hypotheses of ``best`` (labelling → its poses) by matched
    count, then RMS; ties broken by the labelling itself, so that the ranking depends on no
    order of discovery."""
    ranked = sorted(
        ((key, k, h) for key, poses in best.items() for k, h in enumerate(poses)),
        key=lambda e: (-e[2].count, e[2].rms_px, e[0], e[1]),
    )
    return [h for _, _, h in ranked[:keep]]


@dataclass
class Contours:
    """Contour points gathered for each curve feature by a pose's prediction."""

    lines: dict[str, np.ndarray] = field(default_factory=dict)
    ellipses: dict[str, np.ndarray] = field(default_factory=dict)
    snr: dict[str, np.ndarray] = field(default_factory=dict)
    #: curves whose projection is covered by another feature too much to use
    dropped: dict[str, str] = field(default_factory=dict)
    #: curves with hardly any ridge point near their prediction at all: evidence against the pose
    missing: list[str] = field(default_factory=list)
    #: balls in view, clear of the others (their blurred discs touch none), that the labelling
    #: leaves without a blob, where the image could have shown them, and groups of touching
    #: balls none of which it shows (set by :func:`.labelling.misfit`)
    unexplained_beads: int = 0
    #: balls the labelling does not use within two bead widths of another (in its fit's
    #: window) and that the image shows where it puts them (set by :func:`.labelling.misfit`)
    crowded_shown: int = 0


_SAMPLES_CACHE: dict = {}


def curve_samples(
    features: Features, camera: Camera, R: np.ndarray, t: np.ndarray, step_px: float = 0.5
) -> dict[str, tuple[str, np.ndarray]]:
    """Densely projected centre-lines: id → (kind, (n, 2) px), wire pieces of lines only.
    The last few poses' samples are kept (contour gathering, wire support, agreement and
    the ball refit all ask for the same pose)."""
    key = (
        id(features),
        tuple(camera.intrinsics),
        np.asarray(R, float).tobytes(),
        np.asarray(t, float).tobytes(),
        step_px,
    )
    hit = _SAMPLES_CACHE.get(key)
    if hit is not None and hit[0] is features:
        return hit[1]
    out = _curve_samples_uncached(features, camera, R, t, step_px)
    if len(_SAMPLES_CACHE) >= 8:
        _SAMPLES_CACHE.pop(next(iter(_SAMPLES_CACHE)))
    _SAMPLES_CACHE[key] = (features, out)
    return out


def _curve_samples_uncached(
    features: Features, camera: Camera, R: np.ndarray, t: np.ndarray, step_px: float
) -> dict[str, tuple[str, np.ndarray]]:
    # every piece's end points and every ellipse's 64 coarse samples in one projection,
    # then every dense sample in a second (the projection is point-wise: the same numbers)
    pieces = features.wire_pieces
    coarse = [np.array([a, b]) for _, a, b in pieces]
    coarse += [el.sample(np.linspace(0, 2 * np.pi, 64, endpoint=False)) for el in features.ellipses]
    cuv = project(camera, R, t, np.concatenate(coarse))[0] if coarse else np.zeros((0, 2))
    dense, owner = [], []
    for k, (fid, a, b) in enumerate(pieces):
        ab = cuv[2 * k : 2 * k + 2]
        n = max(int(np.linalg.norm(ab[1] - ab[0]) / step_px), 2)
        dense.append(a + np.linspace(0, 1, n)[:, None] * (b - a))
        owner.append((fid, "line"))
    o = 2 * len(pieces)
    for k, el in enumerate(features.ellipses):
        uv = cuv[o + 64 * k : o + 64 * (k + 1)]
        per = float(np.linalg.norm(np.diff(np.vstack([uv, uv[:1]]), axis=0), axis=1).sum())
        n = max(int(per / step_px), 64)
        dense.append(el.sample(np.linspace(0, 2 * np.pi, n, endpoint=False)))
        owner.append((el.id, "ellipse"))
    if not dense:
        return {}
    duv = project(camera, R, t, np.concatenate(dense))[0]
    parts: dict[str, tuple[str, list]] = {}
    i = 0
    for (fid, kind), X in zip(owner, dense):
        parts.setdefault(fid, (kind, []))[1].append(duv[i : i + len(X)])
        i += len(X)
    return {fid: (kind, np.concatenate(p)) for fid, (kind, p) in parts.items()}


def gather_contours(
    features: Features,
    camera: Camera,
    R: np.ndarray,
    t: np.ndarray,
    ridges: RidgePoints,
    bead_radius_px: np.ndarray,
    tol_px: float,
    separation_px: float,
    min_points: int = 8,
    max_angle_deg: float = 25.0,
    ridge_var_px2: float = 0.0,
    thin_px: float = 0.0,
) -> Contours:
    """Ridge points of each projected line and ellipse at pose (R, t).

    A ridge point belongs to a curve when it lies within ``tol_px`` of it, its normal is
    within ``max_angle_deg`` of the curve's, no other curve passes within
    ``separation_px`` and no projected bead covers it (``bead_radius_px`` per model bead,
    the exclusion radius). Curves left with fewer than ``min_points`` are dropped.

    ``ridge_var_px2`` is the variance σ² of the smoothed wire profile that the ridge
    detector sees (detector scale² + blur² + the wire's own profile variance): a curved
    wire's ridge lies σ²κ/2 inside its centre-line (the peak of a ring of radius 1/κ
    blurred by σ), so each ellipse point is moved outward by that much, κ taken from the
    predicted curve.

    ``thin_px`` > 0 keeps one point per ``thin_px`` of arc length (the one nearest the
    middle of its stretch, so the choice does not favour the prediction): Steger points one
    pixel apart share most of their smoothed noise, and counted as independent they
    overstate a curve's information several-fold (the per-feature χ² test then rejected
    correct ellipses and the pose covariance came out ~3× too small).
    """
    out = Contours()
    if len(ridges) == 0:
        return out
    curves = curve_samples(features, camera, R, t)
    ids = list(curves)
    if not ids:
        return out
    reach_px = max(separation_px, tol_px) + 2
    # only ridge points inside the curves' bounding box (grown by the reach) can be near
    # one: everything below runs on those alone (a few hundred of several thousand)
    allp = np.concatenate([p for _, p in curves.values()])
    allp = allp[np.isfinite(allp).all(1)]
    if len(allp):
        lo, hi = allp.min(0) - reach_px, allp.max(0) + reach_px
        ridges = ridges.take(np.flatnonzero(((ridges.uv >= lo) & (ridges.uv <= hi)).all(1)))
    uvr = ridges.uv
    reach, arc, dist, tang, corr = _near_curves(curves, ids, uvr, reach_px, ridge_var_px2)
    # beads cover the wire ends they butt against and anything under them (only a point
    # within reach of a curve can be kept, so only those are tested)
    free = np.ones(len(uvr), bool)
    if len(features.points) and reach.any():
        bu = project(camera, R, t, features.point_centers())[0]
        db = np.linalg.norm(uvr[reach][:, None] - bu[None], axis=-1)
        free[reach] = (db > np.asarray(bead_radius_px)[None]).all(1)
    near = dist <= tol_px
    crowded = (dist <= separation_px).sum(0) > 1
    cosang = np.abs(np.einsum("kni,ni->kn", tang, ridges.normal))  # normal ⟂ tangent → ~0
    aligned = cosang <= np.sin(np.radians(max_angle_deg))
    usable = near & ~crowded & free & aligned
    _keep_points(out, curves, ids, usable, near, arc, uvr, corr, ridges.snr, min_points, thin_px)
    return out


def _near_curves(
    curves: dict, ids: list[str], uvr: np.ndarray, reach_px: float, ridge_var_px2: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """For ridge points ``uvr`` (n, 2) and the curves ``ids``: whether each point is within
    ``reach_px`` of some curve (n,), and per curve and point the arc position of its nearest
    sample (k, n; px), the distance to the curve (k, n; ∞ beyond reach), the curve's tangent
    (k, n, 2) and an ellipse point's outward shift (k, n, 2; see :func:`gather_contours`)."""
    reach = np.zeros(len(uvr), bool)  # within reach of some curve
    arc = np.zeros((len(ids), len(uvr)))
    dist = np.full((len(ids), len(uvr)), np.inf)
    tang = np.zeros((len(ids), len(uvr), 2))
    corr = np.zeros((len(ids), len(uvr), 2))
    for k, fid in enumerate(ids):
        kind, pts = curves[fid]
        # only the ridge points near this curve can be near, crowded or kept (the rest of
        # its row stays at distance ∞): the query and the per-point arithmetic on those
        # inside its own bounding box grown by the reach alone
        fin = pts[np.isfinite(pts).all(1)]
        box = (
            np.flatnonzero(((uvr >= fin.min(0) - reach_px) & (uvr <= fin.max(0) + reach_px)).all(1))
            if len(fin)
            else np.zeros(0, int)
        )
        if len(box) == 0:
            continue
        tree = cKDTree(pts)
        d, j = tree.query(uvr[box], distance_upper_bound=reach_px)
        on = box[np.isfinite(d)]
        d, j = d[np.isfinite(d)], j[np.isfinite(d)]
        reach[on] = True
        ok = np.ones(len(on), bool)
        jj = np.clip(j, 0, len(pts) - 1)
        # tangent from neighbouring samples; perpendicular distance to the local chord
        a = pts[np.clip(jj - 1, 0, len(pts) - 1)]
        b = pts[np.clip(jj + 1, 0, len(pts) - 1)]
        if kind == "ellipse":
            a = pts[(jj - 1) % len(pts)]
            b = pts[(jj + 1) % len(pts)]
        tv = b - a
        tv /= np.maximum(np.linalg.norm(tv, axis=1, keepdims=True), 1e-12)
        perp = np.abs((uvr[on] - pts[jj])[:, 0] * tv[:, 1] - (uvr[on] - pts[jj])[:, 1] * tv[:, 0])
        # at a line piece's ends the nearest sample is the end: use the plain distance there
        dd = np.where(ok, np.minimum(np.maximum(perp, 0), d) if kind == "ellipse" else d, np.inf)
        if kind == "line":
            inner = (jj > 0) & (jj < len(pts) - 1)
            dd = np.where(ok & inner, perp, dd)
        dist[k, on] = dd
        tang[k, on] = tv
        arc[k, on] = jj * 0.5  # _curve_samples' step, px
        if kind == "ellipse":
            # signed curvature from three neighbouring samples; its centre side is where the
            # chord's midpoint bends
            corr[k, on] = outward_shift(pts, ridge_var_px2)[jj]
    return reach, arc, dist, tang, corr


def _keep_points(
    out: Contours,
    curves: dict,
    ids: list[str],
    usable: np.ndarray,
    near: np.ndarray,
    arc: np.ndarray,
    uvr: np.ndarray,
    corr: np.ndarray,
    snr: np.ndarray,
    min_points: int,
    thin_px: float,
) -> None:
    """Each curve's usable ridge points (``usable`` (k, n)) into ``out``, thinned to one per
    ``thin_px`` of arc; a curve left with fewer than ``min_points`` is dropped, and counted
    missing when fewer are even ``near`` it."""
    for k, fid in enumerate(ids):
        sel = usable[k]
        kind = curves[fid][0]
        if sel.sum() < min_points:
            cover = near[k].sum()
            if cover < min_points:
                out.missing.append(fid)
            out.dropped[fid] = (
                f"{int(sel.sum())} usable contour points ({int(cover)} near it; the rest lie on beads or other wires)"
            )
            continue
        idx = np.flatnonzero(sel)
        if thin_px > 0:
            a = arc[k][idx]
            b = np.floor(a / thin_px)
            off = np.abs(a - (b + 0.5) * thin_px)
            o = np.lexsort((off, b))
            first = np.r_[True, b[o][1:] != b[o][:-1]]
            idx = np.sort(idx[o[first]])
            if len(idx) < 5:
                out.dropped[fid] = f"{len(idx)} independent contour points"
                continue
        (out.lines if kind == "line" else out.ellipses)[fid] = uvr[idx] + corr[k][idx]
        out.snr[fid] = snr[idx]
