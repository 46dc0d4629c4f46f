"""Residuals and their closed-form Jacobian for a batch of images (paper §II.B.2–5).

A :class:`Problem` holds B images that observed the same features in the same way (points
as pixels, curves as contour points or as coefficients), compiled into arrays. For poses
``R`` (B, 3, 3), ``t`` (B, 3) — ``P_X = R P_F + t`` — :func:`evaluate` returns

- the raw residuals in pixels, as in the paper: point reprojection errors (Eqs. 3–4);
  signed distances of the projected line end-points to the observed line (Eq. 5); signed
  distances of K projected model points of each ellipse to the observed conic — Sampson's
  first-order distance ``Q / |∇Q|`` by default, or the paper's ``K · PᵀMP`` (Eq. 8);
- the whitened residual ρ = G r and its Jacobian ∂ρ/∂(δ, t), where δ is a rotation vector
  applied on the left (``R ← exp([δ]ₓ) R``, rotation about the fiducial origin, camera axes).

Task-variable scaling G (paper Eq. 17) is the Gauss–Markov whitening: points are divided by
their σ; for a curve, the distances r are mapped to the curve-parameter change they imply,
``D⁺ r`` with ``D = ∂r/∂(curve parameters)``, and whitened by the observed curve's own
information Λ (from its contour fit): ``ρ = chol(Λ)ᵀ D⁺ r``. Then ``|ρ|²`` is the
Mahalanobis distance between the projected model curve and the observed one, to first
order, and the least-squares pose is the maximum-likelihood one. When a curve is given only
by coefficients its information is unknown; then ``Λ = DᵀD / σ²``, which is the paper's
fallback of a diagonal G with 1/σ per distance, restricted to what the curve can tell.

Parameter scaling H (paper Eq. 17) is applied by the solver and the analysis, not here.
All arrays are float64; lengths in mm (F and X frames), image quantities in pixels.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field, fields

import numpy as np

from ..errors import InputError
from ..features.model import Features
from .fitting import (
    ConicFit,
    conic_center_and_axes,
    conic_from_coefficients,
    conic_matrix,
    fit_conic,
    fit_line,
    line_from_coefficients,
)
from .observation import Observation
from .smallmat import spd_solve

#: the paper's 12 model points per ellipse (§II.B.2); with Gauss–Markov whitening any
#: number ≥ 5 spread around the ellipse gives the same answer to first order
ELLIPSE_MODEL_POINTS = 12


@dataclass(frozen=True)
class NoiseModel:
    """Segmentation noise: standard deviation per image axis at the detector, mm.

    The paper's simulations add an error of uniformly distributed magnitude up to e in a
    uniformly random direction, whose per-axis standard deviation is ``e / √6``: the default
    0.102 mm is its 0.25 mm. Contour points carry the same σ along the curve normal.
    Only the ratios between feature types change the pose estimate; the absolute scale is
    re-estimated from the residuals for the covariance.

    ``points`` gives named beads their own σ (mm), overriding ``point_mm``: an image's balls
    are not measured equally well (one overlapped by a wire or a needle fits worse than its
    fellows), and weighting each by its own σ keeps a poor one from pulling the pose.
    """

    point_mm: float = 0.25 / 6**0.5
    line_mm: float = 0.25 / 6**0.5
    ellipse_mm: float = 0.25 / 6**0.5
    #: (bead id, σ mm) pairs for the beads whose σ is not ``point_mm``
    points: tuple[tuple[str, float], ...] = ()

    def point_sigma_mm(self, fid: str) -> float:
        """The σ (mm at the detector, per axis) of bead ``fid``."""
        return dict(self.points).get(fid, self.point_mm)

    @classmethod
    def from_segmentation_error(cls, e_mm: float) -> "NoiseModel":
        """σ for the paper's uniform error of maximum magnitude ``e_mm`` on every feature."""
        s = max(e_mm, 1e-6) / 6**0.5
        return cls(s, s, s)

    def scaled(self, bead: float = 1.0, wire: float = 1.0) -> "NoiseModel":
        """Beads' σ times ``bead``, line and ellipse contours' times ``wire``."""
        return NoiseModel(
            self.point_mm * bead,
            self.line_mm * wire,
            self.ellipse_mm * wire,
            tuple((fid, sig * bead) for fid, sig in self.points),
        )


