"""What images of the fiducial tell about the C-arm's intrinsics (paper §V's "potential" use).

The camera (SPEC §1) enters the image only through ``fx = f/s_x``, ``fy = f/s_y`` (pixels)
and the principal point ``(ox, oy)`` (pixels): ``u = fx X/Z + ox``. The focal length f (mm)
and the pixel pitch s (mm) are not separately observable — scaling both leaves every image
unchanged — so we estimate ``fx, fy`` and report f only as ``fx · s`` for a pixel pitch the
user knows (it does not change over the machine's life, paper §III.A.4); the pixel-size
errors of the paper's Fig. 7d are errors in ``fx, fy`` of relative size ``δs/s``.

Derivatives. For a residual r measured at a model point with ∂r/∂(u, v) = (c_u, c_v),
``∂r/∂(fx, fy, ox, oy) = (c_u x, c_v y, c_u, c_v)`` with ``x = X/Z, y = Y/Z``. The solver's
Jacobian rows (:func:`ftrac_design.pose.problem.jacobian_rows`) already hold
``∂r/∂t_x = c_u fx/Z`` and ``∂r/∂t_y = c_v fy/Z``, so the intrinsic columns follow from them
in closed form: ``∂r/∂fx = ∂r/∂t_x · X/fx``, ``∂r/∂ox = ∂r/∂t_x · Z/fx`` (and the same in y).

- :func:`information_rows`, :func:`crb` — Cramér–Rao bounds of one image's pose and
  intrinsics together (the analysis's Fisher information, :mod:`ftrac_design.analysis.information`,
  with four more columns), and the correlation of each intrinsic with the depth t_z.
- :func:`estimate` — joint maximum-likelihood estimate of N poses and one shared set of
  intrinsics from N images (the solver's whitened residuals, Levenberg–Marquardt over
  6N + k parameters), refused when the images do not determine the intrinsics.

Why one image tells little: under weak perspective (object depth ≪ distance) the image is
unchanged when f and t_z scale together, and when the principal point and t_x, t_y shift
together; only the perspective within the ~5 cm fiducial at ~67 cm separates them. More
images of the same kind add information only as fast as 1/√N (the ambiguity holds for every
image's own t_z), see the numbers in docs/tutorials/reconstruct.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields, replace

import numpy as np

from ..analysis.information import FeatureLayout, feature_layout, whitened_rows
from ..features.model import Features
from ..pose import so3
from ..pose.camera import Camera
from ..pose.observation import Observation
from ..pose.problem import NoiseModel, Problem, compile_problem, evaluate, project_points
from ..pose.solver import SolverOptions, parameter_scale, solve_batch

NAMES = ("fx", "fy", "ox", "oy")
#: the parameter sets offered: square pixels of known aspect make fx, fy one focal length
PARAMETER_SETS = {"f": ("f",), "f,o": ("f", "ox", "oy"), "all": NAMES}


def basis(params: tuple[str, ...], intr: np.ndarray) -> np.ndarray:
    """(4, k): d(fx, fy, ox, oy) per unit of each parameter. "f" is the focal length in
    units of fx with the aspect fy/fx held (``d(fx, fy) = (1, fy/fx)``)."""
    cols = []
    for p in params:
        if p == "f":
            cols.append([1.0, intr[1] / intr[0], 0.0, 0.0])
        else:
            c = [0.0] * 4
            c[NAMES.index(p)] = 1.0
            cols.append(c)
    return np.array(cols).T


def _intrinsic_from_translation(
    Jt: np.ndarray, Xc: np.ndarray, Yc: np.ndarray, Z: np.ndarray, intr: np.ndarray
) -> np.ndarray:
    """(…, 4) ∂r/∂(fx, fy, ox, oy) from ∂r/∂(t_x, t_y) (…, 2) and the camera-frame point."""
    fx, fy = intr[..., 0], intr[..., 1]
    return np.stack([Jt[..., 0] * Xc / fx, Jt[..., 1] * Yc / fy, Jt[..., 0] * Z / fx, Jt[..., 1] * Z / fy], -1)


def information_rows(
    layout: FeatureLayout, camera: Camera, R: np.ndarray, t: np.ndarray, noise: NoiseModel = NoiseModel()
) -> np.ndarray:
    """Whitened rows (B, n, 10): the analysis's pose rows (δ rad, t mm) then ∂/∂(fx, fy, ox, oy) px."""
    R = np.asarray(R, float).reshape(-1, 3, 3)
    t = np.asarray(t, float).reshape(-1, 3)
    rows = whitened_rows(layout, camera, R, t, noise)  # (B, n, 6)
    _, Z, (Q, x, y, _, _) = project_points(layout.X, np.broadcast_to(camera.intrinsics, (R.shape[0], 4)), R, t)
    K = _intrinsic_from_translation(rows[..., 3:5], x * Z, y * Z, Z, camera.intrinsics)
    return np.concatenate([rows, K], -1)


