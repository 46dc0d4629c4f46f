"""Workflows: the steps a command runs, as small testable functions, above every room they
combine (imports flow design → … → workflows → cli).

- :mod:`.track_run` — ``ftrac-design track``: the inputs validated whole before anything is
  tracked, then each frame of each image or run tracked on its own (a failure inside one
  frame never loses the batch), its SPEC §4 pose object with the intake's provenance.
"""
