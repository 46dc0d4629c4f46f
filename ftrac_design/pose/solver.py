"""Single-image pose: closed-form start, Levenberg–Marquardt, multi-start, checks (paper §II.B.4–7).

Strategy, fastest first:

1. **Closed-form start.** With ≥ 6 non-coplanar beads, a normalised DLT gives a pose that
   is already inside the basin of the true minimum, and two Gauss–Newton steps on the bead
   reprojection errors move it to the beads' own minimum; one local solve finishes it —
   usually in a single step. This is what makes a robust solve take about a millisecond
   instead of the paper's 50 runs.
2. **Local solve.** Levenberg–Marquardt on all features with the closed-form Jacobian, the
   rotation as a left so(3) increment (no Euler-angle singularity), parameter scaling H
   (rotation measured as the displacement it causes at the fiducial's characteristic
   radius, so one unit of either parameter moves features by ~1 mm) and the Gauss–Markov
   task scaling G of :mod:`.problem`, refreshed at every accepted step from the closed-form
   start and held fixed within inner solves elsewhere (see :func:`levenberg_marquardt`).
3. **Multi-start** when there is no closed-form start (fewer than 6 beads, beads coplanar)
   or the local solve fails its checks: starts from rotations spread evenly over SO(3)
   with depth and position matched to the image, all solved together in one batch; the
   best few are polished. Distinct poses that fit equally well make the answer ambiguous
   (e.g. the mirror solutions of too few features) and are reported, not guessed between.
4. **Checks.** Converged steps, every model point in front of the source, residuals
   consistent with the noise model (noise scale κ ≤ ``max_noise_scale``), and a
   well-conditioned final Jacobian; otherwise ``converged = False`` with the reason.

The covariance is ``κ² (JᵀJ)⁻¹`` at the solution (whitened J), κ² the residual-based noise
estimate pooled over the pose residuals and the contour fits.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from typing import Iterable

import numpy as np
from scipy.special import chdtrc, fdtrc

from ..features.model import Features
from . import so3
from .observation import Observation
from .problem import (
    ELLIPSE_MODEL_POINTS,
    NoiseModel,
    Problem,
    bead_rows,
    compile_problem,
    evaluate,
    jacobian_rows,
    project_points,
    rows_where,
)
from .record import Pose


@dataclass(frozen=True)
class SolverOptions:
    """Tuning of the solver; the defaults are what the benchmarks measured."""

    noise: NoiseModel = field(default_factory=NoiseModel)
    ellipse_model_points: int = ELLIPSE_MODEL_POINTS
    #: "sampson" (first-order geometric distance) or "paper" (K·PᵀMP, Eq. 8)
    distance: str = "sampson"
    #: "gauss-markov" (whiten by each fitted curve's covariance) or "diagonal" (1/σ per
    #: distance, the paper's fallback G), see :mod:`.problem`
    task_scaling: str = "gauss-markov"
    max_iterations: int = 60
    #: multi-start seeds when there is no closed-form start
    starts: int = 96
    #: iterations each seed gets before the best are polished
    explore_iterations: int = 12
    #: a local solve whose pose residuals are this improbable is re-solved the careful way
    #: (beads first, then multi-start) in case it found a false minimum; the test compares
    #: the pose residuals with the contour fits' own residuals (an F test), so it does not
    #: depend on the noise model being right, and falls back to χ² against the model for
    #: bead-only images and for contours fitted to far below the modelled noise
    retry_p_value: float = 1e-4
    #: reject a pose whose residuals are this many times the noise model's
    max_noise_scale: float = 5.0
    #: reject a pose whose residuals are both certainly more than noise (p-value of the
    #: residual test below ``misfit_p_value``) and large (noise scale above
    #: ``misfit_noise_scale``): features that fit no single pose, e.g. swapped ids between
    #: neighbouring wires, which otherwise converge a few mm off at κ ≈ 3.6–4.6. A C-arm with
    #: 5× the paper's calibration errors gives p down to 1e-17 but κ ≤ 2.3 (tests/test_fuzz_*)
    misfit_p_value: float = 1e-12
    misfit_noise_scale: float = 3.0
    #: a local solve ending this ill-conditioned is re-solved as above: far from the true
    #: pose the whitening of a nearly edge-on ellipse can blow up and hold the solver in a
    #: false minimum (ftrac_2005's workspace stays below ~100)
    retry_condition: float = 1e4
    #: reject a pose whose scaled Jacobian has a larger condition number
    max_condition: float = 1e6
    #: a second minimum within this χ² of the best, far enough away, makes the answer ambiguous
    ambiguity_chi2: float = 9.0
    ambiguity_rotation_deg: float = 2.0
    ambiguity_translation_mm: float = 5.0
    #: use the closed-form (DLT) start when ≥ 6 non-coplanar beads are observed
    closed_form_start: bool = True


#: shared, since the options are immutable
_DEFAULTS = SolverOptions()


# ----------------------------------------------------------------------------- local solve
def parameter_scale(features: Features) -> np.ndarray:
    """H (6,): rotation in units of 1/ρ_F rad (ρ_F the characteristic radius), translation in mm."""
    return np.array([1.0 / features.characteristic_radius] * 3 + [1.0] * 3)


@dataclass
class _State:
    """A batch of poses in the middle of a solve. ``W`` is the whitening the residuals and
    Jacobian are currently computed with; ``fresh`` says it was evaluated at this pose."""

    R: np.ndarray
    t: np.ndarray
    rho: np.ndarray
    J: np.ndarray
    raw: np.ndarray
    Z: np.ndarray
    cost: np.ndarray
    W: list[np.ndarray]
    iters: np.ndarray
    converged: np.ndarray
    fresh: np.ndarray
    lam: np.ndarray

    def rows(self, idx: np.ndarray) -> "_State":
        """A copy of rows ``idx``."""
        return _State(
            self.R[idx],
            self.t[idx],
            self.rho[idx],
            self.J[idx],
            self.raw[idx],
            self.Z[idx],
            self.cost[idx],
            [np.asarray(w)[idx] for w in self.W],
            self.iters[idx].copy(),
            self.converged[idx].copy(),
            self.fresh[idx].copy(),
            self.lam[idx].copy(),
        )

    def put(self, mask: np.ndarray, other: "_State") -> None:
        """Take the rows of ``other`` (same batch size) where ``mask``."""
        if mask.all():
            self.R, self.t, self.rho, self.J = other.R, other.t, other.rho, other.J
            self.raw, self.Z, self.cost, self.W = other.raw, other.Z, other.cost, other.W
            return
        self.R, self.t = rows_where(mask, other.R, self.R), rows_where(mask, other.t, self.t)
        self.rho, self.J = rows_where(mask, other.rho, self.rho), rows_where(mask, other.J, self.J)
        self.raw, self.Z = rows_where(mask, other.raw, self.raw), rows_where(mask, other.Z, self.Z)
        self.cost = np.where(mask, other.cost, self.cost)
        self.W = [rows_where(mask, a, b) for a, b in zip(other.W, self.W)]


#: contour fits whose residual variance is below this fraction of the modelled noise
#: variance say nothing about the noise (see :func:`_finish_all`)
FIT_NOISE_FLOOR = 0.01

#: iterations after which a row whose inner solve has converged is accepted without a
#: further whitening refresh (see :func:`levenberg_marquardt`); solves at the paper's
#: 0.25 mm segmentation error settle in under 15
SETTLE_ITERATIONS = 30

#: initial Marquardt damping: almost none, since the depth direction is ~10⁶ times weaker
#: than the lateral ones in JᵀJ and damping scaled to the strong directions would stall it
_LAMBDA0 = 1e-9


def _evaluate_state(
    prob: Problem,
    R: np.ndarray,
    t: np.ndarray,
    whitening: list[np.ndarray] | None = None,
    reference: list[np.ndarray] | None = None,
    freeze: np.ndarray | None = None,
) -> tuple[_State, np.ndarray | None]:
    """State at poses (R, t): with fresh whitening, or with ``whitening`` held fixed (in the
    rows ``freeze``, if given); and, given a ``reference`` whitening, the cost (B,) under it
    (else None)."""
    with np.errstate(all="ignore"):
        ev = evaluate(prob, R, t, whitening=whitening, reference=reference, freeze=freeze)
        cost = (ev.rho * ev.rho).sum(1)
        # a non-finite residual makes the sum non-finite too
        bad = ~np.isfinite(cost) | (ev.Z.min(1) <= 0)
        cost = np.where(bad, np.inf, cost)
        cost_ref = None
        if reference is not None:
            cost_ref = (ev.rho_ref * ev.rho_ref).sum(1)
            cost_ref = np.where(bad | ~np.isfinite(cost_ref), np.inf, cost_ref)
    B = R.shape[0]
    return _State(
        R,
        t,
        ev.rho,
        ev.J,
        ev.raw,
        ev.Z,
        cost,
        ev.W,
        np.zeros(B, int),
        np.zeros(B, bool),
        np.full(B, whitening is None),
        np.full(B, _LAMBDA0),
    ), cost_ref


def levenberg_marquardt(
    prob: Problem,
    R: np.ndarray | None,
    t: np.ndarray | None,
    h: np.ndarray,
    max_iterations: int,
    state: _State | None = None,
    eager: bool | np.ndarray = False,
) -> _State:
    """Batched LM from poses (B, 3, 3), (B, 3) (or a ``state``); rows converge independently.

    The whitening G is held fixed while the pose moves, so every inner problem has a fixed
    objective, an exact Jacobian and monotone LM steps; when a row's inner problem has
    converged, G is re-evaluated at its pose and the row goes on. It is converged when a
    step with G fresh at its pose gains nothing: the Gauss–Markov (iteratively reweighted)
    least-squares solution, where the gradient vanishes with G taken at the solution.

    ``eager`` (per row, or for all) refreshes G at every accepted step instead (a step is
    still judged on the objective it was computed for): from a start already in the basin,
    such as the closed-form one, the fixed point is the same and is reached in about half
    the evaluations, since the inner solves no longer run to convergence on a stale G. A
    row whose refreshed objective comes out worse than before the step — far from the
    solution, where G still moves a lot with the pose — falls back to holding G fixed.
    """
    st = state if state is not None else _evaluate_state(prob, R, t)[0]
    B = st.R.shape[0]
    eager = np.broadcast_to(np.asarray(eager, bool), (B,)).copy()
    for it in range(max_iterations):
        act = ~st.converged & (st.cost < np.inf)
        if not act.any():
            break
        if B >= 8 and act.sum() <= B // 4:
            # most rows are done: finish the stragglers on a compacted batch instead of
            # recomputing every converged row at every iteration
            _finish_rows(prob, st, np.flatnonzero(act), h, max_iterations - it, eager)
            break
        step, pred, tiny = _lm_step(st, h)
        flat = (pred <= 1e-7 * st.cost) | tiny
        settled = st.fresh & ((pred <= 1e-4 * st.cost) | tiny)
        st.converged |= act & settled
        act &= ~settled
        move = act & ~flat
        st.iters += act
        stalled = _take_step(prob, st, step * h, move, eager) if move.any() else False
        done = act & (flat | stalled | (st.lam > 1e6))
        if done.any():
            _refresh_done(prob, st, done)
    return st


def _finish_rows(prob: Problem, st: _State, idx: np.ndarray, h: np.ndarray, iterations: int, eager: np.ndarray) -> None:
    """Run :func:`levenberg_marquardt` on the rows ``idx`` alone and put them back into ``st``."""
    sub = levenberg_marquardt(prob.take(idx), None, None, h, iterations, st.rows(idx), eager[idx])
    st.R[idx], st.t[idx], st.rho[idx], st.J[idx] = sub.R, sub.t, sub.rho, sub.J
    st.raw[idx], st.Z[idx], st.cost[idx] = sub.raw, sub.Z, sub.cost
    st.iters[idx], st.converged[idx], st.fresh[idx], st.lam[idx] = sub.iters, sub.converged, sub.fresh, sub.lam
    for w, ws in zip(st.W, sub.W):
        w[idx] = ws


def _lm_step(st: _State, h: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The damped Gauss–Newton step of every row (B, 6) in scaled parameters, its predicted
    decrease of the cost (B,) and whether it is negligible (B,)."""
    B = st.R.shape[0]
    Js = st.J * h
    JsT = np.swapaxes(Js, 1, 2)
    A = JsT @ Js
    g = (JsT @ st.rho[..., None])[..., 0]
    # Marquardt: damp each parameter on its own scale (A is not needed undamped again)
    A.reshape(B, 36)[:, ::7] *= 1.0 + st.lam[:, None]
    with np.errstate(all="ignore"):
        try:
            step = -np.linalg.solve(A, g[..., None])[..., 0]
        except np.linalg.LinAlgError:
            step = -(np.linalg.pinv(A) @ g[..., None])[..., 0]
        # predicted decrease of the local model, in χ² units: a step that would gain δ
        # moves the pose by about √δ standard deviations. The inner solve stops at
        # δ ≤ 1e-7 of the cost; with fresh whitening a row is done at δ ≤ 1e-4 of the
        # cost (≤ 5 % of a standard deviation for this fiducial's ~30 residuals, a
        # < 0.3 % loss of efficiency at worst, measured none). On noise-free images the
        # cost goes to ~0 and the absolute floor takes over.
        pred = -(g * step).sum(1) - 1e-14
        tiny = np.abs(step).max(1) < 1e-10
    return step, pred, tiny