@dataclass
class IntrinsicsBound:
    """Cramér–Rao bounds at B poses with ``params`` free besides the pose."""

    params: tuple[str, ...]
    std: np.ndarray  # (B, k) px (f: px of fx)
    corr_tz: np.ndarray  # (B, k) correlation of each parameter with t_z
    pose_std: np.ndarray  # (B, 6) rad, mm with the intrinsics free
    pose_std_known: np.ndarray  # (B, 6) with the intrinsics known


def crb(
    features: Features,
    camera: Camera,
    R: np.ndarray,
    t: np.ndarray,
    noise: NoiseModel = NoiseModel(),
    params: tuple[str, ...] = NAMES,
    images: int = 1,
) -> IntrinsicsBound:
    """Bounds from one image at each pose (B, 3, 3), (B, 3), or from ``images`` independent
    images at that same pose (information × N: the 1/√N best case)."""
    layout = feature_layout(features)
    rows = information_rows(layout, camera, R, t, noise)
    Bm = basis(params, camera.intrinsics)
    A = np.concatenate([rows[..., :6], rows[..., 6:] @ Bm], -1)
    info = np.swapaxes(A, 1, 2) @ A * images
    # scale to unit diagonal before inverting: fx in px and δ in rad differ by ~10⁸
    d = np.sqrt(np.diagonal(info, axis1=1, axis2=2))
    C = np.linalg.inv(info / (d[:, :, None] * d[:, None, :])) / (d[:, :, None] * d[:, None, :])
    sd = np.sqrt(np.diagonal(C, axis1=1, axis2=2))
    corr = C[:, 6:, 5] / (sd[:, 6:] * sd[:, 5:6])
    known = np.linalg.inv(info[:, :6, :6])
    return IntrinsicsBound(tuple(params), sd[:, 6:], corr, sd[:, :6], np.sqrt(np.diagonal(known, axis1=1, axis2=2)))


# ----------------------------------------------------------------------------- joint estimation
def whiten(prob: Problem, W: list[np.ndarray], dr: np.ndarray) -> np.ndarray:
    """Raw-residual derivatives dr (B, n_raw, k) → whitened (B, m, k), as :func:`evaluate` whitens."""
    B, k = dr.shape[0], dr.shape[-1]
    P, L, E, K = len(prob.point_ids), len(prob.line_ids), len(prob.ellipse_ids), prob.K
    out, w = [], 0
    if P:
        out.append(dr[:, : 2 * P] * prob.p_w2)
        w += 1
    if L:
        out.append((W[w] @ dr[:, 2 * P : 2 * P + 2 * L].reshape(B, L, 2, k)).reshape(B, 2 * L, k))
        w += 1
    if E:
        out.append((W[w] @ dr[:, 2 * P + 2 * L :].reshape(B, E, K, k)).reshape(B, 5 * E, k))
    return np.concatenate(out, 1)


def residuals(prob: Problem, R: np.ndarray, t: np.ndarray, whitening=None):
    """Whitened residuals (B, m), their pose Jacobian (B, m, 6), intrinsics Jacobian (B, m, 4)
    and the whitening used, at the intrinsics in ``prob.intr``."""
    ev = evaluate(prob, R, t, whitening=whitening, raw_jacobian=True)
    _, Z, (Q, x, y, _, _) = project_points(prob.X, prob.intr, R, t)
    rp = prob.row_points
    Zr, xr, yr = Z[:, rp], x[:, rp], y[:, rp]
    dr = _intrinsic_from_translation(ev.raw_jac[..., 3:5], xr * Zr, yr * Zr, Zr, prob.intr[:, None, :])
    return ev.rho, ev.J, whiten(prob, ev.W, dr), ev.W


