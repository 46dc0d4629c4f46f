"""A synthetic, anatomy-like background (a line-integral image) for benchmarks and tests.

Not a phantom of any patient: a reproducible clutter with the kinds of structure a pelvic
radiograph puts behind the fiducial — smooth soft-tissue thickness changes (filtered noise,
tens of pixels), bone-like hollow shells and bands with sharp cortical edges (exact chords
of hollow elliptic cylinders of cortical bone, μ from :mod:`.materials`), gas pockets (less
attenuation) and fine texture. Values are line integrals (dimensionless, dense = bright)
about a zero mean tissue level: the imaging model's ``photons_per_px`` is taken as the
quanta reaching the detector through the average patient (automatic exposure control).
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter, zoom

from .materials import linear_attenuation


def _smooth_noise(rng: np.random.Generator, shape: tuple[int, int], scale_px: float) -> np.ndarray:
    """Zero-mean, unit-std Gaussian random field with correlation length ~``scale_px``."""
    H, W = shape
    k = max(1, int(scale_px // 4))
    small = rng.standard_normal((H // k + 4, W // k + 4)).astype(np.float32)
    small = gaussian_filter(small, scale_px / k / 2.0, mode="wrap")
    big = zoom(small, k, order=1)[:H, :W] if k > 1 else small[:H, :W]
    big -= big.mean()
    return big / max(float(big.std()), 1e-12)


def _shell(U: np.ndarray, V: np.ndarray, c, axes, angle: float, wall: float) -> np.ndarray:
    """Chord length (px) of rays along the beam through a hollow elliptic cylinder whose
    cross-section (in the image) has semi-axes ``axes`` and wall thickness ``wall`` px."""
    ca, sa = np.cos(angle), np.sin(angle)
    x = (U - c[0]) * ca + (V - c[1]) * sa
    y = -(U - c[0]) * sa + (V - c[1]) * ca
    # depth through an elliptic cylinder lying in the image plane: chord of its section
    r2 = (x / axes[0]) ** 2 + (y / axes[1]) ** 2
    outer = 2 * axes[1] * np.sqrt(np.maximum(1 - r2, 0))
    ai, bi = axes[0] - wall, axes[1] - wall
    ri2 = (x / ai) ** 2 + (y / bi) ** 2
    inner = 2 * bi * np.sqrt(np.maximum(1 - ri2, 0))
    return (outer - inner).astype(np.float32)


def anatomy(
    shape: tuple[int, int] = (1024, 1024),
    seed: int = 0,
    pixel_mm: float = 0.44,
    strength: float = 1.0,
    energy_kev: float = 60.0,
) -> np.ndarray:
    """A reproducible anatomy-like line-integral image (H, W) float32 (see the module).

    ``seed`` fixes it; ``strength`` scales every structure; ``pixel_mm`` converts the bone
    shells' sizes (drawn in mm at the detector) into pixels.
    """
    rng = np.random.default_rng(seed)
    H, W = shape
    out = 0.15 * _smooth_noise(rng, shape, 120.0) + 0.05 * _smooth_noise(rng, shape, 30.0)
    V, U = np.mgrid[0:H, 0:W].astype(np.float32)
    mu_bone_px = linear_attenuation("bone", energy_kev) * pixel_mm * 0.5  # cortical bone of half density
    for _ in range(rng.integers(2, 4)):
        c = (rng.uniform(0, W), rng.uniform(0, H))
        a = rng.uniform(60, 200) / pixel_mm * 0.44
        axes = (a, a * rng.uniform(0.5, 1.0))
        wall = rng.uniform(3, 8)
        out += mu_bone_px * _shell(U, V, c, axes, rng.uniform(0, np.pi), wall)
    # a long bone-like band (femur/ramus): a hollow cylinder seen side-on
    c = (rng.uniform(0.2, 0.8) * W, rng.uniform(0.2, 0.8) * H)
    out += mu_bone_px * _shell(U, V, c, (4 * max(H, W), rng.uniform(40, 80)), rng.uniform(0, np.pi), 6.0)
    # gas pockets: less attenuation
    for _ in range(rng.integers(1, 4)):
        c = (rng.uniform(0, W), rng.uniform(0, H))
        r = rng.uniform(15, 50)
        out -= 0.15 * np.exp(-((U - c[0]) ** 2 + (V - c[1]) ** 2) / (2 * r * r))
    out += 0.01 * _smooth_noise(rng, shape, 3.0)
    out = gaussian_filter(out, 0.8)
    out -= out.min()
    return (strength * out).astype(np.float32)