@dataclass
class Problem:
    """B images with one observation structure, as arrays (see module docstring)."""

    intr: np.ndarray  # (B, 4) fx, fy, ox, oy
    X: np.ndarray  # (M, 3) model points: beads, line ends, ellipse samples
    point_ids: list[str]
    line_ids: list[str]
    ellipse_ids: list[str]
    K: int  # model points per ellipse
    p_obs: np.ndarray  # (B, P, 2)
    p_w: np.ndarray  # (B, P) 1/σ
    l_n: np.ndarray  # (B, L, 2)
    l_m: np.ndarray  # (B, L, 2)
    l_c: np.ndarray  # (B, L)
    l_info: np.ndarray  # (B, L, 2, 2) already divided by σ²
    l_from_model: np.ndarray  # (L,) bool: Λ = DᵀD/σ²
    l_sig: np.ndarray  # (B, L) σ px
    e_theta: np.ndarray  # (B, E, 6)
    e_m: np.ndarray  # (B, E, 2)
    e_s: np.ndarray  # (B, E)
    e_basis: np.ndarray  # (B, E, 6, 5)
    e_info: np.ndarray  # (B, E, 5, 5) already divided by σ²
    e_from_model: np.ndarray  # (E,) bool
    e_sig: np.ndarray  # (B, E) σ px
    e_kpaper: np.ndarray  # (B, E) the paper's K (Eq. 8), normalised units
    distance: str = "sampson"
    fit_chi2: np.ndarray = field(default_factory=lambda: np.zeros(1))  # (B,) Σ rss/σ² of the fits
    fit_dof: np.ndarray = field(default_factory=lambda: np.zeros(1))  # (B,)
    origins: list[str] = field(default_factory=list)
    pix: np.ndarray = field(default_factory=lambda: np.full(1, 0.44))  # (B,) mm per pixel
    # Cholesky factors Lᵀ of the fitted curves' information (NaN where it comes from the
    # model): constant per image, so factored once here rather than in every evaluation
    l_Lt: np.ndarray = field(init=False, repr=False)
    e_Lt: np.ndarray = field(init=False, repr=False)
    p_w2: np.ndarray = field(init=False, repr=False)
    row_points: np.ndarray = field(init=False, repr=False)
    # the observed conics as ∇²Q, (D, E), F and their tangent basis against (x, y, 1)⊗(x, y, 1)
    e_hess: np.ndarray = field(init=False, repr=False)
    e_lin: np.ndarray = field(init=False, repr=False)
    e_F: np.ndarray = field(init=False, repr=False)
    e_basis9: np.ndarray = field(init=False, repr=False)
    # ∂r/∂(u, v) (B, 2P + 2L, 2) of the bead and line residuals, which do not depend on the pose
    fixed_cuv: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self.l_Lt = _factor(self.l_info, self.l_from_model)
        self.e_Lt = _factor(self.e_info, self.e_from_model)
        self.p_w2 = np.repeat(self.p_w, 2, 1)[..., None]
        P, L, E = len(self.point_ids), len(self.line_ids), len(self.ellipse_ids)
        self.row_points, bead_cuv = _row_layout(P, L, E, self.K)
        B = self.intr.shape[0]
        th = self.e_theta
        self.e_hess = th[..., _HESS_TERMS] * _HESS_SCALE  # (B, E, 2, 2)
        self.e_lin = th[..., None, 3:5]  # (B, E, 1, 2)
        self.e_F = th[..., 5:6]  # (B, E, 1)
        self.e_basis9 = self.e_basis[..., _XI_FROM_OUTER, :] * _XI_OUTER_MASK
        self.fixed_cuv = np.concatenate([np.broadcast_to(bead_cuv, (B, 2 * P, 2)), np.repeat(self.l_n, 2, 1)], 1)
        self._coplanar: bool | None = None

    @property
    def points_coplanar(self) -> bool:
        """Whether the observed beads are (nearly) coplanar — then a DLT cannot start the solve."""
        if self._coplanar is None:
            self._coplanar = _coplanar(self.X[: len(self.point_ids)])
        return self._coplanar

    @property
    def B(self) -> int:
        return self.intr.shape[0]

    @property
    def n_rows(self) -> int:
        """Whitened residuals per image: 2 per point, 2 per line, 5 per ellipse."""
        return 2 * len(self.point_ids) + 2 * len(self.line_ids) + 5 * len(self.ellipse_ids)

    @property
    def n_constraints(self) -> int:
        return self.n_rows

    def row_groups(self) -> list[tuple[str, slice]]:
        """(feature id, slice of whitened rows) in row order."""
        out, i = [], 0
        for ids, k in ((self.point_ids, 2), (self.line_ids, 2), (self.ellipse_ids, 5)):
            for fid in ids:
                out.append((fid, slice(i, i + k)))
                i += k
        return out

    def raw_groups(self) -> list[tuple[str, slice]]:
        """(feature id, slice of raw pixel residuals) in raw order."""
        ids, first, count = self.raw_index
        return [(fid, slice(int(a), int(a + n))) for fid, a, n in zip(ids, first, count)]

    @property
    def raw_index(self) -> tuple[tuple[str, ...], np.ndarray, np.ndarray]:
        """Feature ids in raw-residual order, with each one's first raw row and row count."""
        return _raw_index(tuple(self.point_ids), tuple(self.line_ids), tuple(self.ellipse_ids), self.K)

    def _init_kwargs(self) -> dict:
        return {f.name: getattr(self, f.name) for f in fields(self) if f.init}

    def points_only(self) -> "Problem":
        """The same images with only the beads kept (the paper's first phase, §II.B.7)."""
        P = len(self.point_ids)
        kw = self._init_kwargs()
        kw.update(
            X=self.X[:P],
            line_ids=[],
            ellipse_ids=[],
            l_n=self.l_n[:, :0],
            l_m=self.l_m[:, :0],
            l_c=self.l_c[:, :0],
            l_info=self.l_info[:, :0],
            l_from_model=self.l_from_model[:0],
            l_sig=self.l_sig[:, :0],
            e_theta=self.e_theta[:, :0],
            e_m=self.e_m[:, :0],
            e_s=self.e_s[:, :0],
            e_basis=self.e_basis[:, :0],
            e_info=self.e_info[:, :0],
            e_from_model=self.e_from_model[:0],
            e_sig=self.e_sig[:, :0],
            e_kpaper=self.e_kpaper[:, :0],
        )
        return Problem(**kw)

    def take(self, idx: np.ndarray) -> "Problem":
        """Rows ``idx`` of the batch (e.g. one image repeated once per start)."""
        idx = np.asarray(idx)
        kw = {}
        for name, val in self._init_kwargs().items():
            if (
                isinstance(val, np.ndarray)
                and name not in ("X", "l_from_model", "e_from_model")
                and val.ndim >= 1
                and val.shape[0] == self.B
            ):
                kw[name] = val[idx]
            else:
                kw[name] = val
        kw["origins"] = [self.origins[i] for i in idx] if self.origins else []
        return Problem(**kw)