@dataclass
class IntrinsicsEstimate:
    """Joint estimate: the camera, the poses, the parameters' covariance, or why refused."""

    ok: bool
    reason: str | None
    params: tuple[str, ...]
    camera: Camera
    intrinsics: np.ndarray  # (4,) fx, fy, ox, oy px
    std: np.ndarray  # (k,) px, CRB at the estimate (noise model's σ)
    R: np.ndarray  # (N, 3, 3)
    t: np.ndarray  # (N, 3)
    pose_cov: np.ndarray  # (N, 6, 6) marginal, intrinsics free
    noise_scale: float = float("nan")
    condition: float = float("nan")
    iterations: int = 0
    corr_tz: np.ndarray = field(default_factory=lambda: np.zeros(0))  # (N, k)
    solved: list[int] = field(default_factory=list)  # input indices of the N images
    start: list = field(default_factory=list)  # every input's pose solved with the given camera

    def pose_dicts(self) -> list[dict]:
        """One SPEC §4 object per input image, in input order: the joint estimate (with the
        estimated camera under the extension key ``"camera"``) where it was made, else the
        start pose (``converged: false`` ones stay so)."""
        out = [p.to_dict() for p in self.start]
        if not self.ok:
            return out
        cam = self.camera_dict()
        for a, i in enumerate(self.solved):
            d = out[i]
            d["rotation"] = self.R[a].tolist()
            d["translation_mm"] = self.t[a].tolist()
            d["covariance"] = self.pose_cov[a].tolist() if np.isfinite(self.pose_cov[a]).all() else None
            d["noise_scale"] = self.noise_scale
            d["camera"] = cam
            d["rms_residual_px"] = None  # the start's residuals no longer apply
            d.pop("per_feature_residuals_px", None)
        return out

    def camera_dict(self) -> dict:
        """The estimated SPEC §3 camera plus the bounds (extension keys)."""
        d = self.camera.to_dict()
        d["estimated"] = list(self.params)
        d["std_px"] = dict(zip(self.params, np.round(self.std, 4).tolist()))
        return d


#: the joint problem's normal matrix, scaled to unit diagonal, must be better conditioned
#: than this for the intrinsics to count as determined (rank test)
MAX_CONDITION = 1e10
#: and every estimated intrinsic's bound must be below this fraction of fx (0.5 %: 5 mm of a
#: 1000 mm focal length, 2.5 px of principal point at fx ≈ 2270 px — the paper's Fig. 7 range)
MAX_RELATIVE_STD = 0.005


def _tolerant(opts: SolverOptions) -> SolverOptions:
    """``opts`` with every residual-size check off (those the installed solver has)."""
    off = {"max_noise_scale": math.inf, "retry_p_value": 0.0, "misfit_noise_scale": math.inf}
    names = {f.name for f in fields(SolverOptions)}
    return replace(opts, **{k: v for k, v in off.items() if k in names})


def _camera_from(camera: Camera, intr: np.ndarray) -> Camera:
    """A Camera with intrinsics ``intr``, keeping the pixel pitch (f = fx · s_x)."""
    sx, sy = camera.pixel_size_mm
    f = intr[0] * sx
    return Camera(float(f), (float(sx), float(f / intr[1])), (float(intr[2]), float(intr[3])))


