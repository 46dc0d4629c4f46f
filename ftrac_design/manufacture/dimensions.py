"""Every dimension the shop drawings print, as numbers with tolerances (no plotting here).

A :class:`Dim` is one printed value: its key (unique on its sheet), value, unit, printed
precision, ± tolerance and whether it is fit-critical. The values come from the same
sources the CAD is built from — the seated features (:mod:`ftrac_design.features`), the body
plan (:mod:`ftrac_design.manufacture.plan`), the mount and connector layouts with the profile's cut
sizes (:class:`~ftrac_design.cad.mount.MountPart`, :class:`~ftrac_design.cad.connector.
ConnectorPart`) — so a drawing cannot say something the solid does not.

Body (frame F): azimuth **A** about +z from +x toward +y in degrees (the 4-axis mill's A
axis), axial **z** in mm from mid-length; groove and pocket **depth** radially from the
outer surface (Ø = datum A) to the floor, groove **width** across the wire (normal to it).
An ellipse groove is given by its highest and lowest points (A, z); it is planar, so those
and its width fix it. Mount in frame M, connector in frame T (``features.mounting``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from ..design.schema import Design
from ..features.model import EllipseFeature, Features
from .plan import BodyPlan
from .profiles import DrawingTolerances

Unit = Literal["mm", "deg"]
Kind = Literal["length", "diameter", "angle", "radius"]

#: printed decimals: lengths to 0.001 mm, angles to 0.01°
MM_DECIMALS = 3
DEG_DECIMALS = 2
#: the sign printed after a fit-critical value
CRITICAL_MARK = "◆"


@dataclass(frozen=True)
class Dim:
    """One printed dimension. ``tolerance`` is ± in ``unit`` (None: basic/reference)."""

    key: str
    value: float
    unit: Unit
    kind: Kind
    tolerance: float | None
    critical: bool = False
    label: str = ""

    @property
    def decimals(self) -> int:
        """Decimals printed, by the unit (degrees or mm)."""
        return DEG_DECIMALS if self.unit == "deg" else MM_DECIMALS

    def text(self) -> str:
        """The printed text, e.g. ``Ø0.480 ±0.050 ◆`` or ``295.00° ±0.19°``."""
        d = self.decimals
        deg = "°" if self.unit == "deg" else ""
        prefix = {"diameter": "Ø", "radius": "R"}.get(self.kind, "")
        value = 0.0 if abs(self.value) < 0.5 * 10**-d else self.value  # no "-0.000"
        s = f"{prefix}{value:.{d}f}{deg}"
        if self.tolerance is not None:
            s += f" ±{self.tolerance:.{d}f}{deg}"
        if self.critical:
            s += f" {CRITICAL_MARK}"
        return s


def azimuth_deg(p: np.ndarray) -> float:
    """Azimuth of ``p`` about +z from +x, degrees in [0, 360)."""
    a = math.degrees(math.atan2(float(p[1]), float(p[0]))) % 360.0
    return 0.0 if a >= 360.0 - 0.5 * 10**-DEG_DECIMALS else a


def ellipse_extremes(e: EllipseFeature) -> tuple[tuple[float, float], tuple[float, float]]:
    """((A_top°, z_top), (A_bottom°, z_bottom)) of a seated ellipse on its cylinder.

    On the cylinder of radius r the ellipse's plane ``n·(p − c) = 0`` gives
    ``z(θ) = c_z + r g·(cos θ, sin θ)`` with ``g = −(n_x, n_y)/n_z``: highest at the
    azimuth of ``g``, ``z_c + r|g|``, lowest opposite.
    """
    n, c, r = e.normal, e.center, e.semi_minor
    g = -np.array([n[0], n[1]]) / n[2]
    top = np.array([g[0], g[1], 0.0])
    a = r * float(np.linalg.norm(g))
    return (azimuth_deg(top), float(c[2]) + a), (azimuth_deg(-top), float(c[2]) - a)


def datum_c(design: Design, features: Features) -> tuple[str, float]:
    """(what datum C is, its azimuth °): the key slot when the mount has a key, else the
    first line groove's centre plane, else the first pocket's axis plane, else the +x axis
    (A = 0; a body with no feature to find its azimuth by)."""
    if design.mount.key_height > 0:
        return "key slot centre plane", design.mount.key_azimuth_deg % 360.0
    if features.lines:
        ln = features.lines[0]
        return f"groove {ln.id} centre plane", azimuth_deg(ln.start)
    if features.points:
        p = features.points[0]
        return f"pocket {p.id} axis plane", azimuth_deg(p.center)
    return "+x axis of F", 0.0


def body_dimensions(
    design: Design,
    features: Features,
    plan: BodyPlan,
    tol: DrawingTolerances,
    key_slot: tuple[float, float] | None = None,
) -> list[Dim]:
    """The body's dimensions: size, bore, datum C, and every groove and pocket.

    ``key_slot``: (width, depth) of the slot across the ``z = −L/2`` end, mm, when cut.
    """
    R = plan.outer_radius
    g, c, ang = tol.general, tol.critical, tol.angle_deg(R)
    out = [
        Dim("body.length", 2 * plan.half_length, "mm", "length", g, label="length (B to far end)"),
        Dim("body.outer_diameter", 2 * R, "mm", "diameter", c, True, "outer Ø (datum A; press fit in the mount)"),
    ]
    if plan.bore_radius > 0:
        out.append(Dim("body.bore_diameter", 2 * plan.bore_radius, "mm", "diameter", g, label="bore Ø"))
    what, a_c = datum_c(design, features)
    out.append(Dim("datum_C.A", a_c, "deg", "angle", None, label=f"datum C: {what}"))
    if key_slot is not None:
        out.append(Dim("key_slot.width", key_slot[0], "mm", "length", c, True, "key slot width (sliding fit)"))
        out.append(Dim("key_slot.depth", key_slot[1], "mm", "length", g, label="key slot depth from B"))
    for grv in plan.ellipse_grooves:
        e = grv.feature
        (a_t, z_t), (a_b, z_b) = ellipse_extremes(e)
        out += [
            Dim(f"{e.id}.top.A", a_t, "deg", "angle", ang, label=f"{e.id} highest point"),
            Dim(f"{e.id}.top.z", z_t, "mm", "length", c),
            Dim(f"{e.id}.bottom.A", a_b, "deg", "angle", ang, label=f"{e.id} lowest point"),
            Dim(f"{e.id}.bottom.z", z_b, "mm", "length", c),
            Dim(f"{e.id}.width", grv.width, "mm", "length", c, True, "groove width"),
            Dim(f"{e.id}.depth", R - grv.seat_radius + grv.floor_depth, "mm", "length", c, True, "groove depth"),
        ]
    for grv in plan.line_grooves:
        ln = grv.feature
        a = azimuth_deg(ln.start)
        out += [
            Dim(f"{ln.id}.A", a, "deg", "angle", ang, label=f"{ln.id} (parallel to the axis)"),
            Dim(f"{ln.id}.start.z", grv.z0, "mm", "length", c),
            Dim(f"{ln.id}.end.z", grv.z1, "mm", "length", c),
            Dim(f"{ln.id}.width", grv.width, "mm", "length", c, True, "groove width"),
            Dim(f"{ln.id}.depth", R - grv.floor_radius, "mm", "length", c, True, "groove depth"),
        ]
    for pk in plan.pockets:
        p = pk.feature
        floor_r = math.hypot(float(pk.floor[0]), float(pk.floor[1]))
        out += [
            Dim(f"{p.id}.A", azimuth_deg(p.center), "deg", "angle", ang, label=f"pocket {p.id}"),
            Dim(f"{p.id}.z", float(p.center[2]), "mm", "length", c),
            Dim(f"{p.id}.diameter", pk.diameter, "mm", "diameter", c, True, "pocket Ø"),
            Dim(f"{p.id}.depth", R - floor_r, "mm", "length", c, True, "pocket depth"),
        ]
    return out


def mount_dimensions(mount, tol: DrawingTolerances) -> list[Dim]:
    """The mount's dimensions (frame M) from a :class:`~ftrac_design.cad.mount.MountPart`."""
    m = mount.layout
    g, c = tol.general, tol.critical
    out = [
        Dim("block.width", m.width, "mm", "length", g, label="block side (x and y)"),
        Dim("block.height", m.height, "mm", "length", g, label="block height"),
        Dim("block.base", m.base_height, "mm", "length", c, True, "bottom face to socket floor (datum B)"),
        Dim("block.chamfer", m.chamfer, "mm", "length", g, label="chamfer 45° on vertical edges"),
        Dim("socket.diameter", mount.socket_diameter, "mm", "diameter", c, True, "socket Ø (press fit, datum A)"),
        Dim("socket.depth", m.socket_depth, "mm", "length", g, label="socket depth"),
    ]
    if m.key.height > 0:
        out += [
            Dim("key.width", m.key.width, "mm", "length", c, True, "key width (sliding fit, datum C)"),
            Dim("key.height", m.key.height, "mm", "length", g, label="key height"),
            Dim("key.A", azimuth_deg(m.key.direction), "deg", "angle", None, label="key direction"),
        ]
    for h in m.holes:
        u, v = [k for k in range(3) if k != h.axis]
        out += [
            Dim(f"{h.name}.{'xyz'[u]}", float(h.center[u]), "mm", "length", g, label=f"hole {h.name}"),
            Dim(f"{h.name}.{'xyz'[v]}", float(h.center[v]), "mm", "length", g),
            Dim(f"{h.name}.diameter", mount.hole_diameters[h.name], "mm", "diameter", g),
        ]
        if h.name in mount.counterbore_diameters:
            out += [
                Dim(f"{h.name}.cbore_diameter", mount.counterbore_diameters[h.name], "mm", "diameter", g),
                Dim(f"{h.name}.cbore_depth", h.counterbore_depth, "mm", "length", g),
            ]
    return out