def _take_step(prob: Problem, st: _State, d: np.ndarray, move: np.ndarray, eager: np.ndarray) -> np.ndarray:
    """Try the step ``d`` (B, 6) on the rows ``move``: accept it where it lowers the cost
    (updating ``st``, the damping, and ``eager`` in place), else damp more. Returns the rows
    whose accepted step gained nothing measurable (stalled)."""
    Rn = so3.exp(d[:, :3]) @ st.R
    tn = st.t + d[:, 3:]
    if not eager.any():
        new, trial = _evaluate_state(prob, Rn, tn, whitening=st.W)
        trial = new.cost
    elif eager.all():
        new, trial = _evaluate_state(prob, Rn, tn, reference=st.W)
    else:
        new, trial = _evaluate_state(prob, Rn, tn, whitening=st.W, reference=st.W, freeze=~eager)
    ok = move & (trial < st.cost)
    # a step that is accepted but gains nothing measurable is no progress either: in
    # a curved valley pure Gauss–Newton steps can crawl forever, each one a hair better
    # (a gain of 1e-6 of the cost, ~3e-5 in χ² for ~30 rows, is a step of ~0.005 σ)
    with np.errstate(invalid="ignore"):
        stalled = ok & (st.cost - trial <= 1e-14 + 1e-6 * st.cost)
    if ok.any():
        worse = ok & eager & ~(new.cost <= st.cost)
        st.put(ok, new)
        st.fresh = np.where(ok, eager, st.fresh)
        eager &= ~worse
    st.lam = np.where(ok, np.maximum(st.lam * 0.1, 1e-15), np.where(move, st.lam * 10.0, st.lam))
    return stalled


