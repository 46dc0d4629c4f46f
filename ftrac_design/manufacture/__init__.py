"""What it takes to make the fiducial, without CadQuery: manufacturing profiles and their cut
sizes, the design rules, the body's cut plan, the unrolled grooves, the shop drawings' sheets
and dimensions, the bill of materials, the FDM print files, the body's 4-axis program from the
plan, the press-fit coupon's plan and the build manifest's manufacturing entry.

:mod:`ftrac_design.cad` builds the solids from these plans and exports them; everything here
is plain numbers (numpy, matplotlib to draw), so ``check``, ``gcode`` and the design search
run without the ``cad`` extra.
"""
