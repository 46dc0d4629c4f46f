"""The image-true design score: how well a fiducial tracks from radiographs, measured.

The paper's score (:mod:`ftrac_design.analysis`) is the feature-level Cramér–Rao bound with an
independent 0.25 mm error per feature; it does not rank designs the way images do (thin wires and
small balls lose contrast, features overlap, labellings fail, anatomy hides them). This score
renders the design at a fixed, seeded sample of workspace poses, clean and over a patient, tracks
every image as ``ftrac-design track`` does, and reports the share refused and wrong and the p95
of the right poses' errors with their intervals.

- :mod:`.trial` — the sample, the two imaging conditions, one record per image, any executor;
- :mod:`.figures` — the figures and two designs' paired ratios (common random numbers).
"""

from .figures import condition_figures, paired_ratios, trial_figures
from .trial import (
    CONDITIONS,
    WRONG_DEG,
    WRONG_MM,
    WRONG_SIGMA,
    Condition,
    TrialSettings,
    error_sigma,
    outcome,
    run_images,
    run_trial,
)

__all__ = [
    "CONDITIONS",
    "Condition",
    "TrialSettings",
    "WRONG_DEG",
    "WRONG_MM",
    "WRONG_SIGMA",
    "error_sigma",
    "outcome",
    "condition_figures",
    "paired_ratios",
    "run_images",
    "run_trial",
    "trial_figures",
]
