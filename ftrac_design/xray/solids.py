"""Exact chords, along the beam, of the simple solids a patient is built from (:mod:`.patient`).

Every solid lives in the *patient plane*: x, y (mm) across the beam, z (depth) along it; rays
are taken parallel to z (the few-degree divergence of the beam across one organ is
neglected, and one magnification maps the plane onto the detector). Each solid is a thin
cortical *wall* around a *core* and returns both chords (mm) at points (x, y):

- :class:`Ellipsoid` — semi-axes (a, b) in the plane, c in depth, rotated by ``angle``; the
  core is the ellipsoid (a − w, b − w, c − w). Chord ``2c √(1 − (x/a)² − (y/b)²)``. Optional
  cuts by planes containing the beam (``clips``) keep one side of each (hemispherical
  acetabulum, the iliac wing's fan, the sacrum's wedge).
- :class:`Tube` — the solid swept by an ellipse (half-width h in the plane, half-depth c)
  along a straight segment or a circular arc, with ellipsoidal end caps: chord
  ``2c √(1 − (d/h)²)`` with d the distance to the centre-line (ribs, rami, the femoral
  neck and shaft, processes, colon gas). Exact for that solid: a ray meets one cross-section.
- :class:`Column` — an elliptic cylinder whose axis lies in the plane (a vertebral body): chord
  ``2c √(1 − (x/a)²)`` between flat end plates, the plates (thickness ``plate``) solid wall.
- :class:`Canal` — an elliptic cylinder along the beam, length L (a pedicle seen end-on, a
  sacral foramen): chord L inside, a ring of wall around a core.

Flat faces (the column's plates, the canal's sides, a clip plane) are pixel-integrated (box
filter over the pixel from the signed distance), so their edges do not stair-step; curved
faces are sampled at the pixel centre, where the chord's square-root edge is exact.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

Extent = tuple[float, float, float, float]  # x_min, x_max, y_min, y_max (mm)


def _local(x: np.ndarray, y: np.ndarray, center: tuple[float, float], angle: float):
    ca, sa = math.cos(angle), math.sin(angle)
    dx, dy = x - center[0], y - center[1]
    return dx * ca + dy * sa, -dx * sa + dy * ca


def coverage(signed_distance: np.ndarray, px: float) -> np.ndarray:
    """Fraction of a pixel of side ``px`` (mm) inside a straight face at ``signed_distance``
    (mm, negative inside) from its centre: the box filter's exact value for an edge along a pixel axis."""
    return np.clip(0.5 - signed_distance / px, 0.0, 1.0)


def ellipse_chord(u: np.ndarray, v: np.ndarray, a: float, b: float, c: float) -> np.ndarray:
    """Chord ``2c √(1 − (u/a)² − (v/b)²)`` (mm) of an ellipsoid (a, b in the plane, c in depth); 0 outside."""
    if a <= 0 or b <= 0 or c <= 0:
        return np.zeros(np.broadcast_shapes(np.shape(u), np.shape(v)), np.float32)
    q = (u / a) ** 2 + (v / b) ** 2
    return (2.0 * c) * np.sqrt(np.maximum(1.0 - q, 0.0))


def _ellipse_extent(center, a: float, b: float, angle: float, pad: float = 0.0) -> Extent:
    ca, sa = math.cos(angle), math.sin(angle)
    ex = math.sqrt((a * ca) ** 2 + (b * sa) ** 2) + pad
    ey = math.sqrt((a * sa) ** 2 + (b * ca) ** 2) + pad
    return center[0] - ex, center[0] + ex, center[1] - ey, center[1] + ey


@dataclass(frozen=True)
class Ellipsoid:
    """A hollow ellipsoid (mm): ``axes`` (a, b) in the plane turned by ``angle`` (rad), ``depth``
    semi-axis c, cortical ``wall``; each of ``clips`` (nx, ny, d) keeps the points with
    nx·x' + ny·y' ≤ d in its own axes (x', y' from the centre; a plane containing the beam)."""

    center: tuple[float, float]
    axes: tuple[float, float]
    depth: float
    angle: float = 0.0
    wall: float = 0.0
    clips: tuple[tuple[float, float, float], ...] = ()

    def extent(self) -> Extent:
        """Bounding box in the plane (mm)."""
        return _ellipse_extent(self.center, *self.axes, self.angle)

    def chords(self, x: np.ndarray, y: np.ndarray, px: float) -> tuple[np.ndarray, np.ndarray]:
        """(wall, core) chords (mm) at (x, y) (mm); ``px`` the pixel size (mm) for the clip's edge."""
        u, v = _local(x, y, self.center, self.angle)
        (a, b), c, w = self.axes, self.depth, self.wall
        outer = ellipse_chord(u, v, a, b, c)
        core = ellipse_chord(u, v, a - w, b - w, c - w) if w > 0 else outer
        wall = outer - core
        for nx, ny, d in self.clips:
            cov = coverage((nx * u + ny * v - d) / math.hypot(nx, ny), px)
            wall, core = wall * cov, core * cov
        return wall, core


