"""``make demo`` / ``python -m ftrac_design.demo``: the whole chain on the presets, one module
per step, run in order by :mod:`.run`.

- :mod:`.build` — the paper's fiducial built (STEP, STL, drawings, G-code, manifest);
- :mod:`.score` — scored over its workspace (the image-true score and the paper's model);
- :mod:`.solve` — one synthetic image solved with no initial guess;
- :mod:`.segmentability` — the presets' image clearances;
- :mod:`.radiograph`, :mod:`.track` — a radiograph rendered and tracked from the image;
- :mod:`.intensity` — the pose refined on the pixels, against the pixel-level bound;
- :mod:`.carm` — a C-arm's DICOM run and an intensifier's distorted frame, through the command line;
- :mod:`.reconstruct` — points triangulated from two views;
- :mod:`.optimize` — a tiny design search and its rendered-image check;
- :mod:`.report` — the one-page HTML report of the build.

Each step writes its files and returns the text the demo prints; :mod:`.shell` runs the
command line as a user types it. A step that needs an optional extra which is not installed
is skipped with one line naming the extra (:func:`.run.run_steps`). The demo sits above every
room, the command line included, so no room carries demo code.
"""
