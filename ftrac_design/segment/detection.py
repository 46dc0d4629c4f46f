"""What the image shows before any labelling: expected sizes, the background-free density,
its noise, bead candidates fitted with the blurred-sphere model and wire ridge points.

:class:`Scene` holds one image's detections together with the design, the camera and the
options, so that the labelling, the acceptance tests and the body subtraction take one
argument instead of eight.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..features.model import Features
from ..pose import Camera
from .beads import Beads, blob_candidates, fit_beads
from .image import noise_sigma, top_hat
from .options import TrackOptions
from .ridges import RidgePoints, ridge_points


@dataclass(frozen=True)
class Scales:
    """Expected sizes in pixels at the assumed magnification (``TrackOptions.magnification``)."""

    #: the largest ball's radius, px
    bead_radius_px: float
    #: the thickest wire's width, px
    wire_px: float
    #: mean pixel pitch, mm
    pixel_mm: float
    #: scale of the ridge detector, px
    ridge_sigma_px: float
    #: radius of the top-hat's disc, px: wider than any ball or wire with its blur
    disc_px: int


def scales(features: Features, camera: Camera, opts: TrackOptions) -> Scales:
    """Expected sizes in pixels of ``features`` seen with ``camera`` at the assumed
    magnification: bead radius, wire width, ridge scale and top-hat disc.

    Parameters
    ----------
    features : the design's features (mm).
    camera : intrinsics (SPEC §1).
    opts : the image path's options (magnification, starting blur).

    Returns
    -------
    Scales
    """
    pix = float(np.mean(camera.pixel_size_mm))
    m = opts.magnification
    bead = max((p.diameter for p in features.points), default=0.0) / 2 * m / pix
    wires = [ln.wire_diameter for ln in features.lines] + [e.wire_diameter for e in features.ellipses]
    wire = (max(wires) if wires else 0.0) * m / pix
    disc = int(math.ceil(max(bead, wire) + 3 * opts.blur_px + 2))
    return Scales(bead, wire, pix, max(1.0, 0.5 * wire + 0.5), disc)


@dataclass(frozen=True)
class Scene:
    """One density image's detections, with what they were found for."""

    features: Features
    camera: Camera
    opts: TrackOptions
    scales: Scales
    #: background-free density image (white top-hat, dense = bright)
    T: np.ndarray
    #: robust pixel noise σ of ``T``
    noise: float
    beads: Beads | None
    ridges: RidgePoints | None

    @property
    def shape(self) -> tuple[int, int]:
        """(H, W) of the image searched."""
        return self.T.shape

    def bead_exclusion(self, extra_px: float = 1.0) -> np.ndarray:
        """Per model bead, the radius (px) within which wire evidence is not read: the ball's
        blurred image and ``extra_px``."""
        return np.full(len(self.features.points), self.scales.bead_radius_px + 2 * self.opts.blur_px + extra_px)

    def with_detections(self, T: np.ndarray, beads: Beads | None, ridges: RidgePoints | None) -> "Scene":
        """The same scene with other detections (the body subtracted)."""
        return Scene(self.features, self.camera, self.opts, self.scales, T, self.noise, beads, ridges)


def _bead_candidates(T: np.ndarray, features: Features, sc: Scales, noise: float, opts: TrackOptions) -> Beads:
    rb = sc.bead_radius_px
    P = len(features.points)
    cand, resp = blob_candidates(T, rb, noise, 3 * P + 6, opts.bead_min_snr)
    if len(cand):
        # the beads are the strongest blobs; anything far weaker is a wire crossing or clutter
        ref = np.sort(resp)[::-1][: P]
        keep = resp >= 0.25 * float(np.median(ref))
        cand, resp = cand[keep], resp[keep]
    b = fit_beads(T, cand, rb, opts.blur_px, noise, resp)
    # a fit that ran off (amplitude far from the others', radius or blur at a bound) is
    # redone with priors 25× stronger (σ_prior / 5)
    if len(b) > 2:
        med = float(np.median(b.amplitude))
        bad = ~((b.amplitude > 0.2 * med) & (b.amplitude < 5 * med) & np.isfinite(b.sigma_px))
        if bad.any():
            b2 = fit_beads(T, cand[bad], rb, opts.blur_px, noise, resp[bad], prior_scale=25.0)
            for k in b.__dataclass_fields__:
                getattr(b, k)[bad] = getattr(b2, k)
    H, W = T.shape
    edge = rb + 2 * opts.blur_px + 1
    ok = (np.isfinite(b.uv).all(1) & (b.radius > 0.5 * rb) & (b.radius < 2.0 * rb) & (b.blur < 3.0)
          & (b.amplitude > 0)
          & (b.uv[:, 0] > edge) & (b.uv[:, 1] > edge) & (b.uv[:, 0] < W - 1 - edge)
          & (b.uv[:, 1] < H - 1 - edge) & np.isfinite(b.sigma_px))
    return b.take(ok)


def detect(g: np.ndarray, features: Features, camera: Camera, opts: TrackOptions) -> Scene:
    """Background-free image, noise σ, fitted bead candidates and ridge points of the density
    image ``g`` (dense = bright).

    Parameters
    ----------
    g : (H, W) density image.
    features, camera, opts : the design, the intrinsics of ``g``'s pixels, the options.

    Returns
    -------
    Scene
    """
    sc = scales(features, camera, opts)
    T = top_hat(g, sc.disc_px)
    noise = max(noise_sigma(T), 1e-9)
    beads = _bead_candidates(T, features, sc, noise, opts) if features.points else None
    ridges = None
    if features.lines or features.ellipses:
        ridges = ridge_points(T, sc.ridge_sigma_px, noise, opts.ridge_min_snr)
    return Scene(features, camera, opts, sc, T, noise, beads, ridges)
