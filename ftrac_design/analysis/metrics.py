"""Conditioning and predicted accuracy from the Fisher information of a batch of poses.

Given the information I (B, 6, 6) of a set of features — unscaled, rotation (rad) then
translation (mm), camera axes — and the solver's parameter scaling H (paper §II.B.5,
:func:`ftrac_design.pose.solver.parameter_scale`: rotation in units of 1/ρ_F rad so that a
unit step in any parameter moves the features by about 1 mm), the scaled whitened Jacobian
J_s = J H has singular values σ₁ ≥ … ≥ σ₆ with σᵢ² the eigenvalues of H I H. From them:

- condition number σ₁/σ₆ and σ_min = σ₆ (the weakest direction, in 1/σ per scaled unit);
- observability indices from robot calibration (Borm & Menq 1991; Nahvi & Hollerbach
  1996): D-optimality ``(Π σᵢ)^(1/6) / √m`` (m = the solver's residual rows) and the
  noise amplification ``σ_min² / σ_max``;
- the predicted covariance I⁻¹ (the Cramér–Rao bound): standard deviations of the
  translation per camera axis (mm, z = depth) and of the rotation about each camera axis
  (rad), and their root-sum-squares, the 3-D RMS errors the design score uses.

Singular sets (e.g. three parallel lines alone, which cannot see a slide along them) get
condition ``inf`` and infinite predicted errors.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: a scaled information eigenvalue below this fraction of the largest counts as zero
RANK_TOL = 1e-13


@dataclass
class PoseMetrics:
    """Per-pose figures (arrays of length B); see the module docstring for definitions."""

    sigma: np.ndarray  # (B, 6) singular values of the scaled whitened Jacobian, descending
    condition: np.ndarray  # (B,)
    sigma_min: np.ndarray  # (B,)
    d_optimality: np.ndarray  # (B,)
    noise_amplification: np.ndarray  # (B,)
    rotation_std_rad: np.ndarray  # (B, 3) about camera x, y, z
    translation_std_mm: np.ndarray  # (B, 3) along camera x, y, z (z: depth)

    @property
    def rotation_rms_deg(self) -> np.ndarray:
        """3-D RMS rotation error (root of the rotation covariance's trace), degrees."""
        return np.degrees(np.sqrt(np.sum(self.rotation_std_rad**2, -1)))

    @property
    def translation_rms_mm(self) -> np.ndarray:
        """3-D RMS translation error (root of the translation covariance's trace), mm."""
        return np.sqrt(np.sum(self.translation_std_mm**2, -1))


def pose_metrics(info: np.ndarray, h: np.ndarray, m: int) -> PoseMetrics:
    """Metrics of information matrices ``info`` (B, 6, 6) with parameter scaling ``h`` (6,)
    and ``m`` solver residual rows."""
    info = np.asarray(info, float)
    Is = info * h[:, None] * h[None, :]
    lam = np.linalg.eigvalsh(Is)  # ascending
    singular = lam[:, 0] <= RANK_TOL * lam[:, -1]
    sigma = np.sqrt(np.clip(lam[:, ::-1], 0.0, None))
    # I⁻¹ = H (H I H)⁻¹ H; singular rows get an identity stand-in and infinite variances
    cov_s = np.linalg.inv(np.where(singular[:, None, None], np.eye(6), Is))
    var_s = np.where(singular[:, None], np.inf, np.diagonal(cov_s, axis1=1, axis2=2))
    with np.errstate(divide="ignore", invalid="ignore"):
        cond = np.where(singular, np.inf, sigma[:, 0] / sigma[:, -1])
        d_opt = np.exp(np.mean(np.log(sigma), -1)) / np.sqrt(m)
        amp = sigma[:, -1] ** 2 / sigma[:, 0]
    std = np.sqrt(var_s) * h
    return PoseMetrics(sigma, cond, sigma[:, -1], d_opt, amp, std[:, :3], std[:, 3:])


def rank_ratio(info: np.ndarray, h: np.ndarray, rank: int) -> np.ndarray:
    """σ_rank / σ₁ of scaled information matrices (B, 6, 6): how far a feature that should
    constrain ``rank`` directions of the pose is from losing one (0 = blind)."""
    lam = np.linalg.eigvalsh(np.asarray(info, float) * h[:, None] * h[None, :])[:, ::-1]
    lam = np.clip(lam, 0.0, None)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(lam[:, 0] > 0, np.sqrt(lam[:, rank - 1] / lam[:, 0]), 0.0)