def estimate(
    features: Features,
    observations: list[Observation],
    camera: Camera | None = None,
    params: tuple[str, ...] = ("f", "ox", "oy"),
    options: SolverOptions | None = None,
    max_iterations: int = 50,
    min_images: int = 2,
    max_relative_std: float = MAX_RELATIVE_STD,
) -> IntrinsicsEstimate:
    """Joint ML estimate of N poses and shared intrinsics ``params`` from N images.

    ``camera`` (default: the first observation's) is the starting calibration; each image is
    first solved with it, then all poses and the intrinsics are refined together by
    Levenberg–Marquardt on the solver's whitened residuals (whitening refreshed at each
    accepted step). Refused (``ok = False`` with the reason, poses from the start) when
    fewer than ``min_images`` images were solved, when the normal matrix is rank-deficient
    (scaled condition number > :data:`MAX_CONDITION`), when the residuals stay above the
    solver's ``max_noise_scale`` (the model does not fit: other intrinsics off, distortion),
    or when the data bound an intrinsic no better than ``max_relative_std`` of fx.
    """
    opts = options or SolverOptions()
    obs = list(observations)
    cam0 = camera or obs[0].camera
    obs = [Observation(cam0, o.points, o.lines, o.ellipses, o.origin) for o in obs]
    # the start is solved with a camera that may be off: residuals far above the noise model
    # are expected there, and are no reason to reject a pose (or to search for another one)
    poses = solve_batch(features, obs, _tolerant(opts))
    solved = [i for i, p in enumerate(poses) if p.converged]
    N = len(solved)
    intr = cam0.intrinsics.copy()
    R = np.array([poses[i].rotation for i in solved]).reshape(-1, 3, 3)
    t = np.array([poses[i].translation_mm for i in solved]).reshape(-1, 3)
    refuse = _Refusal(tuple(params), cam0, poses, solved, R.copy(), t.copy())
    if N < min_images:
        return refuse(
            f"{N} solved image{'s' if N != 1 else ''}: shared intrinsics need at least {min_images} "
            f"(one image cannot separate the focal length from the depth, nor the principal point "
            f"from the lateral position)"
        )
    probs = [
        compile_problem(
            features, [obs[i]], opts.noise, opts.ellipse_model_points, opts.distance, task_scaling=opts.task_scaling
        )
        for i in solved
    ]
    joint = _Joint(probs, parameter_scale(features), basis(params, intr), len(params))
    with np.errstate(all="ignore"):
        R, t, intr, ev, A, cost, it = joint.solve(R, t, intr, max_iterations)
    m = sum(e[0].shape[1] for e in ev)
    As, D, cond = _scaled(A)
    if not cond < MAX_CONDITION:
        return refuse(
            f"the images do not determine {', '.join(params)} (scaled condition number {cond:.2g}: rank-deficient)",
            cond=cond,
        )
    std, corr, pose_cov = joint.covariance(As, D)
    kappa = math.sqrt(cost / max(m - 6 * N - joint.k, 1))
    why = _unbound(params, kappa, opts.max_noise_scale, std, intr, corr, max_relative_std)
    if why is not None:
        return refuse(why, std, cond, corr)
    return IntrinsicsEstimate(
        True,
        None,
        tuple(params),
        _camera_from(cam0, intr),
        intr,
        std,
        R,
        t,
        pose_cov,
        kappa,
        cond,
        it,
        corr,
        solved,
        poses,
    )


