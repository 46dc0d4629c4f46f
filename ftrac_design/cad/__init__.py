"""CadQuery parts, exports and manufacturing profiles.

Importing this package does not import CadQuery; the modules that build solids do.
"""
