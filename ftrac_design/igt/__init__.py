"""Image-guided-therapy conventions and files: how a pose reaches 3D Slicer, ITK and PLUS.

- :mod:`.frames` — the frames' names (PLUS ``<From>To<To>``, ≤ 20 characters), LPS ↔ RAS,
  4×4 matrices from SPEC §4 poses (read by :func:`ftrac_design.pose.read_tracked_poses`).
- :mod:`.tfm` — ITK text transform files (``.tfm``): ``AffineTransform_double_3_3`` in LPS, in
  ITK's resampling direction (the file holds the inverse of the point mapping).
- :mod:`.markups` — 3D Slicer markups (``.mrk.json``, LPS).
- :mod:`.sequence` — PLUS-style sequence files (``.seq.mha``) holding a tracked run's
  transforms, statuses and timestamps.
- :mod:`.scene` — a 3D Slicer scene (MRML) of a run: the model and beads under the moving
  transform, the sequence and its browser.
- :mod:`.link` — OpenIGTLink messages (pyigtl, the ``live`` extra): IMAGE in, TRANSFORM and
  STATUS out in the peer's header version, the metadata keys both sides use, the wire framing.

**The one convention.** The numbers in our files (fiducial frame F, C-arm frame X, SPEC §1)
are read by Slicer as **LPS** coordinates — as Slicer reads any file that does not say
otherwise (an STL of the fiducial, a ``.tfm``, a ``.mrk.json``). Slicer's scene is RAS, so a
matrix handed over without a coordinate-system label (an OpenIGTLink TRANSFORM, a sequence
file's ``…Transform`` field) is by default the RAS one, ``S·M·S`` with ``S = diag(-1, -1, 1, 1)``.
Nothing here imports a network library; only :mod:`.link` needs pyigtl.
"""
