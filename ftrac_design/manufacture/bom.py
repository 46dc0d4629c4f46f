"""Bill of materials for one build (plain numbers, no CadQuery): stock per machined part,
wire pieces per feature with cut allowance, beads, screws and dowel pins.

- **Stock** (profile ``cnc``): the body from acetal round rod — the smallest common metric
  rod diameter at least 2 mm over the finished diameter (1 mm turning allowance per side),
  the finished length + 2 mm for facing + :data:`CHUCK_ALLOWANCE` held in the 4-axis chuck;
  mount and connector from acetal block or plate, finished size + 2 mm in each direction
  (1 mm per face), rounded up to whole mm. Profile ``fdm``: printed, so the "stock" is the
  part's build envelope (its finished bounding box).
- **Wire**: every piece the assembly holds — a whole ellipse ring, or a line's pieces
  between its beads (:meth:`ftrac_design.features.model.Features.wire_segments`) — at its
  seated length, plus ``manufacturing.wire_cut_allowance`` per piece to cut from the coil
  and trim.
- **Screws** (ISO 4762 socket-head cap screws): the mount's z hole set holds it in the
  connector's tapped holes; the length is the longest standard length that does not come
  out of the plate's back (which lies on the template). For the rotary table, per hole set,
  the shortest standard length that engages 1.5 × d in a tapped table.
- **Dowel pins** (ISO 2338, m6): the connector's two pins into the template's grid holes.
"""

from __future__ import annotations

import math
from typing import Any

from ..design.schema import Design
from ..features.model import Features
from ..features.mounting import connector_layout, mount_layout
from .profiles import Profile

#: metric acetal rod diameters commonly stocked, mm
ROD_DIAMETERS = (
    6,
    8,
    10,
    12,
    14,
    15,
    16,
    18,
    20,
    22,
    25,
    28,
    30,
    32,
    35,
    40,
    45,
    50,
    55,
    60,
    65,
    70,
    75,
    80,
    90,
    100,
    110,
    120,
    130,
    140,
    150,
)
#: length held in the 4-axis chuck (not machined), mm
CHUCK_ALLOWANCE = 15.0
#: ISO 4762 preferred nominal lengths, mm
ISO4762_LENGTHS = (5, 6, 8, 10, 12, 16, 20, 25, 30, 35, 40, 45, 50, 55, 60, 65, 70, 80, 90, 100, 110, 120)


def _thread_d(screw: str) -> float:
    try:
        return float(screw.upper().lstrip("M"))
    except ValueError:
        return 4.0


def _longest(limit: float) -> int | None:
    ok = [n for n in ISO4762_LENGTHS if n <= limit + 1e-9]
    return ok[-1] if ok else None


def _shortest(minimum: float) -> int | None:
    ok = [n for n in ISO4762_LENGTHS if n >= minimum - 1e-9]
    return ok[0] if ok else None


def _block(size: list[float], profile: Profile) -> list[float]:
    if profile == "fdm":
        return [round(float(s), 3) for s in size]
    return [float(math.ceil(s + 2.0 - 1e-9)) for s in size]


def bill_of_materials(design: Design, features: Features, profile: Profile = "cnc") -> dict[str, Any]:
    """The bill of materials as plain JSON (lengths mm).

    Parameters
    ----------
    design, features : Design, Features
        The design and its features.
    profile : {"cnc", "fdm"}
        Machined from stock, or printed.

    Returns
    -------
    dict
        ``profile``, ``stock`` (body, mount, connector), ``wires`` (the pieces to cut; None
        without a wire), ``beads`` (None without beads), ``screws`` and ``dowel_pins``.
    """
    mount = mount_layout(design)
    con = connector_layout(design, mount)
    beads = None
    if features.points:
        beads = {
            "count": len(features.points),
            "diameter": design.bead.diameter if design.bead else None,
            "material": design.bead.material if design.bead else None,
        }
    c = design.connector
    pins = [
        {
            "item": f"ISO 2338 {c.pin_diameter:g} m6 x {c.pin_length:g}",
            "qty": len(con.pins),
            "use": "connector to the template's grid holes",
            "grid_nodes": [list(p.node) for p in con.pins],
            "engagement": c.pin_engagement,
        }
    ]
    return {
        "profile": profile,
        "stock": _stock(design, mount, con, profile),
        "wires": _wires(design, features),
        "beads": beads,
        "screws": _screws(design, mount),
        "dowel_pins": pins,
    }


