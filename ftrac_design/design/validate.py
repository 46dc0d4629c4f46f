"""Geometric validity of a design: things that cannot be built or would collide.

Manufacturability margins (wall thickness vs tool, fits, clearances) are design *rules*,
reported by ``ftrac-design check``; this module only rejects designs whose features do not
fit in the body or physically run into each other.
"""

from __future__ import annotations

import math

import numpy as np

from .schema import KEY_GAP, Design

#: samples per revolution when searching ellipse–ellipse and ellipse–bead distances;
#: 1/7200 rev at r = 15 mm is 13 µm of arc, far below any clearance we test.
_SAMPLES = 7200


def ellipse_z(design: Design, index: int, phi: np.ndarray, radius: float | None = None) -> np.ndarray:
    """Axial height z (mm, F) of ellipse ``index``'s plane at azimuth ``phi`` (rad) on ``radius``."""
    e = design.ellipses[index]
    r = design.ellipse_seat_radius if radius is None else radius
    return e.z_center - r * math.tan(e.tilt_rad) * np.cos(phi - e.tilt_azimuth_rad)


def _ellipse_points(design: Design, index: int, n: int = _SAMPLES) -> np.ndarray:
    phi = np.linspace(0.0, 2.0 * math.pi, n, endpoint=False)
    r = design.ellipse_seat_radius
    return np.column_stack([r * np.cos(phi), r * np.sin(phi), ellipse_z(design, index, phi)])


def bead_centers(design: Design) -> list[tuple[str, str | None, np.ndarray]]:
    """Every bead as (key in the design file, line id or None, centre in F, mm)."""
    out = []
    for i, line in enumerate(design.lines):
        r = design.line_seat_radius
        for j, z in enumerate(line.beads_z):
            c = np.array([r * math.cos(line.azimuth_rad), r * math.sin(line.azimuth_rad), z])
            out.append((f"lines[{i}].beads_z[{j}]", line.id, c))
    r = design.free_bead_seat_radius
    for i, b in enumerate(design.beads):
        c = np.array([r * math.cos(b.azimuth_rad), r * math.sin(b.azimuth_rad), b.z])
        out.append((f"beads[{i}]", None, c))
    return out


def geometry_errors(design: Design) -> list[tuple[str, str]]:
    """All geometric problems as (key, what was expected); empty when the design is valid."""
    return _feature_errors(design) + mounting_errors(design)


def mounting_errors(design: Design) -> list[tuple[str, str]]:
    """Mount and connector parameters that cannot be built at all.

    Margins (hole-to-edge distances, holes running into each other, the mount covering a
    feature, the mount reaching the template) are design rules, not errors.
    """
    errs: list[tuple[str, str]] = []
    m, c = design.mount, design.connector
    od = design.body.outer_diameter
    if m.width is not None and m.width <= od:
        errs.append(("mount.width", f"a block wider than the socket (Ø{od} mm), got {m.width!r}"))
    if m.key_height > 0:
        if m.key_height + KEY_GAP > m.socket_depth:
            errs.append(
                (
                    "mount.key_height",
                    f"a key that stays inside the socket: key_height + {KEY_GAP} mm (the slot's end gap) "
                    f"at most socket_depth ({m.socket_depth} mm), got {m.key_height!r}",
                )
            )
        if m.key_width >= od:
            errs.append(("mount.key_width", f"a key narrower than the cylinder (Ø{od} mm), got {m.key_width!r}"))
    if not c.pin_engagement < c.pin_length:
        errs.append(("connector.pin_engagement", f"less than pin_length ({c.pin_length} mm), got {c.pin_engagement!r}"))
    elif c.pin_length - c.pin_engagement > c.thickness:
        errs.append(
            (
                "connector.pin_length",
                f"a pin that fits the plate: pin_length - pin_engagement at most thickness "
                f"({c.thickness} mm), got {c.pin_length!r}",
            )
        )
    if not c.pocket_depth < c.thickness:
        errs.append(("connector.pocket_depth", f"less than thickness ({c.thickness} mm), got {c.pocket_depth!r}"))
    if c.pins[0] == c.pins[1]:
        errs.append(("connector.pins", f"two different grid nodes, got {c.pins!r}"))
    for i, (col, row) in enumerate(c.pins):
        y = row * c.grid_pitch
        if y + c.pin_diameter / 2 > c.template_edge:
            errs.append(
                (
                    f"connector.pins[{i}]",
                    f"a grid node on the template: row {row} is at y = {y} mm, above its top edge "
                    f"(template_edge = {c.template_edge} mm)",
                )
            )
    return errs


