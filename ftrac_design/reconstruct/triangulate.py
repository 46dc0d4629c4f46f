"""Maximum-likelihood triangulation of points seen in several tracked images, with covariance.

Each image i has a pose ``P_X = R_i P_F + t_i`` (SPEC §1, F → camera X_i), its covariance
Σθ_i (6×6, left rotation vector δ rad then translation mm, camera axes — SPEC §4) and
intrinsics ``(fx, fy, ox, oy)`` px. A point P (mm, frame F) projects to
``π_i(P) = (fx X/Z + ox, fy Y/Z + oy)`` with ``(X, Y, Z) = R_i P + t_i``.

The observed pixel u_i carries isotropic noise σ_i px per axis, and the pose used to
project it is itself uncertain. To first order a pose error δθ_i moves the predicted pixel
by ``C_i δθ_i`` with ``C_i = ∂π_i/∂θ_i = A_i [−[Q]ₓ | I]`` (``A_i = ∂π/∂P_X``, ``Q = R_i P``:
the solver's own Jacobian rows, :func:`ftrac_design.pose.problem.jacobian_rows`), so the
residual of view i has covariance

    S_i = σ_i² I₂ + C_i Σθ_i C_iᵀ          (pose covariance as extra image noise).

The estimate minimises ``Σ_i r_iᵀ S_i⁻¹ r_i``, ``r_i = π_i(P) − u_i`` — a linear start
(each view's two projection equations, divided by the depth of the fiducial, solved in
least squares: the inhomogeneous DLT) then Gauss–Newton steps with ``S_i`` re-evaluated at
the current point — and its covariance is

    Σ_P = (Σ_i J_iᵀ S_i⁻¹ J_i)⁻¹,   J_i = ∂π_i/∂P = A_i R_i   (3×3, mm², frame F).

This is the Cramér–Rao bound of the point given the images' independent pose errors; it
matches a Monte-Carlo run to a few per cent (tests/test_reconstruct.py). Not in it:
calibration (intrinsics) errors, and the correlation between points reconstructed from the
same images (they share the pose errors: only per-point covariances are reported), and —
when the reconstructed points are the fiducial's own beads — the correlation between a
bead's pixel and the pose solved from it.

Refusals (per point, with the reason): fewer than two views; nearly parallel views — the
widest angle between two views' rays through the point below ``min_parallax_deg``
(default 2°: the depth error is then more than 1/sin 2° ≈ 29 times the in-image error, and
so is every systematic error of the poses — calibration, distortion — which the covariance,
made from random errors only, does not contain); the point behind a source; a solve that
does not settle; image points that do not meet in 3-D (the residuals' χ² with 2N − 3
degrees of freedom has p < 10⁻⁶ under S: a wrong correspondence or a noise set too low).
Everything is batched over points: (n points, N views) with a mask of
which view sees which point. numpy only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.special import chdtrc

from ..pose.problem import jacobian_rows, project_points

#: default minimum angle (deg) between two views' rays through a point (see module doc)
MIN_PARALLAX_DEG = 2.0
#: most Gauss–Newton steps after the linear start (they stop once a step is below 1e-9 mm)
GAUSS_NEWTON_STEPS = 8
#: a point whose reprojection residuals are less probable than this under the noise model
#: (χ² with 2N − 3 degrees of freedom) is refused as inconsistent — one in a million
#: correct points is refused by chance
MIN_P_VALUE = 1e-6


@dataclass(frozen=True)
class Views:
    """N tracked images: poses F → X, their covariances and intrinsics, and σ px per axis."""

    R: np.ndarray  # (N, 3, 3)
    t: np.ndarray  # (N, 3) mm
    intr: np.ndarray  # (N, 4) fx, fy, ox, oy px
    sigma_px: np.ndarray  # (N,) isotropic pixel noise per axis
    pose_cov: np.ndarray  # (N, 6, 6) rad², mm² (zeros: pose taken as exact)

    @classmethod
    def make(cls, R, t, intr, sigma_px, pose_cov=None) -> "Views":
        """Views from array-likes, broadcasting ``intr`` (4,) and ``sigma_px`` to all N."""
        R = np.asarray(R, float).reshape(-1, 3, 3)
        N = R.shape[0]
        cov = np.zeros((N, 6, 6)) if pose_cov is None else np.asarray(pose_cov, float).reshape(N, 6, 6)
        return cls(
            R,
            np.asarray(t, float).reshape(N, 3),
            np.broadcast_to(np.asarray(intr, float), (N, 4)).copy(),
            np.broadcast_to(np.asarray(sigma_px, float), (N,)).copy(),
            cov,
        )

    @property
    def N(self) -> int:
        return self.R.shape[0]

    @property
    def centres(self) -> np.ndarray:
        """X-ray source positions (N, 3) in F, mm: ``−Rᵀ t``."""
        return -np.einsum("nji,nj->ni", self.R, self.t)

    def take(self, idx) -> "Views":
        """The views ``idx`` only."""
        idx = np.asarray(idx)
        return Views(self.R[idx], self.t[idx], self.intr[idx], self.sigma_px[idx], self.pose_cov[idx])


@dataclass
class Triangulation:
    """Points (n, 3) mm in F, covariances (n, 3, 3) mm², reprojection RMS (n,) px, views
    used (n, N) bool, widest ray angle (n,) deg and, per point, None or why it was refused."""

    P: np.ndarray
    cov: np.ndarray
    rms_px: np.ndarray
    used: np.ndarray
    parallax_deg: np.ndarray
    refused: list[str | None]

    @property
    def ok(self) -> np.ndarray:
        """(n,) bool: reconstructed."""
        return np.array([r is None for r in self.refused], bool)


def _project(views: Views, P: np.ndarray):
    """Pixels (N, n, 2), depths (N, n) and the projection terms of points P (n, 3) in every view."""
    return project_points(P, views.intr, views.R, views.t)


def _jacobians(views: Views, pr) -> tuple[np.ndarray, np.ndarray]:
    """∂π/∂P (N, n, 2, 3) in F and ∂π/∂θ (N, n, 2, 6) for the (δ, t) pose parameters."""
    N, n = pr[1].shape
    one, zero = np.ones((N, n)), np.zeros((N, n))
    # the solver's rows with ∂r/∂(u, v) = (1, 0) and (0, 1) are the pixel's own derivatives
    Ju = jacobian_rows(pr, slice(None), one, zero)
    Jv = jacobian_rows(pr, slice(None), zero, one)
    Jth = np.stack([Ju, Jv], -2)  # (N, n, 2, 6)
    JP = Jth[..., 3:] @ views.R[:, None]  # ∂π/∂P_X · R
    return JP, Jth


def _residual_cov(views: Views, Jth: np.ndarray) -> np.ndarray:
    """S (N, n, 2, 2) = σ² I + C Σθ Cᵀ."""
    S = Jth @ views.pose_cov[:, None] @ np.swapaxes(Jth, -1, -2)
    S[..., 0, 0] += views.sigma_px[:, None] ** 2
    S[..., 1, 1] += views.sigma_px[:, None] ** 2
    return S


def linear_start(views: Views, uv: np.ndarray, seen: np.ndarray) -> np.ndarray:
    """Least-squares points (n, 3) from the projection equations of the views that see them.

    With normalised coordinates ``x = (u − ox)/fx`` each view gives
    ``(x r₃ − r₁)·P = t₁ − x t₃`` (and the same in y); dividing by the view's depth at the
    fiducial origin makes the residuals ≈ normalised reprojection errors.
    """
    x = (uv - views.intr[:, None, 2:]) / views.intr[:, None, :2]  # (N, n, 2)
    r1, r2, r3 = views.R[:, 0], views.R[:, 1], views.R[:, 2]  # (N, 3)
    w = (seen / np.maximum(np.abs(views.t[:, 2:3]), 1e-9))[..., None]  # (N, n, 1)
    Ax = (x[..., 0:1] * r3[:, None] - r1[:, None]) * w  # (N, n, 3)
    Ay = (x[..., 1:2] * r3[:, None] - r2[:, None]) * w
    bx = (views.t[:, None, 0] - x[..., 0] * views.t[:, None, 2]) * w[..., 0]  # (N, n)
    by = (views.t[:, None, 1] - x[..., 1] * views.t[:, None, 2]) * w[..., 0]
    A = np.concatenate([Ax, Ay], 0).transpose(1, 0, 2)  # (n, 2N, 3)
    b = np.concatenate([bx, by], 0).T  # (n, 2N)
    AtA = np.swapaxes(A, 1, 2) @ A
    Atb = np.einsum("nki,nk->ni", A, b)
    with np.errstate(all="ignore"):
        ok = np.linalg.cond(AtA) < 1e12
        P = np.full((A.shape[0], 3), np.nan)
        if ok.any():
            P[ok] = np.linalg.solve(AtA[ok], Atb[ok][..., None])[..., 0]
    return P


def parallax_deg(views: Views, P: np.ndarray, seen: np.ndarray) -> np.ndarray:
    """Widest angle (n,) deg between the rays of two views (that see the point) through P."""
    d = P[None] - views.centres[:, None]  # (N, n, 3)
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    c = np.einsum("inc,jnc->nij", d, d)
    both = seen.T[:, :, None] & seen.T[:, None, :]
    c = np.where(both, c, 1.0)
    return np.degrees(np.arccos(np.clip(c.min((1, 2)), -1.0, 1.0)))


def triangulate(
    views: Views,
    uv: np.ndarray,
    seen: np.ndarray | None = None,
    min_parallax_deg: float = MIN_PARALLAX_DEG,
    steps: int = GAUSS_NEWTON_STEPS,
    max_p: float = MIN_P_VALUE,
) -> Triangulation:
    """ML points in F from pixels ``uv`` (N views, n points, 2) where ``seen`` (N, n) bool.

    See the module docstring for the model, the covariance formula and the refusals.
    """
    uv = np.asarray(uv, float).reshape(views.N, -1, 2)
    n = uv.shape[1]
    seen = np.ones((views.N, n), bool) if seen is None else np.asarray(seen, bool).reshape(views.N, n)
    seen = seen & np.isfinite(uv).all(-1)
    uvz = np.where(seen[..., None], uv, 0.0)
    count = seen.sum(0)
    refused: list[str | None] = [None] * n
    P = linear_start(views, uvz, seen)
    dP = np.zeros_like(P)
    with np.errstate(all="ignore"):
        for _ in range(steps):
            uvp, Z, pr = _project(views, np.where(np.isfinite(P), P, 0.0))
            JP, Jth = _jacobians(views, pr)
            Si = np.linalg.inv(_residual_cov(views, Jth))
            Si = np.where(seen[..., None, None], Si, 0.0)
            r = uvp - uvz
            JtS = np.swapaxes(JP, -1, -2) @ Si  # (N, n, 3, 2)
            H = (JtS @ JP).sum(0)  # (n, 3, 3)
            g = (JtS @ r[..., None]).sum(0)[..., 0]
            good = np.isfinite(H).all((1, 2)) & (np.linalg.cond(np.where(np.isfinite(H), H, 0.0)) < 1e14)
            dP = np.zeros_like(P)
            if good.any():
                dP[good] = -np.linalg.solve(H[good], g[good][..., None])[..., 0]
            P = P + dP
            if np.all(~np.isfinite(dP) | (np.abs(dP) < 1e-9)):
                break
        uvp, Z, pr = _project(views, np.where(np.isfinite(P), P, 0.0))
        JP, Jth = _jacobians(views, pr)
        Si = np.where(seen[..., None, None], np.linalg.inv(_residual_cov(views, Jth)), 0.0)
        H = (np.swapaxes(JP, -1, -2) @ Si @ JP).sum(0)
        cov = np.full((n, 3, 3), np.nan)
        invertible = np.isfinite(H).all((1, 2)) & (count >= 2)
        if invertible.any():
            cov[invertible] = np.linalg.inv(H[invertible])
        res = np.where(seen[..., None], uvp - uvz, 0.0)
        rms = np.sqrt((res**2).sum((0, 2)) / np.maximum(2 * count, 1))
        chi2 = (res[..., None, :] @ Si @ res[..., None])[..., 0, 0].sum(0)
        dof = np.maximum(2 * count - 3, 1)
        pval = chdtrc(dof, chi2)
        par = parallax_deg(views, np.where(np.isfinite(P), P, 0.0), seen)
    last_step = np.abs(dP).max(1) if n else np.zeros(0)
    for k in range(n):
        if count[k] < 2:
            refused[k] = (
                f"seen in {int(count[k])} image{'s' if count[k] != 1 else ''}: a point needs at least two views"
            )
        elif not np.isfinite(P[k]).all():
            refused[k] = "the views' projection equations do not determine the point"
        elif not (Z[seen[:, k], k] > 0).all():
            refused[k] = "behind the X-ray source in some view: wrong correspondence or pose?"
        elif not par[k] >= min_parallax_deg:
            refused[k] = (
                f"nearly parallel views: the widest angle between two rays through the point is "
                f"{par[k]:.2f}° (< {min_parallax_deg:g}°), depth would be "
                f"{1 / max(math.sin(math.radians(par[k])), 1e-12):.0f}× less certain than position "
                f"in the image"
            )
        elif not pval[k] >= max_p:
            refused[k] = (
                f"the image points do not meet in 3-D: reprojection RMS {rms[k]:.2f} px, χ² = "
                f"{chi2[k]:.3g} on {int(dof[k])} degrees of freedom (p = {pval[k]:.1e}); a wrong "
                f"correspondence, or raise the noise (σ = {np.median(views.sigma_px):.3g} px)"
            )
        elif not (np.isfinite(cov[k]).all() and last_step[k] < 1e-3):
            refused[k] = "the triangulation did not settle (inconsistent pixels or poses)"
    return Triangulation(P, cov, rms, seen, par, refused)