def _stock(design: Design, mount, con, profile: Profile) -> list[dict[str, Any]]:
    """The material each part is made from: rod and blocks to machine, or printed parts."""
    m, c = design.mount, design.connector
    od, L = design.body.outer_diameter, design.body.length
    if profile == "cnc":
        rod = next((d for d in ROD_DIAMETERS if d >= od + 2.0 - 1e-9), math.ceil(od + 2.0))
        body_stock = {"form": "round rod", "diameter": float(rod), "length": L + 2.0 + CHUCK_ALLOWANCE}
    else:
        body_stock = {"form": "printed", "diameter": od, "length": L}
    return [
        {"part": "body", "material": design.body.material, "finished": {"diameter": od, "length": L}, **body_stock},
        {
            "part": "mount",
            "material": m.material,
            "finished": [mount.width, mount.width, mount.height],
            "form": "block" if profile == "cnc" else "printed",
            "size": _block([mount.width, mount.width, mount.height], profile),
        },
        {
            "part": "connector",
            "material": c.material,
            "finished": [float(v) for v in con.size],
            "form": "plate" if profile == "cnc" else "printed",
            "size": _block([float(v) for v in con.size], profile),
        },
    ]


def _wires(design: Design, features: Features) -> dict[str, Any] | None:
    """The wire pieces to cut (each ellipse a ring, each line's segments straight), with allowance."""
    allowance = design.manufacturing.wire_cut_allowance
    lengths = [(e.id, f"wire_{e.id}", "ring", e.circumference) for e in features.ellipses]
    for ln in features.lines:
        for k, (a, b) in enumerate(features.wire_segments(ln.id), start=1):
            lengths.append((ln.id, f"wire_{ln.id}_{k}", "straight", float(math.dist(a, b))))
    pieces = [
        {
            "feature": feature,
            "piece": piece,
            "shape": shape,
            "length": round(length, 3),
            "cut_length": round(length + allowance, 1),
        }
        for feature, piece, shape, length in lengths
    ]
    if design.wire is None or not pieces:
        return None
    return {
        "diameter": design.wire.diameter,
        "material": design.wire.material,
        "cut_allowance": allowance,
        "pieces": pieces,
        "total_cut_length": round(sum(p["cut_length"] for p in pieces), 1),
    }


def _screws(design: Design, mount) -> list[dict[str, Any]]:
    """The cap screws: the mount onto the connector, and (optional) onto a rotary table per hole set."""
    m, c = design.mount, design.connector
    screws = []
    zs = mount.set("z")
    if zs:
        hz = m.holes_z
        d = _thread_d(hz.screw)
        clamp = mount.height - (hz.counterbore_depth if hz.counterbore_diameter else 0.0)
        n = _longest(clamp + c.thickness - c.pocket_depth - 0.5)
        screws.append(
            {
                "item": f"ISO 4762 {hz.screw} x {n}" if n else f"ISO 4762 {hz.screw} (no standard length fits)",
                "qty": len(zs),
                "use": "mount to connector (mount's z hole set into the tapped plate)",
                "thread_engagement": round(n - clamp, 2) if n else None,
                "recommended_engagement": 1.5 * d,
            }
        )
    for axis, hs in (("x", m.holes_x), ("y", m.holes_y), ("z", m.holes_z)):
        holes = mount.set(axis)
        if not holes:
            continue
        d = _thread_d(hs.screw)
        clamp = holes[0].length - (hs.counterbore_depth if hs.counterbore_diameter else 0.0)
        n = _shortest(clamp + 1.5 * d)
        screws.append(
            {
                "item": f"ISO 4762 {hs.screw} x {n}" if n else f"ISO 4762 {hs.screw}",
                "qty": len(holes),
                "use": f"mount to a rotary table tapped {hs.screw} on a "
                f"{mount.pitches[axis]:g} mm pattern ({axis} hole set; optional)",
                "thread_engagement": round(n - clamp, 2) if n else None,
            }
        )
    return screws