def _refresh_done(prob: Problem, st: _State, done: np.ndarray) -> None:
    """Rows whose inner solve is ``done``: converged where their whitening was fresh, else the
    whitening refreshed at their pose and the solve goes on (see :func:`levenberg_marquardt`)."""
    st.converged |= done & st.fresh
    stale = done & ~st.fresh
    # at large segmentation errors the whitening can keep moving with the pose so that
    # the refresh cycle never settles within the noise; after SETTLE_ITERATIONS the
    # minimum with the whitening of its last refresh (a nearby pose) is accepted — it
    # differs from the fixed point by far less than a standard deviation
    settle = stale & (st.iters >= SETTLE_ITERATIONS)
    st.converged |= settle
    stale &= ~settle
    if stale.any():
        ref = _evaluate_state(prob, st.R, st.t)[0]
        st.put(stale, ref)
        st.fresh |= stale
        st.lam = np.where(stale, _LAMBDA0, st.lam)


# ----------------------------------------------------------------------------- starts
@functools.lru_cache(maxsize=64)
def _dlt_normalisation(X_bytes: bytes, P: int) -> tuple[np.ndarray, np.ndarray]:
    """Hartley normalisation of the bead centres (P, 3): homogeneous normalised points
    (P, 4) and the 4×4 transform T taking a camera matrix back to model coordinates."""
    X = np.frombuffer(X_bytes).reshape(P, 3)
    c = X.mean(0)
    sX = np.sqrt(np.mean(np.sum((X - c) ** 2, 1)) / 3.0)
    Xn = np.concatenate([(X - c) / sX, np.ones((P, 1))], 1)
    T = np.eye(4)
    T[:3, :3] /= sX
    T[:3, 3] = -c / sX
    return Xn, T


