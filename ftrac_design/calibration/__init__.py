"""The bead-grid calibration of an image intensifier's distortion: a dewarping plate's image
in, a :class:`~ftrac_design.images.distortion.DistortionModel` out.

- :mod:`.gridcal` — the beads found, indexed on their lattice and fitted with the plate's
  homography and the distortion polynomial (:func:`~.gridcal.estimate_distortion`);
- :mod:`.gridplate` — a simulated plate and its image through a known distortion (for the
  tests, the benchmarks and the demo);
- :mod:`.gridplot` — the fit's picture (``ftrac-design distortion --plot``).

The distortion model itself, which intake applies to every frame, lives with the image intake
in :mod:`ftrac_design.images`. The calibration finds its beads with the tracker's bead fitting
(:mod:`ftrac_design.segment.beads`) and renders its test plate with the simulator
(:mod:`ftrac_design.xray`), so it sits above both, which intake does not.
"""
