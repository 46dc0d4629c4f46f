"""The body's grooves and pockets unwrapped for a 4-axis (A-axis wrap) toolpath.

A 4-axis mill turns the cylinder about its axis (the A axis) under a radial end mill, so a
groove centre-line is programmed as a polyline in (A = θ, Z = z) at a fixed depth. This
module writes

- ``grooves.csv`` — one row per polyline vertex: ``feature, kind, vertex, theta_deg, z_mm,
  depth_mm, seat_radius_mm, part_diameter_mm, cut_width_mm``. ``θ`` is the azimuth about
  F's ``+z`` from ``+x`` toward ``+y`` (degrees), ``z`` the axial position in F (mm),
  ``depth`` the groove floor (or pocket floor) below the outer surface, ``seat_radius`` the
  radius of the wire's centre-line (wrap ``(θ, z)`` onto it to get the centre-line back),
  ``part_diameter`` the wire (or ball) diameter and ``cut_width`` the groove width (or
  pocket diameter) of the chosen profile. An ellipse is one closed polyline from θ = 0° to
  360° in steps of :data:`STEP_DEG`; a line is two vertices (start, end); a bead pocket is
  one ``pocket`` row (a radial plunge at (θ, z)).
- ``grooves.dxf`` — the unwrapped outer surface: a rectangle 2πR × L (x = R·θ, arc length in
  mm on the outer surface; y = z in F) with the groove centre-lines, the groove edges
  (± half the cut width), the pocket circles, the strip the mount's socket covers and the
  feature ids, each on its own layer.

Everything is computed from the seated features (:mod:`ftrac_design.features`), not from
the design's formulas: an ellipse is sampled by solving its parametrisation for the
parameter whose point lies at azimuth θ.

**Chord error.** The machine interpolates linearly in (θ, z) between vertices. For an
ellipse groove ``z(θ) = z_c − A cos(θ − α)`` the largest deviation of that interpolation
from the true centre-line is ``A (1 − cos(Δθ/2)) ≈ A Δθ²/8``: with Δθ = 0.5° and
A = 8.49 mm (ftrac_2005) it is 0.08 µm. :func:`chord_error` measures it per path.
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..features.model import EllipseFeature, Features
from ..fileio import write_text_atomic
from .profiles import CutSizes

#: angular step of the ellipse polylines, degrees
STEP_DEG = 0.5

CSV_COLUMNS = (
    "feature",
    "kind",
    "vertex",
    "theta_deg",
    "z_mm",
    "depth_mm",
    "seat_radius_mm",
    "part_diameter_mm",
    "cut_width_mm",
)

#: DXF layers
LAYERS = {"OUTLINE": 7, "GROOVE_CENTRELINES": 1, "GROOVE_EDGES": 8, "POCKETS": 5, "MOUNT": 3, "LABELS": 2}


@dataclass(frozen=True)
class UnwrappedPath:
    """One groove (or pocket) in cylinder coordinates."""

    feature: str
    kind: str  # "ellipse", "line" or "pocket"
    theta_deg: np.ndarray
    z: np.ndarray
    seat_radius: float
    depth: float
    part_diameter: float
    cut_width: float

    def wrap(self) -> np.ndarray:
        """The vertices wrapped back onto the seat cylinder (n, 3), mm in F."""
        return wrap(self.theta_deg, self.z, self.seat_radius)


def wrap(theta_deg: np.ndarray, z: np.ndarray, radius: float | np.ndarray) -> np.ndarray:
    """Points ``(r cos θ, r sin θ, z)`` (n, 3) for θ in degrees."""
    t = np.radians(np.asarray(theta_deg, float))
    r = np.broadcast_to(np.asarray(radius, float), t.shape)
    return np.column_stack([r * np.cos(t), r * np.sin(t), np.asarray(z, float)])


def ellipse_parameter_at(e: EllipseFeature, theta: np.ndarray) -> np.ndarray:
    """Parameters ``s`` of ellipse ``e`` whose points lie at azimuths ``theta`` (rad).

    For an ellipse centred on the body axis, ``xy(s) = a cos s·u_xy + b sin s·v_xy`` points
    along ``d = (cos θ, sin θ)`` when ``a (u_xy × d) cos s + b (v_xy × d) sin s = 0``; of
    the two roots the one with ``xy(s)·d > 0`` is taken.
    """
    if np.linalg.norm(e.center[:2]) > 1e-9:
        raise ValueError(f"ellipse {e.id} is not centred on the body axis")
    theta = np.asarray(theta, float)
    dx, dy = np.cos(theta), np.sin(theta)
    u, v = e.major_axis, e.minor_axis
    A = e.semi_major * (u[0] * dy - u[1] * dx)
    B = e.semi_minor * (v[0] * dy - v[1] * dx)
    s = np.arctan2(-A, B)
    xy_dot = e.semi_major * np.cos(s) * (u[0] * dx + u[1] * dy) + e.semi_minor * np.sin(s) * (v[0] * dx + v[1] * dy)
    return np.where(xy_dot < 0, s + math.pi, s)


def _azimuth_radius(x: np.ndarray) -> tuple[float, float]:
    """A point's azimuth about the body axis (degrees in [0, 360)) and its distance from it (mm)."""
    return math.degrees(math.atan2(x[1], x[0])) % 360.0, float(math.hypot(x[0], x[1]))