def connector_dimensions(conn, tol: DrawingTolerances) -> list[Dim]:
    """The connector's dimensions (frame T) from a :class:`~ftrac_design.cad.connector.ConnectorPart`."""
    k = conn.layout
    g, c = tol.general, tol.critical
    sx, sy, t = (float(x) for x in k.size)
    out = [
        Dim("plate.x0", float(k.lo[0]), "mm", "length", g, label="plate corner from the reference hole"),
        Dim("plate.y0", float(k.lo[1]), "mm", "length", g),
        Dim("plate.width", sx, "mm", "length", g, label="plate width (x)"),
        Dim("plate.height", sy, "mm", "length", g, label="plate height (y)"),
        Dim("plate.thickness", t, "mm", "length", g, label="plate thickness"),
        Dim("pocket.x", float(k.pocket_center[0]), "mm", "length", c, label="pocket centre (fiducial axis)"),
        Dim("pocket.y", float(k.pocket_center[1]), "mm", "length", c),
        Dim("pocket.size", conn.pocket_size, "mm", "length", c, True, "pocket side (sliding fit)"),
        Dim("pocket.depth", k.pocket_depth, "mm", "length", c, True, "pocket depth (locates the mount in z)"),
        Dim("pocket.radius", k.pocket_corner_radius, "mm", "radius", g, label="pocket corner radius"),
    ]
    for h in k.holes:
        crit = h.kind == "pin"
        out += [
            Dim(f"{h.name}.x", float(h.center[0]), "mm", "length", c if crit else g, label=f"hole {h.name}"),
            Dim(f"{h.name}.y", float(h.center[1]), "mm", "length", c if crit else g),
            Dim(f"{h.name}.diameter", conn.hole_diameter(h.kind), "mm", "diameter", c if crit else g, crit),
        ]
    return out
