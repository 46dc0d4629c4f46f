"""The C-arm's pinhole model (SPEC §1).

``u = (f / s_x) X / Z + o_x``, ``v = (f / s_y) Y / Z + o_y`` with X, Y, Z in the camera
frame X (origin at the source, ``+z`` the principal ray toward the detector), f the
source-to-detector distance (mm), ``s_x, s_y`` the pixel pitch (mm/pixel) and
``(o_x, o_y)`` the principal point (pixels).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class Camera:
    """Intrinsics of one image: focal length f (mm), pixel pitch (mm), principal point (px)."""

    focal_length_mm: float = 1000.0
    pixel_size_mm: tuple[float, float] = (0.44, 0.44)
    principal_point_px: tuple[float, float] = (512.0, 512.0)

    @property
    def fx(self) -> float:
        """f / s_x, pixels."""
        return self.focal_length_mm / self.pixel_size_mm[0]

    @property
    def fy(self) -> float:
        """f / s_y, pixels."""
        return self.focal_length_mm / self.pixel_size_mm[1]

    @property
    def K(self) -> np.ndarray:
        """3×3 intrinsic matrix mapping camera-frame directions to homogeneous pixels."""
        return np.array(
            [[self.fx, 0.0, self.principal_point_px[0]], [0.0, self.fy, self.principal_point_px[1]], [0.0, 0.0, 1.0]]
        )

    @property
    def intrinsics(self) -> np.ndarray:
        """(fx, fy, ox, oy) in pixels, the form the batched solver uses."""
        return np.array([self.fx, self.fy, *self.principal_point_px], float)

    def project(self, P: np.ndarray) -> np.ndarray:
        """Pixels (..., 2) of camera-frame points P (..., 3), mm."""
        P = np.asarray(P, float)
        return np.stack(
            [
                self.fx * P[..., 0] / P[..., 2] + self.principal_point_px[0],
                self.fy * P[..., 1] / P[..., 2] + self.principal_point_px[1],
            ],
            -1,
        )

    def to_dict(self) -> dict[str, Any]:
        """SPEC §3 ``camera`` object."""
        return {
            "focal_length_mm": self.focal_length_mm,
            "pixel_size_mm": list(self.pixel_size_mm),
            "principal_point_px": list(self.principal_point_px),
        }

    def perturbed(
        self,
        d_focal_mm: float = 0.0,
        d_pixel_mm: tuple[float, float] = (0.0, 0.0),
        d_principal_px: tuple[float, float] = (0.0, 0.0),
    ) -> "Camera":
        """A copy with calibration errors added (paper §III.A)."""
        return Camera(
            self.focal_length_mm + d_focal_mm,
            (self.pixel_size_mm[0] + d_pixel_mm[0], self.pixel_size_mm[1] + d_pixel_mm[1]),
            (self.principal_point_px[0] + d_principal_px[0], self.principal_point_px[1] + d_principal_px[1]),
        )

    def validate(self) -> None:
        """Raise ValueError unless every intrinsic is finite and positive where it must be."""
        vals = [self.focal_length_mm, *self.pixel_size_mm, *self.principal_point_px]
        if not all(math.isfinite(v) for v in vals):
            raise ValueError("finite numbers")
        if self.focal_length_mm <= 0 or min(self.pixel_size_mm) <= 0:
            raise ValueError("a positive focal length and pixel size")
