"""4-axis machining of the body's grooves and pockets: toolpaths, posts, a G-code reader and
a material-removal simulator that checks a program against the cuts the CAD makes.

The room knows no CadQuery: it takes the cuts as plain numbers (:mod:`.model`), so ``cad``
hands its plan down and the tests of this room run without OCC.

- :mod:`.model` — the stock, the reference cuts (ellipse grooves, axial slots, pockets) with
  their exact ray intersections and signed distances; tools, cutting data and the machine.
- :mod:`.toolpath` — the program as moves: ramped entries, side passes, helical pockets.
- :mod:`.post` — RS-274 text for LinuxCNC (default) and a Fanuc-style control.
- :mod:`.gcode` — a reader of the emitted subset, and the cycle time of a program.
- :mod:`.simulate` — radial dexels on the unrolled cylinder: the tool swept through the stock,
  compared with the reference cuts (deviation, gouges, removed volume).
"""
