"""Workflows: the steps a command runs, as small testable functions, above every room they
combine (imports flow design → … → workflows → cli).

- :mod:`.track_run` — ``ftrac-design track``: the inputs validated whole before anything is
  tracked, then each frame of each image or run tracked on its own (a failure inside one
  frame never loses the batch), its SPEC §4 pose object with the intake's provenance.
- :mod:`.analyze` — ``ftrac-design analyze`` / ``compare``: the score, the atlases and their
  pictures written as ``analysis.json`` and PNGs; the text summary.
- :mod:`.optimize`, :mod:`.optimize_outputs` — ``ftrac-design optimize``: a whole search (log,
  resume, executor) and what it writes (winner verified, best design TOML, front, plots, build).
- :mod:`.report` — ``ftrac-design report`` / ``build --report`` / ``analyze --report``: the HTML
  page, with the design's analysis run first when a build has none.
"""
