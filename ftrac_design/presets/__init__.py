"""The preset design files (``*.toml``) and search spaces (``spaces/*.toml``), shipped as
package data. They are data only: :mod:`ftrac_design.design.presets` finds and lists them.
"""
