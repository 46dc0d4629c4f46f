"""The image-true trial: render a fiducial at a fixed, seeded sample of workspace poses, track every
image with the default options and no initial guess, and record how each went.

Two imaging conditions:

- ``clean`` — :func:`ftrac_design.xray.render` with :class:`ftrac_design.xray.ImagingModel`'s
  defaults (60 keV, 10⁴ quanta per pixel, focal spot 0.6 mm, detector line spread 0.7 px), the
  design's body, raw counts;
- ``anatomy`` — :func:`ftrac_design.xray.scenario.realistic_image`'s ``raw`` condition: a patient
  (pelvis, spine, abdomen or chest) behind the fiducial, 1000–5000 quanta behind the patient, the
  C-arm's blur, scatter, flat-field residual and detector drawn per image; linear counts.

Common random numbers: image ``k`` of a trial with seed ``s`` has the same workspace pose (for
designs that share a nominal beam direction), the same noise draws and the same patient whatever
the design, so two designs' figures differ by the designs, not by the draws; a paired ratio of two
designs' figures is far tighter than either figure alone.

Every image is tracked with :class:`ftrac_design.segment.TrackOptions`' defaults but for the time
budget, which is lifted: a score measures the method, not how busy the machine was (with the
budget, a loaded machine refuses images that an idle one tracks, and the same seed would not give
the same figures).

An image ends in one of three ways: ``refused`` (the tracker returned no pose), ``wrong`` (a
confident wrong pose: converged, further than :data:`WRONG_DEG` or :data:`WRONG_MM` from the
truth, *and* further than :data:`WRONG_SIGMA` standard deviations by the pose's own reported
covariance — the tracker claims a precision the pose does not have) or ``right``. The covariance
test keeps the tail of an honest error distribution out of ``wrong``: a 1 × 1 × 2 cm fiducial over
a patient has a 1σ depth error near 1.3 mm, so 3 mm alone would cut its error distribution at
about 2.3σ and leave its p95 pinned below the cut whatever the design (measured on
``ftrac_mini``: 100 images per condition, the 6-D Mahalanobis distance of every converged pose
had median 1.6–1.8 and maximum 3.6, including poses 3–5 mm off; a mislabelled pose 130° off is
thousands of σ away). Lengths mm, angles degrees in the records.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from concurrent.futures import Executor
from dataclasses import dataclass
from typing import Any, Literal, get_args

import numpy as np

from ..analysis.sampling import workspace_poses
from ..features.model import Features
from ..pose.camera import Camera
from ..pose.simulate import Workspace, pose_errors

Condition = Literal["clean", "anatomy"]
CONDITIONS: tuple[Condition, ...] = get_args(Condition)
#: a converged pose further off than this is a wrong answer, not an inaccurate one ...
WRONG_DEG, WRONG_MM = 1.0, 3.0
#: ... if its 6-D error is also this many standard deviations away by its own covariance (a
#: calibrated 6-D Gaussian passes 6σ with probability 3·10⁻⁶)
WRONG_SIGMA = 6.0
#: images per task sent to an executor (amortises sending the features; small enough to balance)
CHUNK = 8


@dataclass(frozen=True)
class TrialSettings:
    """What the trial renders: how many images per condition, which conditions, the seed, the
    workspace and the camera (SPEC §1). Image ``k``'s draws depend on ``seed`` and ``k`` only."""

    images: int = 100
    conditions: tuple[Condition, ...] = CONDITIONS
    seed: int = 0
    workspace: Workspace = Workspace()
    camera: Camera = Camera()

    def describe(self) -> dict[str, Any]:
        """The imaging model in words and numbers, for a report's header."""
        from ..xray import ImagingModel

        m = ImagingModel()
        return {
            "images_per_condition": self.images,
            "seed": self.seed,
            "conditions": list(self.conditions),
            "clean": {
                "energy_kev": m.energy_kev,
                "photons_per_px": m.photons_per_px,
                "focal_spot_mm": m.focal_spot_mm,
                "detector_blur_px": m.detector_blur_px,
                "formation": "raw counts",
                "anatomy": None,
            },
            "anatomy": {
                "scenario": "raw",
                "patient": "pelvis, spine, abdomen or chest, 150–300 mm",
                "quanta_behind_patient": [1000, 5000],
                "energy_kev": "50–70 by thickness",
                "focal_spot_mm": [0.3, 1.2],
                "total_blur_px": [0.5, 0.9],
                "scatter_to_primary": [0.2, 1.2],
                "formation": "raw counts",
            },
            "wrong_if_beyond": {"rotation_deg": WRONG_DEG, "translation_mm": WRONG_MM, "sigma": WRONG_SIGMA},
        }


def _image(
    features: Features, condition: Condition, R: np.ndarray, t: np.ndarray, camera: Camera, seed: int, k: int
) -> np.ndarray:
    from ..xray import ImagingModel, render
    from ..xray.scenario import realistic_image

    if condition == "clean":
        return render(features, R, t, camera, ImagingModel(), rng=np.random.default_rng([seed, k, 1])).raw
    img, _ = realistic_image(features, R, t, camera, "raw", seed * 1_000_003 + k)
    return img