def _scaled(A: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """The normal matrix scaled to a unit diagonal, the scale, and its condition number."""
    D = np.sqrt(np.maximum(np.diag(A), 1e-300))
    As = A / np.outer(D, D)
    ew = np.linalg.eigvalsh(As)
    return As, D, float(ew[-1] / ew[0]) if ew[0] > 0 else math.inf


def _unbound(params, kappa: float, max_noise_scale: float, std, intr, corr, max_relative_std: float) -> str | None:
    """Why the fitted intrinsics are not to be trusted: the residuals stay above the noise
    model, or the data bound an intrinsic no better than ``max_relative_std`` of fx (None: both fine)."""
    if not kappa <= max_noise_scale:
        return (
            f"residuals stay {kappa:.3g} times the noise model with {', '.join(params)} estimated: "
            f"other intrinsics (or distortion) are off, or the segmentation is worse than modelled"
        )
    if not np.all(std < max_relative_std * intr[0]):
        worst = int(np.argmax(std / intr[0]))
        return (
            f"the images bound {params[worst]} only to ±{std[worst]:.3g} px "
            f"({100 * std[worst] / intr[0]:.2g} % of fx > {100 * max_relative_std:g} %; correlation with "
            f"depth {np.abs(corr[:, worst]).max():.3f}): add images from other directions or keep the "
            f"nominal calibration"
        )
    return None


@dataclass(frozen=True)
class _Refusal:
    """A refused estimate: the start (each image solved with the given camera) is what it leaves the user."""

    params: tuple[str, ...]
    cam0: Camera
    poses: list
    solved: list[int]
    R0: np.ndarray
    t0: np.ndarray

    def __call__(self, why: str, std=None, cond=float("nan"), corr=None) -> IntrinsicsEstimate:
        poses, k, N = self.poses, len(self.params), len(self.solved)
        cov = np.array(
            [poses[i].covariance if poses[i].covariance is not None else np.full((6, 6), np.nan) for i in self.solved]
        ).reshape(-1, 6, 6)
        return IntrinsicsEstimate(
            False,
            why,
            self.params,
            self.cam0,
            self.cam0.intrinsics.copy(),
            np.full(k, np.nan) if std is None else std,
            self.R0,
            self.t0,
            cov,
            condition=cond,
            corr_tz=np.zeros((N, k)) if corr is None else corr,
            solved=self.solved,
            start=poses,
        )


class _Joint:
    """The N images' problems with one set of intrinsics: poses (6 per image, rotation in units
    of ``h``) and the intrinsics' free parameters (the columns of ``Bm``) fitted together."""

    def __init__(self, probs: list, h: np.ndarray, Bm: np.ndarray, k: int):
        self.probs, self.h, self.Bm = probs, h, Bm
        self.N, self.k = len(probs), k

    def set_intr(self, q: np.ndarray) -> None:
        for p in self.probs:
            p.intr[:] = q

    def evaluate_all(self, Rs, ts, W=None) -> list:
        return [
            residuals(p, Rs[i : i + 1], ts[i : i + 1], None if W is None else W[i]) for i, p in enumerate(self.probs)
        ]

    def normal(self, ev) -> tuple[np.ndarray, np.ndarray, float]:
        """The normal matrix, the gradient and the cost of the residuals ``ev``."""
        N, h = self.N, self.h
        n = 6 * N + self.k
        A = np.zeros((n, n))
        g = np.zeros(n)
        cost = 0.0
        for i, (rho, J, Kx, _) in enumerate(ev):
            Ki = Kx[0] @ self.Bm
            Ji = J[0] * h
            s = slice(6 * i, 6 * i + 6)
            A[s, s] = Ji.T @ Ji
            A[s, 6 * N :] = Ji.T @ Ki
            A[6 * N :, s] = A[s, 6 * N :].T
            A[6 * N :, 6 * N :] += Ki.T @ Ki
            g[s] = Ji.T @ rho[0]
            g[6 * N :] += Ki.T @ rho[0]
            cost += float(rho[0] @ rho[0])
        return A, g, cost

    def solve(self, R, t, intr, max_iterations: int):
        """Levenberg–Marquardt from (R, t, intr), the whitening refreshed at each accepted step;
        returns the poses, intrinsics, residuals, normal matrix, cost and iterations."""
        N, h = self.N, self.h
        lam = 1e-6
        it = 0
        ev = self.evaluate_all(R, t)
        A, g, cost = self.normal(ev)
        for it in range(1, max_iterations + 1):
            D = np.sqrt(np.maximum(np.diag(A), 1e-300))
            As = A / np.outer(D, D)
            step = -np.linalg.solve(As + lam * np.eye(len(D)), g / D) / D
            dpose = step[: 6 * N].reshape(N, 6) * h
            Rn = so3.exp(dpose[:, :3]) @ R
            tn = t + dpose[:, 3:]
            qn = intr + self.Bm @ step[6 * N :]
            self.set_intr(qn)
            trial = self.evaluate_all(Rn, tn, [e[3] for e in ev])
            tcost = sum(float(e[0][0] @ e[0][0]) for e in trial)
            if np.isfinite(tcost) and tcost <= cost:
                R, t, intr = Rn, tn, qn
                ev = self.evaluate_all(R, t)
                A, g, new = self.normal(ev)
                done = abs(cost - new) <= 1e-10 * max(cost, 1.0) and np.abs(step[6 * N :]).max() < 1e-6
                cost = new
                lam = max(lam / 10, 1e-12)
                if done:
                    break
            else:
                self.set_intr(intr)
                lam *= 10
                if lam > 1e8:
                    break
        return R, t, intr, ev, A, cost, it

    def covariance(self, As: np.ndarray, D: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The intrinsics' σ, each image's depth correlation with them, and each pose's covariance."""
        N, k, h = self.N, self.k, self.h
        C = np.linalg.inv(As) / np.outer(D, D)
        sd = np.sqrt(np.diag(C))
        std = sd[6 * N :]
        corr = np.array(
            [[C[6 * i + 5, 6 * N + j] / (sd[6 * i + 5] * sd[6 * N + j]) for j in range(k)] for i in range(N)]
        )
        # rotation block back from the scaled units h
        pose_cov = np.array([C[6 * i : 6 * i + 6, 6 * i : 6 * i + 6] * np.outer(h, h) for i in range(N)])
        return std, corr, pose_cov
