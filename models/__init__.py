"""The design files: the presets (``*.toml``) and their search spaces (``spaces/*.toml``).

This folder is where a new design starts (copy a preset, change it, ``ftrac-design check`` it).
The build ships it inside the package as ``ftrac_design.presets`` (``setup.py`` maps it in), so
an installed wheel has the presets as a checkout does; :mod:`ftrac_design.design.presets` finds
and lists them, and a preset's name works wherever a design file does.
"""
