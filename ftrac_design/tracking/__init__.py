"""Runs of frames tracked from frame to frame: a cine or a live feed, each frame from the previous
frames' poses, the full identification where that is not confirmed.

- :class:`RunTracker` (:mod:`.run_tracker`): one run, frames in order — predict, track near the
  prediction, re-identify where that is refused; a :class:`FrameAnswer` per frame (the result,
  its status ``tracked`` / ``re-identified`` / ``lost``, the time it took).
- :func:`track_near` (:mod:`.near`): one frame measured only where the predicted pose puts the
  fiducial and solved from it, given out only when the image path's tests pass;
  :class:`RunContext`, what a run's frames share (polarity, formation, blur, noise levels).

Above :mod:`ftrac_design.segment` (the image path, no prior), below the workflows that track
files and serve a live stream; numpy/scipy/OpenCV only, never CadQuery.
"""

from .near import RunContext, run_context, track_near
from .run_tracker import FrameAnswer, RunOptions, RunTracker

__all__ = ["FrameAnswer", "RunContext", "RunOptions", "RunTracker", "run_context", "track_near"]
