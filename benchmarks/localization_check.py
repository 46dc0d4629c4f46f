"""The pixel-level localisation bounds against the renderer they describe.

``xray/localization.py`` computes the Cramér–Rao σ of a ball's image centre and of a wire's
image position from its own fine-grid model of the detector (transmission blurred, then
integrated over the pixels). Here the same σ is taken from central differences of the
renderer's noise-free image (default imaging model, 667 mm, ±20 µm shifts, float64 chords)
at several sub-pixel offsets, as 1/√mean(Fisher information): a ball moved across the image
x axis, a 20 mm wire along x moved across it (information per mm of its image, from the
middle 10 mm of it). Printed: both σ and their ratio, per size.

    .venv/bin/python benchmarks/localization_check.py
"""

from __future__ import annotations

import dataclasses

import numpy as np
from _common import machine

from ftrac_design.features.model import Features, LineFeature, PointFeature
from ftrac_design.pose.camera import Camera
from ftrac_design.xray.localization import bead_sigma_mm, wire_sigma_mm
from ftrac_design.xray.model import ImagingModel
from ftrac_design.xray.render import expected_transmission

DEPTH = 667.0
OFFSETS = 6


def _features(points=(), lines=()) -> Features:
    return Features("probe", None, "-", np.array([0.0, -1.0, 0.0]), points=tuple(points), lines=tuple(lines))


def renderer_sigma(features: Features, axis: int, per_mm_columns: tuple[int, int] | None = None) -> float:
    """σ (detector mm) of a shift along image ``axis`` (0: x, 1: y) from the renderer's
    central differences; ``per_mm_columns``: (lo, hi) image columns whose information is
    divided by their length in detector mm (a wire's σ per mm of image)."""
    cam = Camera()
    im = dataclasses.replace(ImagingModel(), single_precision=False)
    M = cam.focal_length_mm / DEPTH
    h = 0.02
    e = np.zeros(3)
    e[axis] = h
    info = []
    for ox, oy in np.random.default_rng(0).uniform(0, cam.pixel_size_mm[0] / M, (OFFSETS, 2)):
        t = np.array([ox, oy, DEPTH])
        I0 = expected_transmission(features, np.eye(3), t, cam, im).astype(float)
        dI = (
            expected_transmission(features, np.eye(3), t + e, cam, im).astype(float)
            - expected_transmission(features, np.eye(3), t - e, cam, im).astype(float)
        ) / (2 * h)
        F = im.photons_per_px * dI**2 / I0 / M**2  # object mm → detector mm
        if per_mm_columns is not None:
            lo, hi = per_mm_columns
            info.append(F[:, lo:hi].sum() / ((hi - lo) * cam.pixel_size_mm[0]))
        else:
            info.append(F.sum())
    return float(1.0 / np.sqrt(np.mean(info)))


def main() -> None:
    print(f"localisation bound (xray/localization.py) vs the renderer's finite differences, depth {DEPTH:g} mm")
    print(f"machine: {machine()}")
    print(f"{'part':<14}{'bound σ µm':>12}{'renderer σ µm':>15}{'renderer / bound':>18}")
    cam = Camera()
    M = cam.focal_length_mm / DEPTH
    for d in (0.8, 1.0, 1.2):
        f = _features(points=[PointFeature("B1", np.zeros(3), d)])
        b, r = bead_sigma_mm(d, DEPTH), renderer_sigma(f, 0)
        print(f"{f'ball {d:g} mm':<14}{1e3 * b:>12.2f}{1e3 * r:>15.2f}{r / b:>18.3f}")
    half_cols = int(5.0 * M / cam.pixel_size_mm[0])
    c0 = int(cam.principal_point_px[0])
    for d in (0.3, 0.4, 0.5):
        f = _features(lines=[LineFeature("L1", np.array([-10.0, 0, 0]), np.array([10.0, 0, 0]), d)])
        b, r = wire_sigma_mm(d, DEPTH), renderer_sigma(f, 1, (c0 - half_cols, c0 + half_cols))
        print(f"{f'wire {d:g} mm':<14}{1e3 * b:>12.2f}{1e3 * r:>15.2f}{r / b:>18.3f}")


if __name__ == "__main__":
    main()
