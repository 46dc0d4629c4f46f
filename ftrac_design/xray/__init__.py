"""Radiograph simulator and image files: a fiducial at a pose → X-ray image (+ truth).

- :func:`render` — Beer–Lambert image of a :class:`~ftrac_design.features.Features` at a
  pose, with blur, quantum noise, background and occluders (:mod:`.render`).
- :class:`ImagingModel`, :class:`Occluder`, :class:`Radiograph` (:mod:`.model`); the body
  rendered is the features' own (:attr:`~ftrac_design.features.Features.body`).
- :func:`read_image` / :func:`write_image` — re-exported from :mod:`ftrac_design.images`.
- :func:`anatomy` — a synthetic anatomy-like background (:mod:`.background`).
- :func:`.patient.patient` / :func:`seeds` — a patient's line integral (spine, ribs, lungs,
  pelvis, gas) and brachytherapy seeds (:mod:`.patient`; the package's ``patient`` is that
  module); :func:`apply_chain` / :func:`n0_for_counts` — a C-arm's detector and display chain
  (:mod:`.display`); :func:`realistic_image` — a complete test image for a named condition
  (:mod:`.scenario`).
- truth.json (:mod:`.truth`); attenuation coefficients (:mod:`.materials`).
"""

from .model import ImagingModel, Occluder, Radiograph
from .render import blur_sigma_px, expected_transmission, line_integral_box, render
from .truth import projected_features, read_truth, truth_dict, write_truth

__all__ = [
    "ImagingModel",
    "Occluder",
    "Radiograph",
    "render",
    "expected_transmission",
    "line_integral_box",
    "blur_sigma_px",
    "projected_features",
    "read_truth",
    "truth_dict",
    "write_truth",
    "read_image",
    "write_image",
    "anatomy",
    "seeds",
    "apply_chain",
    "n0_for_counts",
    "realistic_image",
]

_LAZY = {"seeds": "patient", "apply_chain": "display", "n0_for_counts": "display", "realistic_image": "scenario"}


def __getattr__(name):
    # image-file and background modules import imaging libraries: load them on first use
    if name in ("read_image", "write_image"):
        from .. import images

        return getattr(images, name)
    if name == "anatomy":
        from .background import anatomy

        return anatomy
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
    raise AttributeError(name)
