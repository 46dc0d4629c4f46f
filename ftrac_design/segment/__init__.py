"""X-ray image → SPEC §3 observation → pose, for any design, with no initial guess.

- :func:`track_image` (:mod:`.pipeline`): segment, identify and solve one image; returns a
  :class:`TrackResult` with the SPEC §4 pose (or ``converged = False`` and the reason), the
  segmented observation and its per-feature quality. :class:`TrackOptions` (:mod:`.options`)
  holds its settings.
- :mod:`.image` polarity, density, background (top-hat), noise; :mod:`.detection` expected
  sizes and what the image shows; :mod:`.beads` bead centres by a blurred-sphere model fit;
  :mod:`.ridges` Steger wire centre-line points; :mod:`.identify` labelling hypotheses (P3P
  over bead triplets) and contours gathered by prediction; :mod:`.labelling` one labelling
  refined into a pose; :mod:`.noise` the measured noise model, per-feature tests and the
  covariance; :mod:`.body` the body's projection subtracted; :mod:`.acceptance` the tests a
  pose must pass; :mod:`.region` where to look; :mod:`.overlay` the picture.

numpy/scipy/OpenCV only (OpenCV for fast morphology, filtering and P3P); never CadQuery.
"""

from .options import TrackOptions, TrackResult, ViewPrior
from .pipeline import track_image

__all__ = ["TrackOptions", "TrackResult", "ViewPrior", "track_image"]
