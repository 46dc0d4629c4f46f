"""Intensity-based pose: the simulator's derivative, the pixel-level Cramér–Rao bound, refinement.

- :class:`RoiModel` — the noise-free log image over a region of interest and its
  derivative with respect to the pose (:mod:`.model`).
- :func:`pixel_information` — Fisher information / Cramér–Rao bound of the pose from the
  pixels at a stated dose, blur and background (:mod:`.bound`).
- :func:`refine_intensity` — Gauss–Newton/LM fit of the simulated image to a radiograph,
  with gain and a smooth background as nuisance parameters, tuned by :class:`RefineOptions`
  (:mod:`.refine`; the background's
  B-spline / polynomial basis and its elimination: :mod:`.background`).
- :func:`imaging_analysis` — that bound over workspace poses beside the feature-level one
  (``analyze --imaging``; :mod:`.workspace`).
"""

from .bound import PixelBound, pixel_information
from .model import PARAMETERS, RoiModel, perturb, roi_around
from .refine import IntensityResult, RefineOptions, refine_intensity, refine_track_result
from .workspace import ImagingAnalysis, imaging_analysis

__all__ = [
    "PARAMETERS",
    "ImagingAnalysis",
    "IntensityResult",
    "imaging_analysis",
    "PixelBound",
    "RoiModel",
    "perturb",
    "pixel_information",
    "RefineOptions",
    "refine_intensity",
    "refine_track_result",
    "roi_around",
]