def unwrap_features(
    features: Features, outer_radius: float, cuts: CutSizes, step_deg: float = STEP_DEG
) -> list[UnwrappedPath]:
    """Every groove and pocket of ``features`` as (θ, z) polylines; ellipses, lines, pockets."""
    out: list[UnwrappedPath] = []
    n = int(round(360.0 / step_deg))
    theta_deg = np.linspace(0.0, 360.0, n + 1)
    for e in features.ellipses:
        s = ellipse_parameter_at(e, np.radians(theta_deg))
        pts = e.sample(s)
        r = np.hypot(pts[:, 0], pts[:, 1])
        if np.ptp(r) > 1e-9:
            raise ValueError(f"ellipse {e.id} does not lie on a cylinder about the body axis")
        rs = float(np.mean(r))
        out.append(
            UnwrappedPath(
                e.id,
                "ellipse",
                theta_deg.copy(),
                pts[:, 2].copy(),
                rs,
                outer_radius - rs + e.wire_diameter / 2,
                e.wire_diameter,
                cuts.groove_width,
            )
        )
    for ln in features.lines:
        if np.linalg.norm(ln.end[:2] - ln.start[:2]) > 1e-9:
            raise ValueError(f"line {ln.id} is not parallel to the body axis")
        th, rs = _azimuth_radius(ln.start)
        out.append(
            UnwrappedPath(
                ln.id,
                "line",
                np.array([th, th]),
                np.array([ln.start[2], ln.end[2]]),
                rs,
                outer_radius - rs + ln.wire_diameter / 2,
                ln.wire_diameter,
                cuts.groove_width,
            )
        )
    for p in features.points:
        th, rs = _azimuth_radius(p.center)
        out.append(
            UnwrappedPath(
                p.id,
                "pocket",
                np.array([th]),
                np.array([p.center[2]]),
                rs,
                outer_radius - rs + p.diameter / 2,
                p.diameter,
                cuts.pocket_diameter,
            )
        )
    return out


def chord_error(path: UnwrappedPath, features: Features) -> float:
    """Largest distance (mm) between the (θ, z)-linear toolpath and the true centre-line,
    measured at every segment's midpoint (where it is largest)."""
    if path.kind != "ellipse":
        return 0.0
    e = next(x for x in features.ellipses if x.id == path.feature)
    th_mid = np.radians((path.theta_deg[:-1] + path.theta_deg[1:]) / 2)
    z_mid = (path.z[:-1] + path.z[1:]) / 2
    true = e.sample(ellipse_parameter_at(e, th_mid))
    return float(np.max(np.abs(true[:, 2] - z_mid)))