def _feature_errors(design: Design) -> list[tuple[str, str]]:
    errs = _missing_tables(design)
    if errs:
        return errs
    rw = design.wire.diameter / 2.0 if design.wire else 0.0
    rbead = design.bead.diameter / 2.0 if design.bead else 0.0
    return (
        _duplicate_ids(design)
        + _seats_in_the_wall(design, rw, rbead)
        + _features_in_the_length(design, rw, rbead)
        + _wires_apart(design, rw)
        + _beads_apart(design, rw, rbead)
    )


def _missing_tables(design: Design) -> list[tuple[str, str]]:
    """The tables and depths that the design's features need."""
    errs: list[tuple[str, str]] = []
    if (design.ellipses or design.lines) and design.wire is None:
        errs.append(("wire", "a [wire] table is required when the design has ellipses or lines"))
    has_beads = any(l.beads_z for l in design.lines) or bool(design.beads)
    if has_beads and design.bead is None:
        errs.append(("bead", "a [bead] table is required when the design has beads"))
    if design.ellipses and design.seating.ellipse_wire_depth is None:
        errs.append(("seating.ellipse_wire_depth", "a depth (mm) when the design has ellipses"))
    if design.lines and design.seating.line_wire_depth is None:
        errs.append(("seating.line_wire_depth", "a depth (mm) when the design has lines"))
    if not (design.ellipses or design.lines or design.beads):
        errs.append(("ellipses", "a design needs at least one ellipse, line or bead"))
    return errs


def _duplicate_ids(design: Design) -> list[tuple[str, str]]:
    errs: list[tuple[str, str]] = []
    ids: dict[str, str] = {}
    named = [(f"ellipses[{i}].id", e.id) for i, e in enumerate(design.ellipses)]
    named += [(f"lines[{i}].id", l.id) for i, l in enumerate(design.lines)]
    named += [(f"beads[{i}].id", b.id) for i, b in enumerate(design.beads) if b.id]
    for key, ident in named:
        if ident in ids:
            errs.append((key, f'a unique id ("{ident}" is also used by {ids[ident]})'))
        ids.setdefault(ident, key)
    return errs


def _seats_in_the_wall(design: Design, rw: float, rbead: float) -> list[tuple[str, str]]:
    """Wires and beads seated in the wall, not reaching the bore."""
    errs: list[tuple[str, str]] = []
    rb = design.bore_radius
    if design.ellipses:
        d = design.seating.ellipse_wire_depth
        if design.ellipse_seat_radius - rw <= rb:
            errs.append(
                (
                    "seating.ellipse_wire_depth",
                    f"a depth that leaves the wire inside the wall (depth {d} mm reaches the bore)",
                )
            )
    if design.lines:
        d = design.seating.line_wire_depth
        reach = max(rw, rbead if any(l.beads_z for l in design.lines) else 0.0)
        if design.line_seat_radius - reach <= rb:
            errs.append(
                (
                    "seating.line_wire_depth",
                    f"a depth that leaves wire and beads inside the wall (depth {d} mm reaches the bore)",
                )
            )
    if design.beads and design.free_bead_seat_radius - rbead <= rb:
        errs.append(("seating.free_bead_depth", "a depth that leaves the beads inside the wall"))
    return errs


