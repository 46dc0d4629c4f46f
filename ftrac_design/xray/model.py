"""Settings and results of the radiograph simulator: imaging model, occluders, image (the
fiducial's body is the design's :class:`~ftrac_design.design.Body`, carried by its features).

The default imaging model (every field's default) is a C-arm with an image-intensifier or
flat-panel pixel of 0.44 mm (SPEC §1 camera), a 0.6 mm focal spot, a detector line-spread
of Gaussian σ = 0.7 px, 10 000 unattenuated quanta per pixel and 16-bit raw output at an
effective energy of 60 keV.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any, Mapping

import numpy as np

from ..pose.camera import Camera
from .materials import linear_attenuation, material_name


@dataclass(frozen=True)
class ImagingModel:
    """How the image is formed. Lengths mm, blur in detector pixels.

    - ``focal_spot_mm``: nominal focal-spot size, taken as the FWHM of a Gaussian source; at
      the detector it blurs by (M − 1) × focal spot, M = f / depth of the fiducial origin.
    - ``detector_blur_px``: Gaussian σ of the detector's line-spread function, pixels.
    - ``photons_per_px``: unattenuated quanta per pixel (the dose); ``None`` or ``inf`` = no noise.
    - ``bit_depth``: raw output quantisation (8–16 bits); the flat field sits at 80 % of full scale.
    - ``attenuation_per_mm``: overrides of μ (1/mm) by material name (``steel``, ``acetal``, …);
      the rest come from :mod:`.materials` at ``energy_kev``.
    - ``supersample``: s, where the line integral is not smooth (wires, beads, body edges)
      each pixel is sampled at s² points (a rotated grid); the detector integrates their
      transmissions (:func:`.render.detected_deficit`).
    - ``single_precision``: evaluate the wire and body chords of the sub-samples in float32
      (about twice as fast; sub-sample chords stay within 2 µm, pixel line integrals within
      2e-3 of the float64 result, < 4e-4 on all but ~0.1 % of the fiducial's pixels);
      False gives float64 throughout.
    """

    energy_kev: float = 60.0
    image_shape: tuple[int, int] = (1024, 1024)
    focal_spot_mm: float = 0.6
    detector_blur_px: float = 0.7
    photons_per_px: float | None = 1.0e4
    bit_depth: int = 16
    attenuation_per_mm: Mapping[str, float] | None = None
    supersample: int = 5
    single_precision: bool = True

    def __post_init__(self) -> None:
        if not 40.0 <= self.energy_kev <= 100.0:
            raise ValueError(f"energy_kev: 40–100 keV, got {self.energy_kev!r}")
        H, W = self.image_shape
        if int(H) != H or int(W) != W or H < 8 or W < 8:
            raise ValueError(f"image_shape: two integers ≥ 8, got {self.image_shape!r}")
        object.__setattr__(self, "image_shape", (int(H), int(W)))
        if not (self.focal_spot_mm >= 0 and self.detector_blur_px >= 0):
            raise ValueError("focal_spot_mm, detector_blur_px: non-negative numbers")
        if self.photons_per_px is not None and not self.photons_per_px > 0:
            raise ValueError(f"photons_per_px: a positive number or None, got {self.photons_per_px!r}")
        if not 1 <= int(self.bit_depth) <= 16:
            raise ValueError(f"bit_depth: 1–16, got {self.bit_depth!r}")
        if int(self.supersample) < 1:
            raise ValueError("supersample: a positive integer")
        if self.attenuation_per_mm is not None:
            object.__setattr__(
                self,
                "attenuation_per_mm",
                {material_name(k): float(v) for k, v in dict(self.attenuation_per_mm).items()},
            )

    @property
    def noisy(self) -> bool:
        """Whether quantum noise is simulated."""
        return self.photons_per_px is not None and math.isfinite(self.photons_per_px)

    def mu(self, material: str) -> float:
        """Linear attenuation coefficient (1/mm) of ``material`` in this model."""
        name = material_name(material)
        if self.attenuation_per_mm and name in self.attenuation_per_mm:
            return self.attenuation_per_mm[name]
        return linear_attenuation(name, self.energy_kev)

    @property
    def full_scale(self) -> int:
        """Largest raw value, 2^bit_depth − 1."""
        return (1 << int(self.bit_depth)) - 1

    @property
    def raw_gain(self) -> float:
        """Raw units per quantum: the flat field (no object) reads 80 % of full scale."""
        n0 = self.photons_per_px if self.noisy else 1.0e4
        return 0.8 * self.full_scale / n0

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (truth.json ``imaging``); ``photons_per_px`` None when noise-free; adds the
        derived ``mu_per_mm`` (coefficients in effect) and ``raw_gain`` (raw units per quantum)."""
        d = asdict(self)
        d["image_shape"] = list(self.image_shape)
        d["photons_per_px"] = self.photons_per_px if self.noisy else None
        d["attenuation_per_mm"] = None if self.attenuation_per_mm is None else dict(self.attenuation_per_mm)
        # the coefficients in effect (derived; from_dict ignores them)
        d["mu_per_mm"] = {m: self.mu(m) for m in ("steel", "acetal")} | dict(self.attenuation_per_mm or {})
        d["raw_gain"] = self.raw_gain
        return d

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "ImagingModel":
        """Inverse of :meth:`to_dict` (unknown keys ignored)."""
        keys = {f for f in cls.__dataclass_fields__}
        kw = {k: v for k, v in d.items() if k in keys}
        if "image_shape" in kw:
            kw["image_shape"] = tuple(kw["image_shape"])
        return cls(**kw)


@dataclass(frozen=True)
class Occluder:
    """A cylinder segment that crosses the view (a needle, a rod, a guide wire), mm.

    ``start``/``end`` are the centre-line's end-points in ``frame`` ("F" fiducial or "X" camera).
    """

    start: tuple[float, float, float]
    end: tuple[float, float, float]
    diameter: float = 1.27  # an 18 G brachytherapy needle
    material: str = "steel"
    frame: str = "F"

    def __post_init__(self) -> None:
        if self.frame not in ("F", "X"):
            raise ValueError(f"frame: 'F' or 'X', got {self.frame!r}")
        if not self.diameter > 0:
            raise ValueError("diameter: a positive number (mm)")
        object.__setattr__(self, "start", tuple(float(x) for x in self.start))
        object.__setattr__(self, "end", tuple(float(x) for x in self.end))
        material_name(self.material)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict."""
        return {
            "start": list(self.start),
            "end": list(self.end),
            "diameter": self.diameter,
            "material": self.material,
            "frame": self.frame,
        }


@dataclass
class Radiograph:
    """One simulated image (``img[row, col]``, the pixel ``img[j, i]`` centred at (u, v) = (i, j))."""

    line_integral: np.ndarray  # (H, W) float64 noise-free −ln(I/I0) after blur, dense = bright
    log_image: np.ndarray  # (H, W) float64 flat-field/log image with noise, dense = bright
    raw: np.ndarray  # (H, W) uint8/uint16 detector counts, dense = DARK
    camera: Camera
    rotation: np.ndarray
    translation_mm: np.ndarray
    truth: dict = field(default_factory=dict)