@functools.lru_cache(maxsize=64)
def _raw_index(point_ids: tuple, line_ids: tuple, ellipse_ids: tuple, K: int):
    ids = (*point_ids, *line_ids, *ellipse_ids)  # a tuple: the cached value is shared
    count = np.array([2] * (len(point_ids) + len(line_ids)) + [K] * len(ellipse_ids), float)
    first = np.concatenate([[0], np.cumsum(count)[:-1]]).astype(int) if ids else np.zeros(0, int)
    return ids, first, count


@functools.lru_cache(maxsize=64)
def bead_rows(P: int) -> tuple[np.ndarray, np.ndarray]:
    """For P beads' residuals (u₀, v₀, u₁, …): the bead each is measured at, and
    ∂r/∂(u, v) (2P, 2)."""
    return np.repeat(np.arange(P), 2), np.tile(np.eye(2), (P, 1))


@functools.lru_cache(maxsize=64)
def _row_layout(P: int, L: int, E: int, K: int) -> tuple[np.ndarray, np.ndarray]:
    """The model point each raw residual is measured at — beads twice (u, v), then the line
    end-points, then the ellipse model points — and ∂r/∂(u, v) of the bead rows."""
    rows, cuv = bead_rows(P)
    return np.concatenate([rows, np.arange(P, P + 2 * L + E * K)]), cuv


#: the flattened (x, y, 1)⊗(x, y, 1) term each of ξ = (x², xy, y², x, y, 1) takes (the
#: other three terms repeat xy, x, y and get zero rows)
_XI_FROM_OUTER = [0, 1, 3, 0, 2, 4, 0, 0, 5]
_XI_OUTER_MASK = np.array([1.0, 1.0, 1.0, 0.0, 1.0, 1.0, 0.0, 0.0, 1.0])[:, None]
#: ∇²Q = [[2A, B], [B, 2C]] from θ = (A, B, C, D, E, F)
_HESS_TERMS = np.array([[0, 1], [1, 2]])
_HESS_SCALE = np.array([[2.0, 1.0], [1.0, 2.0]])


def _factor(info: np.ndarray, from_model: np.ndarray) -> np.ndarray:
    """Lᵀ with Λ = L Lᵀ for the feature columns whose Λ is known, NaN elsewhere."""
    known = ~from_model
    if info.shape[0] and info.shape[1] and known.all():
        return np.swapaxes(np.linalg.cholesky(info), -1, -2)
    out = np.full(info.shape, np.nan)
    if info.shape[0] and known.any():
        out[:, known] = np.swapaxes(np.linalg.cholesky(info[:, known]), -1, -2)
    return out


# --------------------------------------------------------------------------- compilation
#: model-point layouts already built, per (features object, observed ids, K): the same
#: fiducial is solved image after image, so the layout is made once
_LAYOUTS: dict[tuple, tuple[Features, np.ndarray, bool]] = {}


def model_layout(features: Features, point_ids, line_ids, ellipse_ids, K: int) -> tuple[np.ndarray, bool]:
    """Model points (M, 3) in the solver's order, and whether the beads are (nearly)
    coplanar — then a DLT cannot start the solve."""
    key = (id(features), tuple(point_ids), tuple(line_ids), tuple(ellipse_ids), K)
    hit = _LAYOUTS.get(key)
    if hit is not None and hit[0] is features:
        return hit[1], hit[2]
    X = _model_points(features, point_ids, line_ids, ellipse_ids, K)
    coplanar = _coplanar(X[: len(point_ids)])
    if len(_LAYOUTS) > 256:
        _LAYOUTS.clear()
    _LAYOUTS[key] = (features, X, coplanar)
    return X, coplanar


def _coplanar(Xp: np.ndarray) -> bool:
    """Whether bead centres (P, 3) are fewer than 4 or (nearly) on one plane."""
    if len(Xp) < 4:
        return True
    sv = np.linalg.svd(Xp - Xp.mean(0), compute_uv=False)
    return bool(sv[2] < 1e-3 * sv[0])


def _model_points(features: Features, point_ids, line_ids, ellipse_ids, K: int) -> np.ndarray:
    pts = {p.id: p.center for p in features.points}
    lns = {ln.id: ln for ln in features.lines}
    els = {e.id: e for e in features.ellipses}
    s = np.linspace(0.0, 2 * np.pi, K, endpoint=False)
    X = [pts[i] for i in point_ids]
    for i in line_ids:
        X += [lns[i].start, lns[i].end]
    for i in ellipse_ids:
        X += list(els[i].sample(s))
    return np.asarray(X, float).reshape(-1, 3)


def _check_ids(features: Features, obs: Observation) -> None:
    kinds = {
        "points": {p.id for p in features.points},
        "lines": {ln.id for ln in features.lines},
        "ellipses": {e.id for e in features.ellipses},
    }
    for sec in ("points", "lines", "ellipses"):
        for k in getattr(obs, sec):
            if k not in kinds[sec]:
                known = ", ".join(sorted(kinds[sec])) or "none"
                raise InputError(
                    obs.origin, f"{sec}.{k}", f"the id of a {sec[:-1]} in features.json ({features.name} has: {known})"
                )