def dlt_start(prob: Problem) -> tuple[np.ndarray, np.ndarray] | None:
    """Poses (B, 3, 3), (B, 3) from the observed beads by a normalised DLT, or None when
    fewer than 6 beads are observed or they are (nearly) coplanar."""
    P = len(prob.point_ids)
    X = prob.X[:P]
    if P < 6 or prob.points_coplanar:
        return None
    B = prob.B
    fx, fy, ox, oy = (prob.intr[:, i, None] for i in range(4))
    x = (prob.p_obs[..., 0] - ox) / fx
    y = (prob.p_obs[..., 1] - oy) / fy
    Xn, T = _dlt_normalisation(X.tobytes(), P)
    A = np.zeros((B, 2 * P, 12))
    A[:, 0::2, 0:4] = Xn
    A[:, 0::2, 8:12] = -x[..., None] * Xn
    A[:, 1::2, 4:8] = Xn
    A[:, 1::2, 8:12] = -y[..., None] * Xn
    # the null vector of A as the lowest eigenvector of AᵀA: a batched 12×12 eigh is several
    # times faster than the SVD of A, and with normalised coordinates the squared
    # conditioning costs nothing measurable (the start is polished by Gauss–Newton anyway)
    _, V = np.linalg.eigh(np.swapaxes(A, 1, 2) @ A)
    Pm = V[:, :, 0].reshape(B, 3, 4) @ T
    # choose the sign that puts the beads in front of the source
    depth = Pm[:, 2, :3] @ X.sum(0) + P * Pm[:, 2, 3]
    sign = np.where(depth < 0, -1.0, 1.0)
    Pm *= sign[:, None, None]
    M = Pm[:, :, :3]
    U, sv, Vt = np.linalg.svd(M)
    scale = sv.mean(1)
    R = U @ Vt
    neg = np.linalg.det(R) < 0
    if neg.any():  # noise made M improper: take the nearest proper rotation
        R[neg] = so3.project_to_so3(M[neg])
    t = Pm[:, :, 3] / scale[:, None]
    return R, t


#: Gauss–Newton steps on the beads that polish the DLT start; measured on 300 images of
#: ftrac_2005 at 0.25 mm, from the polished start the local solve on all features needs a
#: single step in 98 % of images (after one bead step: 56 %; from the raw DLT start: none)
BEAD_REFINE_STEPS = 2