def grooves_csv_text(paths: list[UnwrappedPath]) -> str:
    """The ``grooves.csv`` text of ``paths``: one row per sample of each groove or pocket."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(CSV_COLUMNS)
    for p in paths:
        for k, (th, z) in enumerate(zip(p.theta_deg, p.z)):
            w.writerow(
                [
                    p.feature,
                    p.kind,
                    k,
                    f"{th:.9f}",
                    f"{z:.9f}",
                    f"{p.depth:.9f}",
                    f"{p.seat_radius:.9f}",
                    f"{p.part_diameter:.6f}",
                    f"{p.cut_width:.6f}",
                ]
            )
    return buf.getvalue()


def write_grooves_csv(path: str | Path, paths: list[UnwrappedPath]) -> Path:
    """Write ``grooves.csv`` atomically."""
    return write_text_atomic(path, grooves_csv_text(paths))


def read_grooves_csv(path: str | Path) -> list[UnwrappedPath]:
    """Read ``grooves.csv`` back into paths (vertices in file order)."""
    rows: dict[tuple[str, str], list[dict[str, str]]] = {}
    with open(path, newline="", encoding="utf-8") as fh:
        for row in csv.DictReader(fh):
            rows.setdefault((row["feature"], row["kind"]), []).append(row)
    out = []
    for (feature, kind), rs in rows.items():
        rs.sort(key=lambda r: int(r["vertex"]))
        out.append(
            UnwrappedPath(
                feature,
                kind,
                np.array([float(r["theta_deg"]) for r in rs]),
                np.array([float(r["z_mm"]) for r in rs]),
                float(rs[0]["seat_radius_mm"]),
                float(rs[0]["depth_mm"]),
                float(rs[0]["part_diameter_mm"]),
                float(rs[0]["cut_width_mm"]),
            )
        )
    return out


def _offset(xy: np.ndarray, d: float) -> np.ndarray:
    """A polyline offset sideways by ``d`` (left of the direction of travel)."""
    t = np.gradient(xy, axis=0)
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    return xy + d * np.column_stack([-t[:, 1], t[:, 0]])


def unwrapped_dxf(
    paths: list[UnwrappedPath], outer_radius: float, half_length: float, socket_depth: float | None = None
):
    """An ezdxf document of the unwrapped outer surface (mm; x = R·θ, y = z)."""
    import ezdxf
    from ezdxf import units

    doc = ezdxf.new("R2010")
    doc.units = units.MM
    doc.header["$MEASUREMENT"] = 1
    for name, color in LAYERS.items():
        doc.layers.add(name, color=color)
    msp = doc.modelspace()
    R, L2 = outer_radius, half_length
    W = 2 * math.pi * R
    msp.add_lwpolyline([(0, -L2), (W, -L2), (W, L2), (0, L2)], close=True, dxfattribs={"layer": "OUTLINE"})
    if socket_depth:
        rim = -L2 + socket_depth
        msp.add_lwpolyline([(0, -L2), (W, -L2), (W, rim), (0, rim)], close=True, dxfattribs={"layer": "MOUNT"})
    text_h = max(0.5, min(2.0, R / 8))
    for p in paths:
        x = R * np.radians(p.theta_deg)
        if p.kind == "pocket":
            msp.add_circle((float(x[0]), float(p.z[0])), p.cut_width / 2, dxfattribs={"layer": "POCKETS"})
            msp.add_text(p.feature, height=text_h * 0.6, dxfattribs={"layer": "LABELS"}).set_placement(
                (float(x[0]) + p.cut_width, float(p.z[0]))
            )
            continue
        xy = np.column_stack([x, p.z])
        msp.add_lwpolyline([tuple(map(float, q)) for q in xy], dxfattribs={"layer": "GROOVE_CENTRELINES"})
        for side in (-1, 1):
            if p.kind == "line":
                edge = xy + np.array([side * p.cut_width / 2, 0.0])
            else:
                edge = _offset(xy, side * p.cut_width / 2)
            msp.add_lwpolyline([tuple(map(float, q)) for q in edge], dxfattribs={"layer": "GROOVE_EDGES"})
        k = int(np.argmax(p.z)) if p.kind == "ellipse" else len(xy) - 1
        msp.add_text(p.feature, height=text_h, dxfattribs={"layer": "LABELS"}).set_placement(
            (float(xy[k, 0]) + text_h / 2, float(xy[k, 1]) + text_h / 2)
        )
    return doc


def write_grooves_dxf(
    path: str | Path,
    paths: list[UnwrappedPath],
    outer_radius: float,
    half_length: float,
    socket_depth: float | None = None,
) -> Path:
    """Write ``grooves.dxf`` atomically."""
    doc = unwrapped_dxf(paths, outer_radius, half_length, socket_depth)
    buf = io.StringIO()
    doc.write(buf)
    return write_text_atomic(path, buf.getvalue())
