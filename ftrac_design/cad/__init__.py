"""CadQuery solids and their exports: the body, wires and beads, the mount and connector, the
press-fit coupon, STEP/STL/assembly files, the render and the views the drawings show.

The plans, sizes and rules the solids are made from are :mod:`ftrac_design.manufacture`.
Importing this package does not import CadQuery; the modules that build solids do.
"""
