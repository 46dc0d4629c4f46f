"""How precisely a ball's centre and a wire's position can be read from the image, by size.

The pixel-level Cramér–Rao bound of one feature's image position under this package's
imaging model (:mod:`.model`, :func:`.render.render`): steel transmission
``T = exp(−μ·chord)``, a Gaussian blur of the transmission (detector line spread and the
focal spot at magnification ``M = f / depth``, :func:`.render.blur_sigma_px`), integration
over square pixels and Poisson counts ``λ = N₀·T`` per pixel, whose Fisher information
about a shift ``s`` of the image is ``Σ (∂λ/∂s)² / λ`` over the pixels. Sub-pixel phases are
averaged. It answers one question the feature-level noise model cannot: *is a smaller
ball worth the room it frees?* A ball's shadow loses contrast and edge as it shrinks, so
its centre is read less precisely; the design optimiser scales a design's stated
segmentation error by these ratios when it changes stock sizes
(:func:`size_error_factors`).

Parallel projection of the part across its own small width (the ray's angle changes
by < 0.1° over a 2 mm ball at 600 mm) and no body or anatomy behind it (both lower the
counts by the same factor for every size, which cancels in a ratio). The derivative of a
pixel mean with respect to a shift is exact: the difference of the blurred profile at the
pixel's two edges over its width. Tested against finite differences of the renderer.
numpy only.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter1d

from ..pose.camera import Camera
from .model import ImagingModel
from .render import blur_sigma_px

#: sub-samples per pixel side (at least) of the fine grid the blurred transmission is evaluated on
FINE = 16
#: sub-pixel phases averaged per axis
PHASES = 8


def _chord(r_img: np.ndarray, radius_mm: float, magnification: float) -> np.ndarray:
    """Path length (mm) through a ball (or across a wire) of ``radius_mm`` along the ray
    hitting the detector ``r_img`` mm from the part's image centre (line)."""
    rho = np.asarray(r_img, float) / magnification
    return 2.0 * np.sqrt(np.clip(radius_mm**2 - rho**2, 0.0, None))


def _fine(width_mm: float, pix: float) -> int:
    # at least FINE samples per pixel and 16 across the part's image
    return max(FINE, int(np.ceil(16 * pix / width_mm)))


def _blur(a: np.ndarray, sigma_fine: float, axes: tuple[int, ...]) -> np.ndarray:
    # the transmission is 1 outside the part: constant 1 beyond the grid
    for ax in axes:
        if sigma_fine > 0:
            a = gaussian_filter1d(a, sigma_fine, axis=ax, mode="constant", cval=1.0, truncate=4.0)
    return a


def _setup(diameter_mm: float, depth_mm: float, camera: Camera, imaging: ImagingModel):
    if not (diameter_mm > 0 and depth_mm > 0):
        raise ValueError(f"diameter and depth: positive mm, got {diameter_mm!r}, {depth_mm!r}")
    if not imaging.noisy:
        raise ValueError("a pixel-level bound needs a finite dose (photons_per_px)")
    M = camera.focal_length_mm / depth_mm
    pix = float(np.mean(camera.pixel_size_mm))
    blur = float(np.mean(blur_sigma_px(camera, imaging, depth_mm)))
    half_px = int(np.ceil((diameter_mm * M / 2) / pix + 4 * blur + 2))
    return M, pix, blur, half_px, imaging.mu("steel"), float(imaging.photons_per_px)


def bead_sigma_mm(
    diameter_mm: float, depth_mm: float, camera: Camera = Camera(), imaging: ImagingModel = ImagingModel()
) -> float:
    """Cramér–Rao σ (detector mm, per image axis) of a steel ball's image centre.

    ``diameter_mm`` the ball's, ``depth_mm`` its distance from the source (sets the
    magnification and the focal-spot blur). Averaged over sub-pixel phases as 1/mean(info).
    """
    M, pix, blur, half, mu, N0 = _setup(diameter_mm, depth_mm, camera, imaging)
    fine = _fine(diameter_mm * M, pix)
    n = 2 * half * fine
    info = []
    for p in range(PHASES):
        for q in range(PHASES):
            # fine grid in detector mm, the ball's image centre at phase (p, q) of a pixel
            x = (np.arange(n) + 0.5) / fine * pix - half * pix - p / PHASES * pix
            y = (np.arange(n) + 0.5) / fine * pix - half * pix - q / PHASES * pix
            T = np.exp(-mu * _chord(np.hypot(x[None, :], y[:, None]), diameter_mm / 2, M))
            Tb = _blur(T, blur * fine, (0, 1))
            # pixel means, and their derivative for a shift along x: edge difference / width
            rows = Tb.reshape(2 * half, fine, n).mean(1)  # (px rows, fine x)
            lam = rows.reshape(2 * half, 2 * half, fine).mean(2)
            edges = np.concatenate([rows[:, ::fine], rows[:, -1:]], axis=1)  # approx. pixel edges
            dlam = -(edges[:, 1:] - edges[:, :-1]) / pix
            info.append(N0 * np.sum(dlam**2 / lam))
    return float(1.0 / np.sqrt(np.mean(info)))


def wire_sigma_mm(
    diameter_mm: float, depth_mm: float, camera: Camera = Camera(), imaging: ImagingModel = ImagingModel()
) -> float:
    """Cramér–Rao σ (detector mm) of a steel wire's image position across its length,
    from one millimetre of its image (σ of a longer stretch ∝ 1/√length).

    The wire is taken along a pixel axis; phases across it are averaged as 1/mean(info).
    """
    M, pix, blur, half, mu, N0 = _setup(diameter_mm, depth_mm, camera, imaging)
    fine = _fine(diameter_mm * M, pix)
    n = 2 * half * fine
    info = []
    for p in range(PHASES):
        x = (np.arange(n) + 0.5) / fine * pix - half * pix - p / PHASES * pix
        T = np.exp(-mu * _chord(x, diameter_mm / 2, M))
        Tb = _blur(T, blur * fine, (0,))
        lam = Tb.reshape(2 * half, fine).mean(1)
        edges = np.concatenate([Tb[::fine], Tb[-1:]])
        dlam = -(edges[1:] - edges[:-1]) / pix
        info.append(N0 * np.sum(dlam**2 / lam) / pix)  # per pixel row → per mm of image
    return float(1.0 / np.sqrt(np.mean(info)))


def size_error_factors(
    bead_mm: float | None,
    wire_mm: float | None,
    ref_bead_mm: float | None,
    ref_wire_mm: float | None,
    depth_mm: float,
    camera: Camera = Camera(),
    imaging: ImagingModel = ImagingModel(),
) -> tuple[float, float]:
    """(bead, wire) segmentation-error factors of parts of ``bead_mm`` / ``wire_mm`` relative
    to the reference sizes: σ(size) / σ(reference) from the pixel-level bound at ``depth_mm``.
    A missing size (None) gives 1."""
    kb = (
        bead_sigma_mm(bead_mm, depth_mm, camera, imaging) / bead_sigma_mm(ref_bead_mm, depth_mm, camera, imaging)
        if bead_mm and ref_bead_mm and bead_mm != ref_bead_mm
        else 1.0
    )
    kw = (
        wire_sigma_mm(wire_mm, depth_mm, camera, imaging) / wire_sigma_mm(ref_wire_mm, depth_mm, camera, imaging)
        if wire_mm and ref_wire_mm and wire_mm != ref_wire_mm
        else 1.0
    )
    return float(kb), float(kw)
