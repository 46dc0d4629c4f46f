"""Shared pieces of the image-intake tests: a detector-grid test image and a camera whose
axes differ (so a swapped pitch or principal point shows)."""

from __future__ import annotations

import numpy as np

from ftrac_design.pose import Camera

#: s_x ≠ s_y and an off-centre principal point, so an axis swap cannot pass unnoticed
CAM = Camera(1100.0, (0.30, 0.40), (21.25, 13.5))


def stored(
    n: int = 1, shape: tuple[int, int] = (48, 64), bits: int = 12, seed: int = 0, signed: bool = False
) -> np.ndarray:
    """(n, H, W) random stored integers of ``bits`` bits (signed: two's-complement range)."""
    rng = np.random.default_rng(seed)
    if signed:
        return rng.integers(-(1 << (bits - 1)), 1 << (bits - 1), (n, *shape)).astype(np.int16)
    return rng.integers(0, 1 << bits, (n, *shape)).astype(np.uint16)
