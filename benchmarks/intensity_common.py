"""Shared by the intensity benchmarks (``intensity_accuracy.py``, ``track_accuracy.py --intensity``):
one refinement judged against the pixel-level bound, and efficiencies with their intervals."""

from __future__ import annotations

import time

import numpy as np
from scipy.stats import chi2

from ftrac_design.intensity import pixel_information, refine_intensity
from ftrac_design.intensity.refine import DEFAULT_SPLINE_PX
from ftrac_design.pose import so3

AXES = ("rx", "ry", "rz", "tx", "ty", "tz")

#: refinement settings by name: the default ("auto": spline background, high-pass where the
#: image is cluttered, Huber 3σ), the plain gain + quadratic model, the earlier default
#: (high-pass 8 px + Huber), the spline always
MODES = {
    "default": {},
    "plain": {"background": "polynomial", "robust": None},
    "highpass": {"background": "highpass"},
    "spline": {"background": "spline"},
}


def pose_errors(R, t, R_true, t_true) -> np.ndarray:
    """(rx, ry, rz, tx, ty, tz): ``log(R R_trueᵀ)`` (camera axes, rad) and ``t − t_true`` (mm)."""
    return np.concatenate([so3.log(np.asarray(R) @ np.asarray(R_true).T), np.asarray(t) - t_true])


def efficiency(z: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per axis 1 / mean(z²) of z (m, 6) and its 95 % interval (if z ~ N(0, 1/E):
    m·mean(z²)·E ~ χ²ₘ)."""
    z = np.asarray(z, float).reshape(-1, 6)
    m, ms = len(z), np.mean(z**2, 0)
    return 1 / ms, chi2.ppf(0.025, m) / (m * ms), chi2.ppf(0.975, m) / (m * ms)


class Judge:
    """Refine starts on images of one pose and judge them against the pixel bound there:
    the bound with gain and a quadratic background unknown (``quad``; with a known
    ``background`` image its attenuation included) and with the default spline background
    unknown (``spline``); a result is judged against the one matching the background model
    it used (the high-pass against ``quad``, as before)."""

    def __init__(self, features, camera, imaging, R_true, t_true, background=None):
        self.features, self.camera, self.imaging = features, camera, imaging
        self.R, self.t = R_true, t_true
        self.quad = pixel_information(features, R_true, t_true, camera, imaging, background=background, nuisance=True)
        self.background = background
        self._spline = None

    @property
    def spline(self):
        if self._spline is None:
            self._spline = pixel_information(
                self.features,
                self.R,
                self.t,
                self.camera,
                self.imaging,
                background=self.background,
                nuisance=True,
                background_spline_px=DEFAULT_SPLINE_PX,
            )
        return self._spline

    def z(self, R, t, model: str = "polynomial") -> np.ndarray:
        """Error of pose (R, t) in units of the matching bound's σ."""
        b = self.spline if model == "spline" else self.quad
        return pose_errors(R, t, self.R, self.t) / b.std

    def z_quad(self, R, t) -> np.ndarray:
        """Error of pose (R, t) in units of the quadratic-background bound's σ."""
        return pose_errors(R, t, self.R, self.t) / self.quad.std

    def refine(self, raw, R0, t0, mode: str = "default", **options):
        """Refine (R0, t0) on ``raw`` counts: (result, z vs matching bound, z vs quadratic
        bound, (wall s, CPU s))."""
        w0, c0 = time.perf_counter(), time.process_time()
        res = refine_intensity(
            self.features,
            raw,
            self.camera,
            R0,
            t0,
            self.imaging,
            polarity="dense_dark",
            **{**MODES[mode], **options},
        )
        dt = (time.perf_counter() - w0, time.process_time() - c0)
        return (
            res,
            self.z(res.rotation, res.translation_mm, res.background_model),
            self.z_quad(res.rotation, res.translation_mm),
            dt,
        )