def refine_on_beads(
    prob: Problem, R: np.ndarray, t: np.ndarray, h: np.ndarray, steps: int = BEAD_REFINE_STEPS
) -> tuple[np.ndarray, np.ndarray]:
    """Poses (B, 3, 3), (B, 3) moved to the beads' own reprojection minimum by Gauss–Newton.

    The DLT minimises an algebraic error, not the reprojection error, so its pose is a few
    standard deviations off in χ²; the full solve from there spends its first evaluations
    (the costly ones, with ellipse whitening) on what the beads alone can settle. Bead
    residuals need no whitening and are smooth everywhere, so a few plain Gauss–Newton
    steps — each a projection of P points — are cheap and safe. A row keeps its DLT pose
    where the steps did not lower the bead residuals.
    """
    P = len(prob.point_ids)
    X, obs = prob.X[:P], prob.p_obs
    rows, cuv = bead_rows(P)
    cu, cv = cuv[:, 0], cuv[:, 1]

    def residual(R, t):
        uv, _, pr = project_points(X, prob.intr, R, t)
        return (uv - obs).reshape(len(R), 2 * P), pr

    r, pr = residual(R, t)
    cost0 = (r * r).sum(1)
    R1, t1 = R, t
    with np.errstate(all="ignore"):
        for _ in range(steps):
            Js = jacobian_rows(pr, rows, cu, cv) * h
            JsT = np.swapaxes(Js, 1, 2)
            try:
                d = -np.linalg.solve(JsT @ Js, JsT @ r[..., None])[..., 0] * h
            except np.linalg.LinAlgError:
                return R, t
            R1 = so3.exp(d[:, :3]) @ R1
            t1 = t1 + d[:, 3:]
            r, pr = residual(R1, t1)
        better = (r * r).sum(1) < cost0
    if better.all():
        return R1, t1
    return rows_where(better, R1, R), rows_where(better, t1, t)


def _image_anchors(prob: Problem):
    """Per image: centroid (B, 2) px and RMS spread (B,) of what was observed, and the
    matching 3-D reference points (n, 3) and extra radii, for placing multi-start seeds."""
    P, L, E = len(prob.point_ids), len(prob.line_ids), len(prob.ellipse_ids)
    pts2, pts3 = [], []
    if P:
        pts2.append(prob.p_obs)
        pts3.append(prob.X[:P])
    if L:
        ends = prob.X[P : P + 2 * L].reshape(L, 2, 3)
        use = ~prob.l_from_model
        if use.any():
            pts2.append(prob.l_m[:, use])
            pts3.append(ends.mean(1)[use])
    radii2, radii3 = [], []
    if E:
        pts2.append(prob.e_m)
        ell = prob.X[P + 2 * L :].reshape(E, prob.K, 3)
        pts3.append(ell.mean(1))
        radii2.append(prob.e_s * np.sqrt(2.0))
        radii3.append(np.sqrt(np.mean(np.sum((ell - ell.mean(1, keepdims=True)) ** 2, -1), -1)))
    return pts2, pts3, radii2, radii3


def multistart_seeds(prob: Problem, rotations: np.ndarray, depth_prior_mm: float):
    """Seeds for every (image, rotation) pair: rotations (B·S, 3, 3), translations (B·S, 3)
    placing the rotated model so its projection has the image's centroid and spread."""
    B, S = prob.B, rotations.shape[0]
    pts2, pts3, radii2, radii3 = _image_anchors(prob)
    fx, fy, ox, oy = (prob.intr[:, i] for i in range(4))
    if pts2:
        a2 = np.concatenate(pts2, 1)  # (B, n, 2)
        a3 = np.concatenate(pts3, 0)  # (n, 3)
        c2 = a2.mean(1)
        c3 = a3.mean(0)
        spread2 = np.sum((a2 - c2[:, None]) ** 2, (1, 2))  # (B,)
        q = np.einsum("sij,nj->sni", rotations, a3 - c3)  # (S, n, 3)
        spread3 = np.sum(q[..., :2] ** 2, (1, 2))  # (S,)
        f = 0.5 * (fx + fy)
        s2 = spread2[:, None] / f[:, None] ** 2
        s3 = np.broadcast_to(spread3[None], (B, S)).copy()
        for r2, r3 in zip(radii2, radii3):
            s2 = s2 + np.sum(r2**2, 1)[:, None] / f[:, None] ** 2
            s3 = s3 + np.sum(r3**2)
        with np.errstate(all="ignore"):
            Z0 = np.sqrt(s3 / s2)
        Z0 = np.where(np.isfinite(Z0) & (Z0 > 0), Z0, depth_prior_mm)
        ray = np.stack([(c2[:, 0] - ox) / fx, (c2[:, 1] - oy) / fy, np.ones(B)], -1)
        t = Z0[..., None] * ray[:, None, :] - np.einsum("sij,j->si", rotations, c3)[None]
    else:
        t = np.broadcast_to(np.array([0.0, 0.0, depth_prior_mm]), (B, S, 3))
    R = np.broadcast_to(rotations[None], (B, S, 3, 3))
    return R.reshape(B * S, 3, 3).copy(), np.asarray(t).reshape(B * S, 3).copy()


