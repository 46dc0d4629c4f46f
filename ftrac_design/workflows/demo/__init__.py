"""The steps of ``make demo`` beyond the build and the score, one module per capability.

Each module's ``demo_step(out_dir)`` runs one capability end to end on the presets (a
radiograph and its truth, the intensity refinement, the features' image clearances, a
reconstruction from two views, a tiny design search, the one-page report), writes its files
into ``out_dir`` and returns the lines :mod:`ftrac_design.demo` prints. They live here, above
the rooms they exercise, so no numerical room carries demo code.
"""