@dataclass(frozen=True)
class Tube:
    """A hollow tube (mm) of half-width ``half_width`` (in the plane) and half-depth ``depth``
    with cortical ``wall``, along a segment ``start``→``end`` or, when ``radius`` is set, along
    the arc of that radius about ``start`` from angle ``angles[0]`` to ``angles[1]`` (rad,
    counter-clockwise from +x toward +y); rounded (ellipsoidal) ends."""

    start: tuple[float, float]
    end: tuple[float, float] = (0.0, 0.0)
    half_width: float = 5.0
    depth: float = 5.0
    wall: float = 0.0
    radius: float | None = None
    angles: tuple[float, float] = (0.0, 0.0)

    def centerline(self) -> tuple[np.ndarray, float]:
        """Points (n, 2) (mm) of a polyline along the centre-line and the most it departs from it (mm)."""
        if self.radius is None:
            return np.array([self.start, self.end], float), 0.0
        th = np.linspace(self.angles[0], self.angles[1], 33)
        sag = self.radius * (1 - math.cos(abs(self.angles[1] - self.angles[0]) / 64))
        return np.c_[self.start[0] + self.radius * np.cos(th), self.start[1] + self.radius * np.sin(th)], sag

    def extent(self) -> Extent:
        """Bounding box in the plane (mm); an arc's is padded by its largest sagitta between samples."""
        p, sag = self.centerline()
        pad = self.half_width + sag
        return p[:, 0].min() - pad, p[:, 0].max() + pad, p[:, 1].min() - pad, p[:, 1].max() + pad

    def distance(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Distance (mm) of (x, y) from the centre-line."""
        if self.radius is None:
            (x0, y0), (x1, y1) = self.start, self.end
            dx, dy = x1 - x0, y1 - y0
            ll = dx * dx + dy * dy
            s = np.clip(((x - x0) * dx + (y - y0) * dy) / ll, 0.0, 1.0) if ll > 0 else 0.0
            return np.hypot(x - x0 - s * dx, y - y0 - s * dy)
        cx, cy = self.start
        t0, t1 = self.angles
        px, py = x - cx, y - cy
        rho = np.hypot(px, py)
        inside = np.mod(np.arctan2(py, px) - t0, 2 * np.pi) <= np.mod(t1 - t0, 2 * np.pi)
        e0 = np.hypot(px - self.radius * math.cos(t0), py - self.radius * math.sin(t0))
        e1 = np.hypot(px - self.radius * math.cos(t1), py - self.radius * math.sin(t1))
        return np.where(inside, np.abs(rho - self.radius), np.minimum(e0, e1))

    def chords(self, x: np.ndarray, y: np.ndarray, px: float) -> tuple[np.ndarray, np.ndarray]:
        """(wall, core) chords (mm) at (x, y) (mm)."""
        d = self.distance(x, y)
        h, c, w = self.half_width, self.depth, self.wall
        outer = ellipse_chord(d, 0.0, h, h, c)
        core = ellipse_chord(d, 0.0, h - w, h - w, c - w) if w > 0 else outer
        return outer - core, core


@dataclass(frozen=True)
class Column:
    """An elliptic cylinder lying in the plane (mm): axis along ``angle`` + 90° (the body's
    long axis), ``half_width`` a across it, ``depth`` c, ``half_height`` along it; a side
    ``wall`` and solid end ``plate`` s of cortical bone."""

    center: tuple[float, float]
    half_width: float
    depth: float
    half_height: float
    angle: float = 0.0
    wall: float = 0.0
    plate: float = 0.0
    plate_fill: float = 1.0

    def extent(self) -> Extent:
        """Bounding box in the plane (mm)."""
        return _ellipse_extent(
            self.center,
            self.half_width * 1.0001,
            self.half_height * 1.0001,
            self.angle,
            pad=0.5 * min(self.half_width, self.half_height),
        )

    def chords(self, x: np.ndarray, y: np.ndarray, px: float) -> tuple[np.ndarray, np.ndarray]:
        """(wall, core) chords (mm) at (x, y) (mm)."""
        u, v = _local(x, y, self.center, self.angle)
        a, c, w = self.half_width, self.depth, self.wall
        av = np.abs(v)
        in_body = coverage(av - self.half_height, px)
        in_core = coverage(av - (self.half_height - self.plate), px)
        core = ellipse_chord(u, 0.0, a - w, a - w, c - w) * (in_core + (in_body - in_core) * (1.0 - self.plate_fill))
        return ellipse_chord(u, 0.0, a, a, c) * in_body - core, core


@dataclass(frozen=True)
class Canal:
    """An elliptic cylinder along the beam (mm): cross-section ``axes`` (a, b) turned by
    ``angle``, ``length`` along z, a ``wall`` ring around the core."""

    center: tuple[float, float]
    axes: tuple[float, float]
    length: float
    angle: float = 0.0
    wall: float = 0.0

    def extent(self) -> Extent:
        """Bounding box in the plane (mm)."""
        return _ellipse_extent(self.center, *self.axes, self.angle, pad=1.0)

    @staticmethod
    def _inside(u, v, a, b, px):
        if a <= 0 or b <= 0:
            return np.zeros(np.broadcast_shapes(np.shape(u), np.shape(v)), np.float32)
        q = (u / a) ** 2 + (v / b) ** 2
        grad = 2.0 * np.sqrt((u / (a * a)) ** 2 + (v / (b * b)) ** 2)
        # first-order signed distance to the ellipse (exact on it), box-filtered over the pixel
        return coverage((q - 1.0) / np.maximum(grad, 1e-9), px)

    def chords(self, x: np.ndarray, y: np.ndarray, px: float) -> tuple[np.ndarray, np.ndarray]:
        """(wall, core) chords (mm) at (x, y) (mm)."""
        u, v = _local(x, y, self.center, self.angle)
        (a, b), w = self.axes, self.wall
        outer = self._inside(u, v, a, b, px)
        core = self._inside(u, v, a - w, b - w, px) if w > 0 else outer
        return self.length * (outer - core), self.length * core


def capsule_chord(x: np.ndarray, y: np.ndarray, p0: np.ndarray, p1: np.ndarray, radius: float) -> np.ndarray:
    """Chord (mm) along z of rays at (x, y) (mm, any shape) through the capsule of ``radius``
    about the 3-D segment p0→p1 (mm): the union of the ray's intervals in the cylinder (cut by
    the end planes) and in the two end spheres — one interval, the capsule being convex."""
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    axis = p1 - p0
    L = float(np.linalg.norm(axis))
    lo = np.full(np.shape(x), np.inf)
    hi = np.full(np.shape(x), -np.inf)

    def add(a, b):
        ok = b > a
        np.minimum(lo, np.where(ok, a, np.inf), out=lo)
        np.maximum(hi, np.where(ok, b, -np.inf), out=hi)

    for c in (p0, p1):
        h2 = radius * radius - (x - c[0]) ** 2 - (y - c[1]) ** 2
        h = np.sqrt(np.maximum(h2, 0.0))
        add(np.where(h2 > 0, c[2] - h, 0.0), np.where(h2 > 0, c[2] + h, 0.0))
    if L > 0:
        e = axis / L
        wx, wy = x - p0[0], y - p0[1]  # ray point at z = p0_z, relative to p0
        we = wx * e[0] + wy * e[1]
        Ax, Ay, Az = wx - we * e[0], wy - we * e[1], -we * e[2]  # part of w across the axis
        Bx, By, Bz = -e[2] * e[0], -e[2] * e[1], 1.0 - e[2] * e[2]  # part of the ray direction (0,0,1) across it
        bb = Bx * Bx + By * By + Bz * Bz
        if bb > 1e-12:
            ab = Ax * Bx + Ay * By + Az * Bz
            disc = ab * ab - bb * (Ax * Ax + Ay * Ay + Az * Az - radius * radius)
            sq = np.sqrt(np.maximum(disc, 0.0))
            s_lo, s_hi = (-ab - sq) / bb, (-ab + sq) / bb
            if abs(e[2]) > 1e-12:
                t_a, t_b = -we / e[2], (L - we) / e[2]  # the end planes along the ray
                s_lo, s_hi = np.maximum(s_lo, np.minimum(t_a, t_b)), np.minimum(s_hi, np.maximum(t_a, t_b))
            else:
                inside = (we >= 0) & (we <= L)
                s_hi = np.where(inside, s_hi, -np.inf)
            s_hi = np.where(disc > 0, s_hi, -np.inf)
            add(p0[2] + s_lo, p0[2] + s_hi)
        else:  # axis along the beam: the cylinder is the disc's prism
            inside = Ax * Ax + Ay * Ay < radius * radius
            add(np.where(inside, min(p0[2], p1[2]), 0.0), np.where(inside, max(p0[2], p1[2]), 0.0))
    return np.where(hi > lo, hi - lo, 0.0)


def capsule_volume(length: float, radius: float) -> float:
    """Volume (mm³) of a capsule of overall ``length`` (end to end) and ``radius`` (mm)."""
    return math.pi * radius * radius * (length - 2 * radius) + 4.0 / 3.0 * math.pi * radius**3