def _pad(arrays: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    n = max(len(a) for a in arrays)
    if all(len(a) == n for a in arrays):
        return np.array(arrays, float), np.ones((len(arrays), n))
    out = np.zeros((len(arrays), n, 2))
    w = np.zeros((len(arrays), n))
    for i, a in enumerate(arrays):
        out[i, : len(a)] = a
        w[i, : len(a)] = 1.0
        out[i, len(a) :] = a[0]  # padding repeats a real point so normalisation stays finite
    return out, w


def _fit_batch(fitter, contours: list[np.ndarray], origins: list[str], keys: list[str], what: str):
    pts, w = _pad(contours)
    n = len(contours)
    with np.errstate(all="ignore"):
        try:
            fit = fitter(pts, w)
            info = fit.info.reshape((n,) + fit.info.shape[-2:])
            # the curve must be pinned down in every direction (points spread along it): a
            # Cholesky factor exists with a diagonal well above rounding (NaN fails the test)
            try:
                dg = np.diagonal(np.linalg.cholesky(info), axis1=-2, axis2=-1)
                bad = ~(dg.min(-1) > 1e-6 * dg.max(-1))
            except np.linalg.LinAlgError:
                bad = ~np.isfinite(info).all((-2, -1))
                if not bad.any():
                    ev = np.linalg.eigvalsh(info)
                    bad = ~(ev[:, 0] > 1e-12 * np.abs(ev[:, -1]))
        except np.linalg.LinAlgError:
            bad = np.ones(n, bool)
            fit = None
        if isinstance(fit, ConicFit):
            # collinear points fit a double line that can pass the information test by
            # rounding alone (whether it does depends on the LAPACK build), so ask for it
            # directly: the points must spread across their line. (A very noisy, nearly
            # edge-on ellipse may legitimately fit as a thin hyperbola; that is the
            # solver's to down-weight, not an input error.)
            q = pts - fit.center[..., None, :]
            S = np.swapaxes(q * w[..., None], -1, -2) @ q
            tr = S[..., 0, 0] + S[..., 1, 1]
            bad |= ~(S[..., 0, 0] * S[..., 1, 1] - S[..., 0, 1] ** 2 > 1e-12 * tr * tr)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise InputError(origins[i], keys[i], f"contour points that determine {what} (collinear or repeated points?)")
    return fit


#: an ellipse whose projected semi-minor axis is below this many σ is down-weighted
THIN_ELLIPSE_SIGMAS = 3.0


def thin_ellipse_weight(fit: ConicFit, sigma_px: np.ndarray) -> np.ndarray:
    """Weight ≤ 1 for fitted ellipses seen nearly edge-on (paper §II.A.2's blind spot).

    When the semi-minor axis b of the projected ellipse is not large against the contour
    noise σ, the ends of the ellipse curve more tightly (radius b²/a) than the noise, the
    first-order (Sampson) fit and its information matrix stop being valid, and the fit
    claims an accuracy it does not have. Its information is scaled by (b / 3σ)² below
    b = 3σ, so a nearly edge-on ellipse informs the pose only as far as it can.
    """
    b_px = semi_minor(fit.theta) * fit.scale
    w = (b_px / (THIN_ELLIPSE_SIGMAS * sigma_px)) ** 2
    return np.where(np.isfinite(w), np.minimum(w, 1.0), 1.0)


def semi_minor(theta: np.ndarray) -> np.ndarray:
    """Semi-minor axis of ellipses θ (...), in θ's coordinates (closed form, no solves)."""
    A, B, C, D, E, F = np.moveaxis(theta, -1, 0)
    det2 = 4 * A * C - B * B  # > 0 for an ellipse
    # value of the conic at its centre: F0 = F − (A E² − B D E + C D²) / det2
    F0 = F - (A * E * E - B * D * E + C * D * D) / det2
    root = np.sqrt((A - C) ** 2 + B * B)
    lam_big = np.maximum(np.abs((A + C + root) / 2), np.abs((A + C - root) / 2))
    with np.errstate(all="ignore"):
        return np.sqrt(np.abs(F0 / lam_big))


def paper_k(theta: np.ndarray) -> np.ndarray:
    """The paper's scale K = ab(AC − B²/4) / (2 √(a² + b²) det M) (Eq. 8), in θ's units."""
    M = conic_matrix(theta)
    _, a, b = conic_center_and_axes(theta)
    A, B, C = theta[..., 0], theta[..., 1], theta[..., 2]
    return a * b * (A * C - B * B / 4) / (2 * np.sqrt(a * a + b * b) * np.linalg.det(M))


#: the last few compilations of one observation (:func:`compile_problem`): (key, features, noise, problem)
_COMPILED: list = []


def _content(o: Observation) -> tuple:
    """What of ``o`` a compiled problem depends on, as a hashable key (its arrays' bytes)."""

    def arr(v) -> tuple:
        a = np.asarray(v)
        return (a.dtype.str, a.shape, a.tobytes())

    def curves(d: dict) -> tuple:
        return tuple(
            (k, None if c.points is None else arr(c.points), None if c.coefficients is None else arr(c.coefficients))
            for k, c in sorted(d.items())
        )

    points = tuple((k, arr(v)) for k, v in sorted(o.points.items()))
    return (o.camera, o.origin, points, curves(o.lines), curves(o.ellipses))


def compile_problem(
    features: Features,
    observations: list[Observation],
    noise: NoiseModel | None = None,
    ellipse_model_points: int = ELLIPSE_MODEL_POINTS,
    distance: str = "sampson",
    same_structure: bool = False,
    task_scaling: str = "gauss-markov",
) -> Problem:
    """Arrays for a batch of observations sharing one :attr:`Observation.structure`.

    Fits every contour (batched), checks ids against ``features`` and raises
    :class:`InputError` (file, key, expected) on anything the solver cannot use.
    ``task_scaling="diagonal"`` ignores the fitted curves' covariances and weights every
    distance by 1/σ, the paper's fallback G (kept for comparison).

    The last few compilations of one observation are remembered by its contents (the same
    ``features`` and ``noise`` objects): a labelling's solve, its per-feature tests and its
    score compile the same observation, and each compilation fits every contour again
    (~1 ms of a run's frame). The problem returned is shared and is not to be changed. A
    batch (the optimiser's, the covariance's displaced copies) is compiled every time.
    """
    key = None
    if len(observations) == 1:
        try:
            key = (_content(observations[0]), ellipse_model_points, distance, same_structure, task_scaling)
            hash(key)
        except TypeError:  # an observation with unhashable parts: compiled every time
            key = None
    if key is not None:
        for k, f, n, prob in list(_COMPILED):
            if f is features and n is noise and k == key:
                return prob
    prob = _compiled(features, observations, noise, ellipse_model_points, distance, same_structure, task_scaling)
    if key is not None:
        _COMPILED[:] = [*_COMPILED[-3:], (key, features, noise, prob)]
    return prob


def _compiled(
    features: Features,
    observations: list[Observation],
    noise: NoiseModel | None,
    ellipse_model_points: int,
    distance: str,
    same_structure: bool,
    task_scaling: str,
) -> Problem:
    if distance not in ("sampson", "paper"):
        raise ValueError(f"distance must be 'sampson' or 'paper', not {distance!r}")
    if task_scaling not in ("gauss-markov", "diagonal"):
        raise ValueError(f"task_scaling must be 'gauss-markov' or 'diagonal', not {task_scaling!r}")
    noise = noise or NoiseModel()
    obs0 = observations[0]
    _check_ids(features, obs0)
    if not same_structure:  # the caller may vouch for it (solve_batch groups by structure)
        s0 = obs0.structure
        for o in observations[1:]:
            if o.structure != s0:
                raise ValueError("compile_problem needs observations of one structure; group them first")
    B = len(observations)
    origins = [o.origin for o in observations]
    point_ids = sorted(obs0.points)
    line_ids = sorted(obs0.lines)
    ellipse_ids = sorted(obs0.ellipses)
    K = int(ellipse_model_points)
    X, coplanar = model_layout(features, point_ids, line_ids, ellipse_ids, K)
    intr = np.array([o.camera.intrinsics for o in observations])
    pix = np.array([(o.camera.pixel_size_mm[0] + o.camera.pixel_size_mm[1]) / 2 for o in observations])

    P, E = len(point_ids), len(ellipse_ids)
    p_obs = np.array([[o.points[i] for i in point_ids] for o in observations]).reshape(B, P, 2)
    p_w = pix[:, None] / np.array([noise.point_sigma_mm(fid) for fid in point_ids], float).reshape(1, P)
    l_n, l_m, l_c, l_info, l_from_model, l_sig, l_chi2, l_dof = _line_arrays(
        observations, line_ids, noise.line_mm / pix, intr, task_scaling
    )
    e_theta, e_m, e_s, e_basis, e_info, e_from_model, e_sig, e_chi2, e_dof = _ellipse_arrays(
        observations, ellipse_ids, noise.ellipse_mm / pix, task_scaling
    )
    fit_chi2, fit_dof = l_chi2 + e_chi2, l_dof + e_dof
    e_kpaper = paper_k(e_theta) if E and distance == "paper" else np.zeros((B, E))
    prob = Problem(
        intr,
        X,
        point_ids,
        line_ids,
        ellipse_ids,
        K,
        p_obs,
        p_w,
        l_n,
        l_m,
        l_c,
        l_info,
        l_from_model,
        l_sig,
        e_theta,
        e_m,
        e_s,
        e_basis,
        e_info,
        e_from_model,
        e_sig,
        e_kpaper,
        distance,
        fit_chi2,
        fit_dof,
        origins,
        pix,
    )
    prob._coplanar = coplanar
    return prob


def _fit_section(observations: list[Observation], section: str, ids: list[str], fitter, what: str):
    """Fit every contour-given curve of ``section`` ("lines", "ellipses") in one batched call:
    the columns of ``ids`` fitted (a slice when every curve is contour-given, the usual case,
    indexing without a copy) and the (B·n) results, or ([], None)."""
    obs0 = observations[0]
    cols = [j for j, fid in enumerate(ids) if getattr(obs0, section)[fid].points is not None]
    if not cols:
        return cols, None
    contours = [getattr(o, section)[ids[j]].points for o in observations for j in cols]
    keys = [f"{section}.{ids[j]}.points" for _ in observations for j in cols]
    org = [o.origin for o in observations for _ in cols]
    fit = _fit_batch(fitter, contours, org, keys, what)
    return (slice(None) if len(cols) == len(ids) else cols), fit


def _line_arrays(observations: list[Observation], line_ids: list[str], sigma: np.ndarray, intr, task_scaling: str):
    """The lines' arrays of :class:`Problem` (normal, anchor, offset, information, whether the
    whitening comes from the model, σ px) and their fits' χ² and degrees of freedom (B,);
    ``sigma`` (B,) the line noise in px."""
    B, L = len(observations), len(line_ids)
    chi2, dof = np.zeros(B), np.zeros(B)
    l_n, l_m, l_c = np.zeros((B, L, 2)), np.zeros((B, L, 2)), np.zeros((B, L))
    l_info, l_from_model = np.full((B, L, 2, 2), np.nan), np.ones(L, bool)
    l_sig = np.repeat(sigma[:, None], L, 1)
    cols, fit = _fit_section(observations, "lines", line_ids, fit_line, "a line")
    if fit is not None:
        n = fit.normal.size // (2 * B)
        l_n[:, cols] = fit.normal.reshape(B, n, 2)
        l_m[:, cols] = fit.anchor.reshape(B, n, 2)
        l_info[:, cols] = fit.info.reshape(B, n, 2, 2) / l_sig[:, cols, None, None] ** 2
        chi2 += (fit.rss.reshape(B, n) / l_sig[:, cols] ** 2).sum(1)
        dof += fit.dof.reshape(B, n).sum(1)
        l_from_model[cols] = task_scaling == "diagonal"
    for j in np.flatnonzero(l_from_model):
        if observations[0].lines[line_ids[j]].points is not None:
            continue
        lf = line_from_coefficients(np.array([o.lines[line_ids[j]].coefficients for o in observations]), intr[:, 2:4])
        l_n[:, j], l_m[:, j], l_c[:, j] = lf.normal, lf.anchor, lf.offset
    return l_n, l_m, l_c, l_info, l_from_model, l_sig, chi2, dof


def _ellipse_arrays(observations: list[Observation], ellipse_ids: list[str], sigma: np.ndarray, task_scaling: str):
    """The ellipses' arrays of :class:`Problem` (conic, centre, scale, basis, information,
    whether the whitening comes from the model, σ px) and their fits' χ² and degrees of
    freedom (B,); ``sigma`` (B,) the ellipse noise in px."""
    B, E = len(observations), len(ellipse_ids)
    chi2, dof = np.zeros(B), np.zeros(B)
    e_theta, e_m, e_s = np.zeros((B, E, 6)), np.zeros((B, E, 2)), np.ones((B, E))
    e_basis, e_info = np.zeros((B, E, 6, 5)), np.full((B, E, 5, 5), np.nan)
    e_from_model = np.ones(E, bool)
    e_sig = np.repeat(sigma[:, None], E, 1)
    cols, cf = _fit_section(observations, "ellipses", ellipse_ids, fit_conic, "an ellipse")
    if cf is not None:
        n = cf.scale.size // B
        e_theta[:, cols] = cf.theta.reshape(B, n, 6)
        e_m[:, cols] = cf.center.reshape(B, n, 2)
        e_s[:, cols] = cf.scale.reshape(B, n)
        e_basis[:, cols] = cf.basis.reshape(B, n, 6, 5)
        e_info[:, cols] = (
            cf.info.reshape(B, n, 5, 5)
            / e_sig[:, cols, None, None] ** 2
            * thin_ellipse_weight(cf, e_sig[:, cols].reshape(-1)).reshape(B, n, 1, 1)
        )
        chi2 += (cf.rss.reshape(B, n) / e_sig[:, cols] ** 2).sum(1)
        dof += cf.dof.reshape(B, n).sum(1)
        e_from_model[cols] = task_scaling == "diagonal"
    for j in np.flatnonzero(e_from_model):
        if observations[0].ellipses[ellipse_ids[j]].points is not None:
            continue
        cc = conic_from_coefficients(np.array([o.ellipses[ellipse_ids[j]].coefficients for o in observations]))
        e_theta[:, j], e_m[:, j], e_s[:, j], e_basis[:, j] = cc.theta, cc.center, cc.scale, cc.basis
    return e_theta, e_m, e_s, e_basis, e_info, e_from_model, e_sig, chi2, dof


# --------------------------------------------------------------------------- evaluation
@dataclass
class Evaluation:
    """Everything :func:`evaluate` computes at poses (B, 3, 3), (B, 3).

    ``raw`` (B, n_raw) px are the paper's residuals and ``raw_jac`` (B, n_raw, 6) their exact
    closed-form derivatives w.r.t. (δ, t); ``W`` maps them to the whitened residuals
    ``rho = W raw`` (B, m) with ``J = W raw_jac`` (B, m, 6). ``W`` depends on the pose (the
    whitening is evaluated where the model points project) and is held fixed within a
    solver iteration, like the paper's constant G; ``J`` is the exact Jacobian of
    ``W_fixed · raw``. ``Z`` (B, M) are the model points' depths, mm.
    """

    rho: np.ndarray
    J: np.ndarray | None
    raw: np.ndarray
    raw_jac: np.ndarray | None
    W: list[np.ndarray]
    Z: np.ndarray
    #: the residuals whitened with a reference ``W`` (see :func:`evaluate`), else None
    rho_ref: np.ndarray | None = None


def project(prob: Problem, R: np.ndarray, t: np.ndarray):
    """Pixels (B, M, 2) of every model point and what their Jacobians need: the rotated
    model points Q = R P_F (B, M, 3), normalised coordinates x, y and f/Z (B, M)."""
    return project_points(prob.X, prob.intr, R, t)


def project_points(X: np.ndarray, intr: np.ndarray, R: np.ndarray, t: np.ndarray):
    """Pixels (B, M, 2) of points X (M, 3) mm in F at poses (B, 3, 3), (B, 3) seen with
    intrinsics (B, 4) ``fx, fy, ox, oy``; depths Z (B, M) mm; and the projection terms
    :func:`jacobian_rows` needs (Q = R X, x, y, f_x/Z, f_y/Z)."""
    B = R.shape[0]
    # one (3B × 3)(3 × M) product instead of B small ones; component-major, so each
    # coordinate below is a contiguous (B, M) block and Q is a (B, M, 3) view
    Qc = (R.reshape(3 * B, 3) @ np.asarray(X, float).T).reshape(B, 3, -1)
    Q = np.swapaxes(Qc, 1, 2)
    Z = Qc[:, 2] + t[:, 2, None]
    iz = 1.0 / Z
    x = (Qc[:, 0] + t[:, 0, None]) * iz
    y = (Qc[:, 1] + t[:, 1, None]) * iz
    fx = intr[:, 0, None]
    fy = intr[:, 1, None]
    uv = np.empty(x.shape + (2,))
    uv[..., 0] = fx * x + intr[:, 2, None]
    uv[..., 1] = fy * y + intr[:, 3, None]
    return uv, Z, (Q, x, y, fx * iz, fy * iz)


def jacobian_rows(pr, idx: np.ndarray | slice, cu: np.ndarray, cv: np.ndarray, columns: bool = False) -> np.ndarray:
    """∂r/∂(δ, t) (B, n, 6) for residuals r with ∂r/∂(u, v) = (cu, cv) (B, n), each measured
    at model point ``idx[i]`` (a slice selects without copying). ``columns=True`` returns
    the transpose (B, 6, n), contiguous per parameter, for forming JᵀJ.

    With a = ∂r/∂P = (cu f_x/Z, cv f_y/Z, −(cu f_x x + cv f_y y)/Z) in the camera frame, the
    translation part is a and, for the left rotation increment (∂P/∂δ = −[Q]ₓ), the
    rotation part is Q × a — the paper's Eqs. 10–13 in vector form.
    """
    Q, x, y, fxz, fyz = pr
    Q = Q[:, idx]
    ax = cu * fxz[:, idx]
    ay = cv * fyz[:, idx]
    az = -(ax * x[:, idx] + ay * y[:, idx])
    Qx, Qy, Qz = Q[..., 0], Q[..., 1], Q[..., 2]
    if columns:
        Jt = np.empty(ax.shape[:1] + (6,) + ax.shape[1:])
        np.multiply(Qy, az, out=Jt[:, 0])
        Jt[:, 0] -= Qz * ay
        np.multiply(Qz, ax, out=Jt[:, 1])
        Jt[:, 1] -= Qx * az
        np.multiply(Qx, ay, out=Jt[:, 2])
        Jt[:, 2] -= Qy * ax
        Jt[:, 3], Jt[:, 4], Jt[:, 5] = ax, ay, az
        return Jt
    J = np.empty(ax.shape + (6,))
    J[..., 0] = Qy * az - Qz * ay
    J[..., 1] = Qz * ax - Qx * az
    J[..., 2] = Qx * ay - Qy * ax
    J[..., 3] = ax
    J[..., 4] = ay
    J[..., 5] = az
    return J


def _xi_basis(p: np.ndarray, basis9: np.ndarray) -> np.ndarray:
    """ξ(p) · basis (..., K, 5) for points p (..., K, 2), ξ = (x², xy, y², x, y, 1), as the
    outer product of (x, y, 1) with itself against the basis rows spread over its 9 terms."""
    h = np.ones(p.shape[:-1] + (3,))
    h[..., :2] = p
    hh = (h[..., :, None] * h[..., None, :]).reshape(p.shape[:-1] + (9,))
    return hh @ basis9


def rows_where(mask: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Rows of ``a`` where ``mask`` (B,), else of ``b``."""
    return np.where(mask.reshape((-1,) + (1,) * (a.ndim - 1)), a, b)


def _chol_t(info: np.ndarray) -> np.ndarray:
    """Lᵀ for Λ = L Lᵀ (batched)."""
    return np.swapaxes(np.linalg.cholesky(info), -1, -2)


def evaluate(
    prob: Problem,
    R: np.ndarray,
    t: np.ndarray,
    jac: bool = True,
    whitening: list[np.ndarray] | None = None,
    raw_jacobian: bool = False,
    reference: list[np.ndarray] | None = None,
    freeze: np.ndarray | None = None,
) -> Evaluation:
    """Residuals and Jacobians at poses (B, 3, 3), (B, 3); see :class:`Evaluation`.

    ``whitening`` — the ``W`` of an earlier evaluation — freezes G instead of recomputing it;
    with ``freeze`` (B,) bool only those rows keep it and the others get a fresh G.
    ``reference`` — another ``W`` — also returns the residuals whitened with it
    (``rho_ref``), so a solver can judge a trial step on the objective it was computed for.
    """
    uv, Z, pr = project(prob, R, t)
    B = prob.B
    refresh = whitening is None or freeze is not None
    P, L, E, K = len(prob.point_ids), len(prob.line_ids), len(prob.ellipse_ids), prob.K
    rho, Js, raw, Ws, ref = [], [], [], [], []
    cuvs = [prob.fixed_cuv] if P or L else []
    if P:
        d = uv[:, :P] - prob.p_obs
        rho.append((d * prob.p_w[..., None]).reshape(B, 2 * P))
        ref.append(rho[-1])
        raw.append(d.reshape(B, 2 * P))
        Ws.append(prob.p_w)

    if L:
        prev = whitening[len(Ws)] if whitening is not None else None
        r, W = _line_residuals(prob, uv[:, P : P + 2 * L], refresh, prev, freeze)
        if reference is not None:
            ref.append((reference[len(Ws)] @ r[..., None]).reshape(B, 2 * L))
        Ws.append(W)
        rho.append((W @ r[..., None]).reshape(B, 2 * L))
        raw.append(r.reshape(B, 2 * L))
    if E:
        prev = whitening[len(Ws)] if whitening is not None else None
        r, W, duv = _ellipse_residuals(prob, uv[:, P + 2 * L : P + 2 * L + E * K], refresh, jac, prev, freeze)
        if reference is not None:
            ref.append((reference[len(Ws)] @ r[..., None]).reshape(B, 5 * E))
        Ws.append(W)
        rho.append((W @ r[..., None]).reshape(B, 5 * E))
        raw.append(r.reshape(B, E * K))
        if jac:
            cuvs.append(duv.reshape(B, E * K, 2))
    cat = (lambda xs: xs[0]) if len(rho) == 1 else (lambda xs: np.concatenate(xs, 1))
    J = dr = None
    if jac:
        # one pass over every raw residual row: ∂r/∂(δ, t), then each group's whitening
        cuv = cuvs[0] if len(cuvs) == 1 else np.concatenate(cuvs, 1)
        dr = jacobian_rows(pr, prob.row_points, cuv[..., 0], cuv[..., 1])  # (B, n_raw, 6)
        if P:
            Js.append(dr[:, : 2 * P] * prob.p_w2)
        if L:
            Js.append((Ws[1 if P else 0] @ dr[:, 2 * P : 2 * P + 2 * L].reshape(B, L, 2, 6)).reshape(B, 2 * L, 6))
        if E:
            Js.append((Ws[-1] @ dr[:, 2 * P + 2 * L :].reshape(B, E, K, 6)).reshape(B, 5 * E, 6))
        J = cat(Js)
    return Evaluation(
        cat(rho), J, cat(raw), dr if raw_jacobian else None, Ws, Z, cat(ref) if reference is not None else None
    )


def _line_residuals(prob: Problem, uv: np.ndarray, refresh: bool, prev, freeze) -> tuple[np.ndarray, np.ndarray]:
    """The lines' raw residuals (B, L, 2) at their model points' projections ``uv`` (B, 2L, 2)
    and their whitening W (B, L, 2, 2): computed afresh when ``refresh``, where ``freeze`` is
    False (elsewhere ``prev``), else ``prev`` (see :func:`evaluate`)."""
    B, L = prob.B, len(prob.line_ids)
    q = uv.reshape(B, L, 2, 2) - prob.l_m[:, :, None, :]
    nx, ny = prob.l_n[..., 0, None], prob.l_n[..., 1, None]
    r = q[..., 0] * nx + q[..., 1] * ny + prob.l_c[..., None]  # (B, L, 2)
    if not refresh:
        return r, prev
    # D = ∂r/∂(ψ, c) has rows (n⊥·(p − m), 1); W = chol(Λ)ᵀ D⁻¹
    d0 = q[..., 1] * nx - q[..., 0] * ny
    det = d0[..., 0] - d0[..., 1]
    Dinv = np.empty((B, L, 2, 2))
    Dinv[..., 0, 0] = 1.0
    Dinv[..., 0, 1] = -1.0
    Dinv[..., 1, 0] = -d0[..., 1]
    Dinv[..., 1, 1] = d0[..., 0]
    Dinv /= det[..., None, None]
    Lt = prob.l_Lt
    if prob.l_from_model.any():
        D = np.stack([d0, np.ones_like(d0)], -1)
        dm = np.swapaxes(D, -1, -2) @ D / prob.l_sig[..., None, None] ** 2
        Lt = np.where(prob.l_from_model[None, :, None, None], _chol_t(dm), Lt)
    W = Lt @ Dinv
    return r, (rows_where(freeze, prev, W) if freeze is not None else W)


def _ellipse_residuals(
    prob: Problem, uv: np.ndarray, refresh: bool, jac: bool, prev, freeze
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """The ellipses' raw residuals (B, E, K) at their model points' projections ``uv``
    (B, E·K, 2), their whitening W (B, E, 5, K) (as :func:`_line_residuals`) and, with ``jac``,
    each residual's image gradient (B, E, K, 2)."""
    B, E, K = prob.B, len(prob.ellipse_ids), prob.K
    s = prob.e_s[..., None]
    pn = (uv.reshape(B, E, K, 2) - prob.e_m[:, :, None, :]) / s[..., None]
    # with H = ∇²Q and ℓ = (D, E): ∇Q = H p + ℓ and Q = ½ p·(∇Q + ℓ) + F
    H = prob.e_hess
    g = pn @ H + prob.e_lin  # (B, E, K, 2)
    Qv = 0.5 * (pn * (g + prob.e_lin)).sum(-1) + prob.e_F
    duv = None
    if prob.distance == "sampson":
        gn2 = (g * g).sum(-1)
        gn = np.sqrt(gn2)
        r = s * Qv / gn
        if refresh:
            # D = ∂d/∂θ, taken where each model point's distance is measured: at its foot
            # on the observed conic (one Newton step), where ∂(Q/|∇Q|)/∂θ = ξ/|∇Q|. Taken
            # at the model points themselves it equals this to first order near the
            # solution, but far from it (model points off a thin ellipse) DᵀD can become
            # singular and the whitening explode into false minima.
            foot = pn - (Qv / gn2)[..., None] * g
            fg = foot @ H + prob.e_lin
            D = _xi_basis(foot, prob.e_basis9) * (s / np.sqrt((fg * fg).sum(-1)))[..., None]
        if jac:
            # exact image gradient of Q/|∇Q|: ∇Q/|∇Q| − Q H∇Q/|∇Q|³
            duv = g / gn[..., None] - (Qv / (gn2 * gn))[..., None] * (g @ H)
    else:
        k = prob.e_kpaper[..., None]
        r = s * k * Qv
        if refresh:
            D = _xi_basis(pn, prob.e_basis9) * (s * k)[..., None]
        if jac:
            duv = k[..., None] * g
    if not refresh:
        return r, prev, duv
    Dt = np.swapaxes(D, -1, -2)  # (B, E, 5, K)
    DtD = Dt @ D
    Lt = prob.e_Lt
    if prob.e_from_model.any():
        Lt = np.where(prob.e_from_model[None, :, None, None], _chol_t(DtD / prob.e_sig[..., None, None] ** 2), Lt)
    W = Lt @ spd_solve(DtD, Dt)  # (B, E, 5, K)
    return r, (rows_where(freeze, prev, W) if freeze is not None else W), duv
