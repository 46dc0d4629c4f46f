"""Points with covariances carried through rigid transforms: F → T → U (paper §IV).

``P_U = F_TU · F_FT · P_F``: F_FT is ``features.json``'s ``template_from_fiducial`` (the CNC
connector), F_TU a user's template → ultrasound (or any further) transform. A transform
``T = (R, t)`` may itself be uncertain: a small error ``(δ, δt)`` — rotation vector rad
applied on the left, translation mm, in the target frame (the convention of SPEC §4's pose
covariance) — moves a mapped point by ``−[R P]ₓ δ + δt``. To first order, for a point with
covariance Σ_P and a transform with covariance Σ_T (6×6, independent of the point),

    P' = R P + t,   Σ_P' = R Σ_P Rᵀ + G Σ_T Gᵀ,   G = [−[R P]ₓ | I₃].

The propagation is exact for a certain transform (Σ_T = 0) and first-order otherwise;
tests/test_reconstruct.py checks it against Monte-Carlo. numpy only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..pose import so3


@dataclass(frozen=True)
class RigidTransform:
    """A named rigid 4×4 ``target_from_source`` with an optional 6×6 covariance (see module doc)."""

    matrix: np.ndarray
    source: str
    target: str
    covariance: np.ndarray | None = None

    @property
    def R(self) -> np.ndarray:
        return self.matrix[:3, :3]

    @property
    def t(self) -> np.ndarray:
        return self.matrix[:3, 3]


def is_rigid(M: np.ndarray, tol: float = 1e-6) -> bool:
    """Whether M (4, 4) is a proper rigid transform (orthonormal R, det +1, last row 0 0 0 1)."""
    M = np.asarray(M, float)
    if M.shape != (4, 4) or not np.isfinite(M).all():
        return False
    R = M[:3, :3]
    return bool(
        np.allclose(R @ R.T, np.eye(3), atol=tol)
        and abs(np.linalg.det(R) - 1) < tol
        and np.allclose(M[3], [0, 0, 0, 1], atol=tol)
    )


def isotropic_covariance(sigma_mm: float = 0.0, sigma_rad: float = 0.0) -> np.ndarray:
    """6×6 covariance of a transform known to σ mm per translation axis and σ rad per rotation axis."""
    return np.diag([sigma_rad**2] * 3 + [sigma_mm**2] * 3)


def apply(T: RigidTransform, P: np.ndarray, cov: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Points P (n, 3) with covariances (n, 3, 3) mapped by T, first-order propagation."""
    P = np.asarray(P, float).reshape(-1, 3)
    RP = P @ T.R.T
    out = RP + T.t
    c = T.R @ np.asarray(cov, float).reshape(-1, 3, 3) @ T.R.T
    if T.covariance is not None:
        G = np.concatenate([-so3.skew(RP), np.broadcast_to(np.eye(3), RP.shape + (3,))], -1)  # (n, 3, 6)
        c = c + G @ T.covariance @ np.swapaxes(G, -1, -2)
    return out, c


def sample(T: RigidTransform, rng: np.random.Generator) -> np.ndarray:
    """A 4×4 drawn from T's uncertainty (Monte-Carlo checks and the system budget)."""
    if T.covariance is None:
        return T.matrix.copy()
    e = rng.multivariate_normal(np.zeros(6), T.covariance)
    M = np.eye(4)
    M[:3, :3] = so3.exp(e[:3]) @ T.R
    M[:3, 3] = T.t + e[3:]
    return M


def chain(P: np.ndarray, cov: np.ndarray, transforms: list[RigidTransform]):
    """Apply ``transforms`` in order; returns the points and covariances in the last target frame."""
    for T in transforms:
        P, cov = apply(T, P, cov)
    return P, cov
