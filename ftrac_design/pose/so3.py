"""Rotations as 3×3 matrices with left so(3) increments, batched over leading axes.

The solver perturbs a pose as ``R ← exp([δ]ₓ) R``, ``t ← t + δt``: δ is a small rotation
vector in the camera frame X (radians), applied about the fiducial's origin. Unlike Euler
angles this has no singular configuration.
"""

from __future__ import annotations

import math

import numpy as np


def skew(v: np.ndarray) -> np.ndarray:
    """``[v]ₓ`` for v of shape (..., 3) → (..., 3, 3)."""
    z = np.zeros(v.shape[:-1])
    x, y, w = v[..., 0], v[..., 1], v[..., 2]
    return np.stack([np.stack([z, -w, y], -1), np.stack([w, z, -x], -1), np.stack([-y, x, z], -1)], -2)


def exp(v: np.ndarray) -> np.ndarray:
    """Rodrigues: rotation vector (..., 3) in radians → rotation matrix (..., 3, 3)."""
    v = np.asarray(v, float)
    if v.shape == (1, 3):
        return _exp_one(*v[0].tolist())[None]
    th2 = (v * v).sum(-1)
    small = th2 < 1e-12
    th2s = np.where(small, 1.0, th2)
    th = np.sqrt(th2s)
    # Taylor series below 1e-6 rad keeps full precision where sin(θ)/θ cancels
    a = np.where(small, 1.0 - th2 / 6.0, np.sin(th) / th)
    b = np.where(small, 0.5 - th2 / 24.0, (1.0 - np.cos(th)) / th2s)
    # R = I + a[v]ₓ + b[v]ₓ² with [v]ₓ² = v vᵀ − |v|² I, written out (hot path of the solver)
    R = v[..., :, None] * v[..., None, :] * b[..., None, None]
    d = 1.0 - b * th2
    R[..., 0, 0] += d
    R[..., 1, 1] += d
    R[..., 2, 2] += d
    av = v * a[..., None]
    R[..., 0, 1] -= av[..., 2]
    R[..., 1, 0] += av[..., 2]
    R[..., 0, 2] += av[..., 1]
    R[..., 2, 0] -= av[..., 1]
    R[..., 1, 2] -= av[..., 0]
    R[..., 2, 1] += av[..., 0]
    return R


def _exp_one(x: float, y: float, z: float) -> np.ndarray:
    """:func:`exp` of one rotation vector with scalar arithmetic: the single-image solver
    calls it every iteration, where array operations on one row cost ~5× more."""
    th2 = x * x + y * y + z * z
    if th2 < 1e-12:
        a, b = 1.0 - th2 / 6.0, 0.5 - th2 / 24.0
    else:
        th = math.sqrt(th2)
        if th == math.inf:  # math.sin raises here; NaN out, as the batched path gives
            return np.full((3, 3), math.nan)
        a, b = math.sin(th) / th, (1.0 - math.cos(th)) / th2
    d = 1.0 - b * th2
    return np.array(
        [
            [d + b * x * x, b * x * y - a * z, b * x * z + a * y],
            [b * x * y + a * z, d + b * y * y, b * y * z - a * x],
            [b * x * z - a * y, b * y * z + a * x, d + b * z * z],
        ]
    )


def log(R: np.ndarray) -> np.ndarray:
    """Rotation matrix (..., 3, 3) → rotation vector (..., 3), radians, angle in [0, π]."""
    R = np.asarray(R, float)
    tr = np.trace(R, axis1=-2, axis2=-1)
    c = np.clip((tr - 1.0) / 2.0, -1.0, 1.0)
    th = np.arccos(c)
    w = np.stack([R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0], R[..., 1, 0] - R[..., 0, 1]], -1)
    s = np.sin(th)
    out = np.where((s > 1e-6)[..., None], w * (th / (2 * np.where(s > 1e-6, s, 1.0)))[..., None], 0.5 * w)
    # near π the antisymmetric part vanishes: take the axis from the symmetric part
    near_pi = th > np.pi - 1e-4
    if np.any(near_pi):
        Rp = R[near_pi]
        B = (Rp + np.swapaxes(Rp, -1, -2)) / 2 - np.eye(3) * ((np.trace(Rp, axis1=-2, axis2=-1) - 1) / 2)[
            ..., None, None
        ]
        # B = (1 - cos θ) n nᵀ: the column with the largest diagonal gives n up to sign
        k = np.argmax(np.diagonal(B, axis1=-2, axis2=-1), axis=-1)
        col = np.take_along_axis(B, k[..., None, None].repeat(3, -2), axis=-1)[..., 0]
        n = col / np.linalg.norm(col, axis=-1, keepdims=True)
        wp = w[near_pi]
        sign = np.where(np.sum(n * wp, -1) < 0, -1.0, 1.0)[..., None]
        out[near_pi] = n * sign * th[near_pi][..., None]
    return out


def angle(Ra: np.ndarray, Rb: np.ndarray) -> np.ndarray:
    """Angle (rad) of the rotation taking Rb to Ra, batched."""
    Rd = Ra @ np.swapaxes(Rb, -1, -2)
    c = (np.trace(Rd, axis1=-2, axis2=-1) - 1.0) / 2.0
    return np.arccos(np.clip(c, -1.0, 1.0))


def is_rotation(M, tol: float = 1e-6) -> bool:
    """Whether ``M`` is a proper 3 × 3 rotation matrix: finite, orthonormal and of determinant
    +1, each to within ``tol``."""
    R = np.asarray(M, float)
    return bool(
        R.shape == (3, 3)
        and np.all(np.isfinite(R))
        and np.abs(R.T @ R - np.eye(3)).max() < tol
        and abs(np.linalg.det(R) - 1.0) < tol
    )


def project_to_so3(M: np.ndarray) -> np.ndarray:
    """Nearest rotation (Frobenius) to M (..., 3, 3)."""
    U, _, Vt = np.linalg.svd(M)
    d = np.sign(np.linalg.det(U @ Vt))
    U = U.copy()
    U[..., :, 2] *= d[..., None]
    return U @ Vt


def uniform_rotations(n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` rotations drawn uniformly from SO(3) (Shoemake's unit quaternions)."""
    u1, u2, u3 = rng.random((3, n))
    q = np.stack(
        [
            np.sqrt(1 - u1) * np.sin(2 * np.pi * u2),
            np.sqrt(1 - u1) * np.cos(2 * np.pi * u2),
            np.sqrt(u1) * np.sin(2 * np.pi * u3),
            np.sqrt(u1) * np.cos(2 * np.pi * u3),
        ],
        -1,
    )
    return quat_to_matrix(q)


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """Unit quaternions (..., 4) as (x, y, z, w) → rotation matrices (..., 3, 3)."""
    x, y, z, w = np.moveaxis(q, -1, 0)
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
            np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
            np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1),
        ],
        -2,
    )


def spread_rotations(n: int) -> np.ndarray:
    """``n`` deterministic rotations spread evenly over SO(3) (super-Fibonacci spiral,
    Alexa 2022), used as multi-start seeds so that results are reproducible."""
    i = np.arange(n) + 0.5
    phi = np.sqrt(2.0)
    psi = 1.533751168755204288118041  # root of ψ⁴ = ψ + 4 (Alexa's constant)
    s = i / n
    r = np.sqrt(s)
    R_ = np.sqrt(1.0 - s)
    alpha = 2 * np.pi * i / phi
    beta = 2 * np.pi * i / psi
    q = np.stack([r * np.sin(alpha), r * np.cos(alpha), R_ * np.sin(beta), R_ * np.cos(beta)], -1)
    return quat_to_matrix(q)