def _features_in_the_length(design: Design, rw: float, rbead: float) -> list[tuple[str, str]]:
    """Every feature inside the body's length, each line's beads on it and apart."""
    errs: list[tuple[str, str]] = []
    L2 = design.half_length
    for i, e in enumerate(design.ellipses):
        reach = design.ellipse_seat_radius * math.tan(e.tilt_rad) + rw / math.cos(e.tilt_rad)
        if abs(e.z_center) + reach > L2:
            errs.append(
                (
                    f"ellipses[{i}].z_center",
                    f"an ellipse inside the body: it spans z = {e.z_center - reach:.3f} … "
                    f"{e.z_center + reach:.3f} mm, the body ends at ±{L2} mm",
                )
            )
    for i, line in enumerate(design.lines):
        for key, z, reach in ((f"lines[{i}].z_start", line.z_start, rw), (f"lines[{i}].z_end", line.z_end, rw)):
            if abs(z) + reach > L2:
                errs.append((key, f"a value within ±{L2 - reach:.3f} mm (the body ends at ±{L2} mm)"))
        zs = sorted(line.beads_z)
        for j, z in enumerate(line.beads_z):
            if not (line.z_start - 1e-9 <= z <= line.z_end + 1e-9):
                errs.append(
                    (
                        f"lines[{i}].beads_z[{j}]",
                        f"a bead on its line: z = {z} mm is off the line's extent [{line.z_start}, {line.z_end}]",
                    )
                )
            elif abs(z) + rbead > L2:
                errs.append((f"lines[{i}].beads_z[{j}]", f"a bead inside the body's length (±{L2} mm)"))
        for a, b in zip(zs, zs[1:]):
            if b - a <= 2 * rbead:
                errs.append((f"lines[{i}].beads_z", f"beads at least one diameter apart (z = {a} and {b} overlap)"))
    for i, b in enumerate(design.beads):
        if abs(b.z) + rbead > L2:
            errs.append((f"beads[{i}].z", f"a bead inside the body's length (±{L2} mm)"))
    return errs


def _wires_apart(design: Design, rw: float) -> list[tuple[str, str]]:
    """Ellipse wires that neither cross nor touch, and line wires seated clear of them in depth."""
    errs: list[tuple[str, str]] = []
    phi = np.linspace(0.0, 2.0 * math.pi, _SAMPLES, endpoint=False)
    for i in range(len(design.ellipses)):
        for j in range(i + 1, len(design.ellipses)):
            gap = ellipse_z(design, j, phi) - ellipse_z(design, i, phi)
            if gap.min() < 0 < gap.max() or np.abs(gap).min() <= 2 * rw:
                errs.append(
                    (
                        f"ellipses[{j}].z_center",
                        f"ellipses that do not cross: {design.ellipses[i].id} and "
                        f"{design.ellipses[j].id} come within {np.abs(gap).min():.3f} mm axially "
                        f"(wire diameter {2 * rw} mm)",
                    )
                )
    # a line wire passes under an ellipse wire: the radial step must clear both wires
    if design.ellipses and design.lines:
        step = design.line_seat_radius - design.ellipse_seat_radius
        if abs(step) < 2 * rw:
            errs.append(
                (
                    "seating.line_wire_depth",
                    f"line and ellipse wires seated at least one wire diameter ({2 * rw} mm) apart "
                    f"in depth where they cross; they are {abs(step):.3f} mm apart",
                )
            )
    return errs


def _beads_apart(design: Design, rw: float, rbead: float) -> list[tuple[str, str]]:
    """Beads that touch neither an ellipse wire nor another bead."""
    errs: list[tuple[str, str]] = []
    beads = bead_centers(design)
    if design.ellipses and beads:
        for k in range(len(design.ellipses)):
            pts = _ellipse_points(design, k)
            for key, _, c in beads:
                dmin = float(np.min(np.linalg.norm(pts - c, axis=1)))
                if dmin <= rbead + rw:
                    errs.append(
                        (
                            key,
                            f"a bead clear of ellipse {design.ellipses[k].id}: "
                            f"its centre is {dmin:.3f} mm from the wire, needs > {rbead + rw:.3f}",
                        )
                    )
    for a in range(len(beads)):
        for b in range(a + 1, len(beads)):
            if np.linalg.norm(beads[a][2] - beads[b][2]) <= 2 * rbead:
                errs.append((beads[b][0], f"beads that do not overlap ({beads[a][0]} is too close)"))
    return errs