# ----------------------------------------------------------------------------- results
def _finish_all(
    prob: Problem, st: _State, h: np.ndarray, opts: SolverOptions, starts: int, error: str | None = None
) -> list[Pose]:
    """Checks and covariances for every row of a solved batch, vectorised."""
    B = st.R.shape[0]
    m = prob.n_rows
    pose_dof = m - 6
    dof = pose_dof + prob.fit_dof
    with np.errstate(all="ignore"):
        kappa2 = np.where(dof > 0, (st.cost + prob.fit_chi2) / np.maximum(dof, 1), 1.0)
        if pose_dof <= 0:
            pval = np.ones(B)
        else:
            ratio = (st.cost / pose_dof) / (prob.fit_chi2 / np.maximum(prob.fit_dof, 1))
            # the fits' residuals are the reference unless they are ~0 (contours exact to far
            # below the modelled noise, as in noise-free simulation): then any miscalibration
            # would look infinitely improbable against them, and the model is the reference
            by_fits = (prob.fit_dof > 0) & (prob.fit_chi2 > FIT_NOISE_FLOOR * prob.fit_dof)
            # NaN (a non-finite cost) counts as an infinitely improbable residual
            pval = fdtrc(pose_dof, np.maximum(prob.fit_dof, 1), np.where(ratio == ratio, ratio, np.inf))
            if not by_fits.all():
                pval = np.where(by_fits, pval, chdtrc(pose_dof, np.where(st.cost == st.cost, st.cost, np.inf)))
        sq = st.raw * st.raw
        ids, starts_, counts = prob.raw_index
        per = np.sqrt(np.add.reduceat(sq, starts_, axis=1) / counts) if ids else np.zeros((B, 0))
        rms = np.sqrt(sq.sum(1) / sq.shape[1]) if sq.shape[1] else np.full(B, np.nan)
        finite = np.isfinite(st.J).all((1, 2))
        Jf = np.where(finite[:, None, None], st.J, 0.0)
        hh = np.outer(h, h)
        # one eigendecomposition of the scaled JᵀJ gives both the condition number (its
        # eigenvalues are the scaled Jacobian's σ²) and the inverse
        ev, V = np.linalg.eigh((np.swapaxes(Jf, 1, 2) @ Jf) * hh)
        cond = np.where(finite & (ev[:, 0] > 0), np.sqrt(ev[:, -1] / np.where(ev[:, 0] > 0, ev[:, 0], 1.0)), np.inf)
        good = np.isfinite(cond) & (cond < 1e7)
        cov = (V / ev[:, None, :]) @ np.swapaxes(V, 1, 2) * hh * kappa2[:, None, None]
    per_l, rms_l, k_l, c_l, p_l = per.tolist(), rms.tolist(), np.sqrt(kappa2).tolist(), cond.tolist(), pval.tolist()
    out = []
    for row in range(B):
        err = error
        kappa = k_l[row]
        if err is None:
            if not st.converged[row]:
                err = f"did not converge in {int(st.iters[row])} iterations"
            elif not math.isfinite(st.cost[row]):
                err = "no pose puts every feature in front of the source"
            elif not c_l[row] < opts.max_condition:
                err = (
                    f"degenerate view: the observed features do not determine all six pose parameters "
                    f"(condition number {c_l[row]:.3g})"
                )
            elif kappa > opts.max_noise_scale:
                err = (
                    f"residuals too large for the noise model (noise scale {kappa:.3g} > "
                    f"{opts.max_noise_scale}): wrong correspondences or calibration?"
                )
            elif kappa > opts.misfit_noise_scale and p_l[row] < opts.misfit_p_value:
                err = (
                    f"the features fit no single pose: residuals {kappa:.3g} x the noise model and "
                    f"improbable against the contours' own scatter (p = {p_l[row]:.2g}); "
                    f"swapped or misidentified features?"
                )
        out.append(
            Pose(
                st.R[row].copy(),
                st.t[row].copy(),
                err is None,
                rms_l[row],
                cov[row] if good[row] else None,
                dict(zip(ids, per_l[row])),
                int(st.iters[row]),
                err,
                noise_scale=kappa,
                condition_number=c_l[row],
                residual_p_value=p_l[row],
                starts=starts,
                origin=prob.origins[row] if prob.origins else "",
            )
        )
    return out


def _finish(
    prob: Problem, st: _State, row: int, h: np.ndarray, opts: SolverOptions, starts: int, error: str | None = None
) -> Pose:
    """Checks and covariance for one row of a solved batch."""
    return _finish_all(prob.take(np.array([row])), st.rows(np.array([row])), h, opts, starts, error)[0]


def _underdetermined(prob: Problem) -> str | None:
    if prob.n_rows < 6:
        return (
            f"observations do not constrain the pose: {prob.n_rows} independent constraints "
            f"(2 per bead and line, 5 per ellipse) for 6 unknowns"
        )
    return None


