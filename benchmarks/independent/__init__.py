"""An independent X-ray renderer for held-out test images of the built fiducial.

It shares no code with ``ftrac_design.xray``: the geometry is the CAD body's STL written by
``ftrac-design build`` plus steel wire and ball meshes made from ``features.json``, cast with
Embree (:mod:`.fiducial`, :mod:`.raycast`); the patient is a 3-D voxel pelvis projected in
perspective (:mod:`.phantom`, :mod:`.drr`); the beam is a polychromatic tungsten spectrum
with NIST attenuation tables (:mod:`.spectrum`, :mod:`.attenuation`); the detector adds
focal-spot and MTF blur on the photon field, scatter, compound-Poisson noise, offset and gain
(:mod:`.detector`). Import with ``benchmarks/`` on ``sys.path``::

    from independent import render_independent
    counts, truth = render_independent("ftrac_2005", R, t, camera, kvp=80, dose_behind_patient=1000,
                                       patient=True, seed=1)
"""

from .render import RenderSettings, patient_placement, render_independent

__all__ = ["RenderSettings", "patient_placement", "render_independent"]