def track_record(image: np.ndarray, features: Features, R: np.ndarray, t: np.ndarray, camera: Camera) -> dict[str, Any]:
    """Track ``image`` with the default options (time budget lifted) and class the outcome against
    the true pose (R, t) (F → X, mm).

    Parameters
    ----------
    image : numpy.ndarray
        The radiograph.
    features : Features
        The fiducial, its body (``features.body``) as known to the tracker.
    R, t : numpy.ndarray
        The true pose, SPEC §1.
    camera : Camera
        The C-arm's intrinsics.

    Returns
    -------
    dict
        ``outcome`` (right / wrong / refused), ``translation_mm`` and ``rotation_deg`` (3-D errors,
        None when refused), ``sigma`` (the 6-D error's Mahalanobis distance by the pose's reported
        covariance; None when refused or without a covariance).
    """
    from ..segment.options import TrackOptions
    from ..segment.pipeline import track_image

    # a score tracks in as many processes as cores: one thread each (the same answers)
    pose = track_image(image, features, camera, TrackOptions(time_budget_s=math.inf, detector_threads=1)).pose
    rec: dict[str, Any] = {"outcome": "refused", "translation_mm": None, "rotation_deg": None, "sigma": None}
    if pose.converged:
        dr, dt = pose_errors(pose.rotation, pose.translation_mm, R, t)
        a, d = math.degrees(float(np.linalg.norm(dr))), float(np.linalg.norm(dt))
        sigma = error_sigma(np.r_[dr, dt], pose.covariance)
        rec.update(outcome=outcome(a, d, sigma), translation_mm=d, rotation_deg=a, sigma=sigma)
    return rec


def error_sigma(error: np.ndarray, covariance: np.ndarray | None) -> float | None:
    """Mahalanobis distance √(eᵀ Σ⁻¹ e) of a pose error ``e`` = (δr rad, δt mm) under the pose's
    reported covariance Σ (same order, SPEC §1); None without a usable covariance."""
    if covariance is None:
        return None
    c = np.asarray(covariance, float)
    if c.shape != (6, 6) or not np.all(np.isfinite(c)):
        return None
    try:
        v = float(error @ np.linalg.solve(c, error))
    except np.linalg.LinAlgError:
        return None
    return math.sqrt(v) if math.isfinite(v) and v >= 0 else None


def outcome(rotation_deg: float, translation_mm: float, sigma: float | None) -> Literal["right", "wrong"]:
    """Class of a converged pose: ``wrong`` when it is beyond :data:`WRONG_DEG` or
    :data:`WRONG_MM` and beyond :data:`WRONG_SIGMA` standard deviations of its own covariance
    (beyond the thresholds alone when it has none), else ``right``.

    Parameters
    ----------
    rotation_deg, translation_mm : float
        The 3-D rotation (degrees) and translation (mm) errors.
    sigma : float or None
        :func:`error_sigma` of the error.

    Returns
    -------
    {"right", "wrong"}
    """
    far = rotation_deg > WRONG_DEG or translation_mm > WRONG_MM
    return "wrong" if far and (sigma is None or sigma > WRONG_SIGMA) else "right"


def run_images(
    features: Features, settings: TrialSettings, condition: Condition, indices: Sequence[int]
) -> list[dict[str, Any]]:
    """Render and track images ``indices`` of one condition; one record per image.

    Parameters
    ----------
    features : Features
        The fiducial (SPEC §2); its acetal body (``features.body``), where known, is rendered and
        known to the tracker.
    settings : TrialSettings
        The sample (poses and draws are fixed by ``settings.seed`` and the index).
    condition : {"clean", "anatomy"}
        The imaging condition.
    indices : sequence of int
        Which images of the sample, each in ``range(settings.images)``.

    Returns
    -------
    list of dict
        ``{"condition", "k", "outcome": "right"|"wrong"|"refused", "translation_mm",
        "rotation_deg", "sigma"}`` — the 3-D errors and their distance by the pose's own covariance
        (None when refused).
    """
    R, t = workspace_poses(settings.workspace, features.nominal_beam_direction, settings.images, settings.seed)
    out = []
    for k in indices:
        img = _image(features, condition, R[k], t[k], settings.camera, settings.seed, int(k))
        out.append({"condition": condition, "k": int(k), **track_record(img, features, R[k], t[k], settings.camera)})
    return out


def run_trial(
    features: Features,
    settings: TrialSettings,
    executor: Executor | None = None,
    progress: Callable[[int], None] | None = None,
) -> list[dict[str, Any]]:
    """Every image of the trial, in (condition, k) order, whatever the executor.

    Parameters
    ----------
    features, settings
        As :func:`run_images`.
    executor : concurrent.futures.Executor or None
        Where the images are made and tracked, in chunks of :data:`CHUNK` (None: here, in turn).
    progress : callable or None
        Called with the number of images finished after each chunk.

    Returns
    -------
    list of dict
        :func:`run_images`' records of every condition and image.
    """
    tasks = [
        (c, list(range(i, min(i + CHUNK, settings.images))))
        for c in settings.conditions
        for i in range(0, settings.images, CHUNK)
    ]
    if executor is None:
        out = []
        for c, idx in tasks:
            out += run_images(features, settings, c, idx)
            if progress:
                progress(len(idx))
        return out
    futures = [executor.submit(run_images, features, settings, c, idx) for c, idx in tasks]
    out = []
    for fut, (_, idx) in zip(futures, tasks):
        out += fut.result()
        if progress:
            progress(len(idx))
    return out