def view_seeds(nominal_beam: np.ndarray, cone_deg: float = 30.0, rolls: int = 12) -> np.ndarray:
    """Rotations looking along the design's nominal beam and along 12 directions tilted
    cone/2 and cone from it, each at ``rolls`` evenly spaced rolls: multi-start seeds that
    cover the workspace densely (SPEC §1), where a far-off global spread is thin."""
    from .simulate import cone_directions, rotations_from_beams

    polar = np.concatenate([[0.0], np.full(6, np.radians(cone_deg) / 2), np.full(6, np.radians(cone_deg))])
    az = np.concatenate([[0.0], np.arange(6) * np.pi / 3, np.arange(6) * np.pi / 3 + np.pi / 6])
    beams = cone_directions(nominal_beam, polar, az)
    roll = np.arange(rolls) * 2 * np.pi / rolls
    return rotations_from_beams(np.repeat(beams, rolls, 0), np.tile(roll, len(beams)))


def _robust_one(
    prob: Problem,
    h: np.ndarray,
    opts: SolverOptions,
    extra: _State | None = None,
    nominal_beam: np.ndarray | None = None,
) -> Pose:
    """Multi-start solve of the single image in ``prob`` (B = 1)."""
    S = opts.starts
    # SPEC §1: the fiducial sits about 2/3 of the source-detector distance from the source
    depth_prior = 2.0 / 3.0 * float(prob.intr[0, 0] * prob.pix[0])
    rots = so3.spread_rotations(S)
    if nominal_beam is not None:
        rots = np.concatenate([rots, view_seeds(nominal_beam)], 0)
    R0, t0 = multistart_seeds(prob, rots, depth_prior)
    if extra is not None:
        R0 = np.concatenate([R0, extra.R], 0)
        t0 = np.concatenate([t0, extra.t], 0)
    rep = prob.take(np.zeros(len(R0), int))
    st = levenberg_marquardt(rep, R0, t0, h, opts.explore_iterations)
    order = np.argsort(st.cost)
    finite = order[np.isfinite(st.cost[order])]
    if finite.size == 0:
        return _finish(
            prob,
            _evaluate_state(prob, R0[:1], t0[:1])[0],
            0,
            h,
            opts,
            len(R0),
            "no start led to a pose with every feature in front of the source",
        )
    # polish the best few distinct candidates to full convergence
    keep: list[int] = []
    for i in finite:
        if len(keep) >= 6:
            break
        if all(so3.angle(st.R[i], st.R[j]) > 1e-3 or np.linalg.norm(st.t[i] - st.t[j]) > 1e-2 for j in keep):
            keep.append(int(i))
    k = np.array(keep)
    sub = rep.take(np.zeros(len(k), int))
    st2 = st.rows(k)
    st2.converged[:] = False
    st2 = levenberg_marquardt(sub, st2.R, st2.t, h, opts.max_iterations, st2)
    best = int(np.argmin(st2.cost))
    pose = _finish(sub, st2, best, h, opts, len(R0))
    pose.iterations = int(st2.iters[best]) + opts.explore_iterations
    if pose.converged:
        # another converged minimum, far away, that fits as well: the image cannot tell them apart
        kappa2 = max(pose.noise_scale**2, 1e-30) if math.isfinite(pose.noise_scale) else 1.0
        for j in range(len(k)):
            if j == best or not st2.converged[j] or not math.isfinite(st2.cost[j]):
                continue
            dchi2 = (st2.cost[j] - st2.cost[best]) / max(kappa2, 1.0)
            dang = math.degrees(float(so3.angle(st2.R[j], st2.R[best])))
            dt = float(np.linalg.norm(st2.t[j] - st2.t[best]))
            if dchi2 < opts.ambiguity_chi2 and (
                dang > opts.ambiguity_rotation_deg or dt > opts.ambiguity_translation_mm
            ):
                pose.converged = False
                pose.error = (
                    f"ambiguous: another pose {dang:.1f}° and {dt:.1f} mm away fits the image "
                    f"equally well (Δχ² = {dchi2:.2g}); observe more features"
                )
                break
    return pose


def solve_problem(prob: Problem, features: Features, opts: SolverOptions | None = None) -> list[Pose]:
    """Solve every image of a compiled batch; see the module docstring for the strategy."""
    opts = opts or _DEFAULTS
    h = parameter_scale(features)
    why = _underdetermined(prob)
    if why:
        return _unsolved(prob, why)
    results: list[Pose | None] = [None] * prob.B
    start = dlt_start(prob) if opts.closed_form_start else None
    if start is not None:
        start = refine_on_beads(prob, *start, h)
    st = None
    retry: list[int] = list(range(prob.B))
    if start is not None:
        st = levenberg_marquardt(prob, start[0], start[1], h, opts.max_iterations, eager=True)
        retry = []
        for i, p in enumerate(_finish_all(prob, st, h, opts, 1)):
            results[i] = p
            if _suspect(p, opts):
                retry.append(i)
        if retry:
            # the paper's two phases (§II.B.7) from the closed-form start: beads first, whose
            # residuals are smooth everywhere, then every feature from there
            idx = np.array(retry)
            sub = prob.take(idx)
            pts = levenberg_marquardt(sub.points_only(), start[0][idx], start[1][idx], h, 10)
            st2 = levenberg_marquardt(sub, pts.R, pts.t, h, opts.max_iterations)
            still = []
            for k, (i, p) in enumerate(zip(retry, _finish_all(sub, st2, h, opts, 1))):
                p.iterations += int(pts.iters[k]) + int(st.iters[i])
                if _better(p, results[i]):
                    results[i] = p
                    st.R[i], st.t[i], st.cost[i] = st2.R[k], st2.t[k], st2.cost[k]
                if _suspect(results[i], opts):
                    still.append(i)
            retry = still
    for i in retry:
        one = prob.take(np.array([i]))
        extra = st.rows(np.array([i])) if st is not None and np.isfinite(st.cost[i]) else None
        p = _robust_one(one, h, opts, extra, features.nominal_beam_direction)
        if results[i] is None or _better(p, results[i]) or (p.error or "").startswith("ambiguous"):
            results[i] = p
    return results  # type: ignore[return-value]


def _suspect(p: Pose, opts: SolverOptions) -> bool:
    """Whether a local solve's answer needs the careful path before it is believed."""
    return (
        not p.converged
        or not p.residual_p_value >= opts.retry_p_value
        or not p.condition_number <= opts.retry_condition
    )


def _better(a: Pose, b: Pose | None) -> bool:
    """Whether solution ``a`` is better than ``b``: a converged one beats one that is not
    (an unconverged iterate can sit at a lower cost on its way somewhere else); otherwise
    the one that fits its image better."""
    if b is None:
        return True
    if a.converged != b.converged:
        return a.converged
    ka = a.noise_scale if math.isfinite(a.noise_scale) else math.inf
    kb = b.noise_scale if math.isfinite(b.noise_scale) else math.inf
    return ka < kb


def solve_batch(
    features: Features, observations: Iterable[Observation], options: SolverOptions | None = None
) -> list[Pose]:
    """Poses for many images, in input order; images that observed the same features the
    same way are compiled and solved together (vectorised)."""
    opts = options or _DEFAULTS
    obs = list(observations)
    groups: dict[tuple, list[int]] = {}
    if len(obs) == 1:
        groups[()] = [0]
    else:
        for i, o in enumerate(obs):
            groups.setdefault(o.structure, []).append(i)
    out: list[Pose | None] = [None] * len(obs)
    for idx in groups.values():
        prob = compile_problem(
            features,
            [obs[i] for i in idx],
            opts.noise,
            opts.ellipse_model_points,
            opts.distance,
            same_structure=True,
            task_scaling=opts.task_scaling,
        )
        try:
            poses = solve_problem(prob, features, opts)
        except np.linalg.LinAlgError as exc:
            # the numerical core refuses rather than raises (observations are range-checked,
            # so this is a last resort): every image of the group is reported unsolved
            poses = _unsolved(prob, f"numerical failure ({exc}); check the observation's coordinates")
        for i, p in zip(idx, poses):
            out[i] = p
    return out  # type: ignore[return-value]


def _unsolved(prob: Problem, why: str) -> list[Pose]:
    """One unconverged pose per image of ``prob`` that says ``why``."""
    nan = np.full(3, np.nan)
    return [
        Pose(
            np.full((3, 3), np.nan),
            nan,
            False,
            float("nan"),
            None,
            {},
            0,
            why,
            origin=prob.origins[i] if prob.origins else "",
        )
        for i in range(prob.B)
    ]


def solve_pose(features: Features, observation: Observation, options: SolverOptions | None = None) -> Pose:
    """The pose of the fiducial in one image: ``P_X = R P_F + t`` (SPEC §1), no initial guess."""
    return solve_batch(features, [observation], options)[0]


def refine_pose(
    features: Features,
    observation: Observation,
    R: np.ndarray,
    t: np.ndarray,
    options: SolverOptions | None = None,
    max_iterations: int | None = None,
) -> Pose:
    """The paper's *basic* algorithm (Fig. 5): one local solve from a given initial pose."""
    opts = options or _DEFAULTS
    prob = compile_problem(
        features, [observation], opts.noise, opts.ellipse_model_points, opts.distance, task_scaling=opts.task_scaling
    )
    why = _underdetermined(prob)
    h = parameter_scale(features)
    st = levenberg_marquardt(
        prob,
        np.asarray(R, float)[None].copy(),
        np.asarray(t, float)[None].copy(),
        h,
        max_iterations or opts.max_iterations,
    )
    return _finish(prob, st, 0, h, opts, 1, why)
