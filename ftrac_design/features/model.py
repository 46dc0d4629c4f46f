"""The fiducial as the pose solver, the analysis, the simulator and the tracker see it: seated
feature centre-lines and the body that carries them.

Plain numpy dataclasses, no CadQuery; the body is the design's own
:class:`~ftrac_design.design.Body`. All coordinates are in the fiducial frame F (SPEC §1),
millimetres.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from ..design.schema import Body


@dataclass(frozen=True)
class PointFeature:
    """A bead: its seated centre (mm, F), ball diameter (mm) and the line it sits on."""

    id: str
    center: np.ndarray
    diameter: float
    line: str | None = None


@dataclass(frozen=True)
class LineFeature:
    """A straight wire: the segment between its seated end-points (mm, F)."""

    id: str
    start: np.ndarray
    end: np.ndarray
    wire_diameter: float

    @property
    def direction(self) -> np.ndarray:
        """Unit vector from start to end (F)."""
        d = self.end - self.start
        return d / np.linalg.norm(d)

    @property
    def length(self) -> float:
        """Centre-line length between the end-points, mm."""
        return float(np.linalg.norm(self.end - self.start))

    def sample(self, t: np.ndarray) -> np.ndarray:
        """Points (n, 3) on the centre-line at fractions ``t`` (0 = start, 1 = end), mm in F."""
        t = np.asarray(t, float)[..., None]
        return self.start + t * (self.end - self.start)

    def parameter(self, p: np.ndarray) -> np.ndarray:
        """Fraction ``t`` of the orthogonal projection of point(s) ``p`` onto the line."""
        d = self.end - self.start
        return (np.asarray(p, float) - self.start) @ d / float(d @ d)


@dataclass(frozen=True)
class EllipseFeature:
    """An ellipse wire: ``center + a cos(s) major_axis + b sin(s) minor_axis`` (mm, F)."""

    id: str
    center: np.ndarray
    major_axis: np.ndarray
    minor_axis: np.ndarray
    semi_major: float
    semi_minor: float
    wire_diameter: float

    @property
    def normal(self) -> np.ndarray:
        """Unit normal of the ellipse's plane, ``major × minor`` (F)."""
        return np.cross(self.major_axis, self.minor_axis)

    def sample(self, s: np.ndarray) -> np.ndarray:
        """Points (n, 3) on the centre-line at parameters ``s`` (rad), mm in F."""
        s = np.asarray(s, float)[..., None]
        return (
            self.center + self.semi_major * np.cos(s) * self.major_axis + self.semi_minor * np.sin(s) * self.minor_axis
        )

    def tangent(self, s: np.ndarray) -> np.ndarray:
        """Unit tangents (n, 3) of the centre-line at parameters ``s`` (rad), direction of increasing s."""
        s = np.asarray(s, float)[..., None]
        t = -self.semi_major * np.sin(s) * self.major_axis + self.semi_minor * np.cos(s) * self.minor_axis
        return t / np.linalg.norm(t, axis=-1, keepdims=True)

    @property
    def circumference(self) -> float:
        """Centre-line length, mm (Ramanujan's second approximation, error < 1e-9 here)."""
        a, b = self.semi_major, self.semi_minor
        h = ((a - b) / (a + b)) ** 2
        return float(np.pi * (a + b) * (1 + 3 * h / (10 + np.sqrt(4 - 3 * h))))


@dataclass(frozen=True)
class Features:
    """Every radiographic feature of one fiducial, plus the frames it is mounted by.

    ``frames`` maps a name (``mount_from_fiducial``, ``template_from_fiducial``) to a 4×4
    homogeneous transform taking F coordinates (mm) into that frame. ``body`` is the hollow
    cylinder the features sit on (the design's, or the one ``features.json`` names), or None
    where it is not known: then the simulator renders wires and beads only and the tracker
    subtracts no body.
    """

    name: str
    source: str | None
    sha256: str | None
    nominal_beam_direction: np.ndarray
    points: tuple[PointFeature, ...] = ()
    lines: tuple[LineFeature, ...] = ()
    ellipses: tuple[EllipseFeature, ...] = ()
    frames: dict[str, np.ndarray] = field(default_factory=dict)
    body: Body | None = None

    @property
    def ids(self) -> list[str]:
        """All feature ids: points, then lines, then ellipses."""
        return [f.id for f in (*self.points, *self.lines, *self.ellipses)]

    def point_centers(self) -> np.ndarray:
        """Bead centres (n, 3), mm in F."""
        return np.array([p.center for p in self.points], float).reshape(-1, 3)

    @cached_property
    def characteristic_radius(self) -> float:
        """RMS distance of all feature geometry from the F origin, mm.

        A rotation of ``1 / characteristic_radius`` rad moves the features by about 1 mm;
        the solver and the analysis use it to put rotation and translation on one scale.
        """
        pts = [p.center for p in self.points]
        for ln in self.lines:
            pts += [ln.start, ln.end]
        for e in self.ellipses:
            pts += list(e.sample(np.linspace(0, 2 * np.pi, 12, endpoint=False)))
        if not pts:
            return 1.0
        return float(np.sqrt(np.mean(np.sum(np.asarray(pts) ** 2, axis=1))))

    def beads_on(self, line_id: str) -> tuple[PointFeature, ...]:
        """The beads threaded on line ``line_id``, ordered from its start to its end."""
        ln = self.line(line_id)
        on = [p for p in self.points if p.line == line_id]
        return tuple(sorted(on, key=lambda p: float(ln.parameter(p.center))))

    def line(self, line_id: str) -> LineFeature:
        """The line feature with id ``line_id`` (KeyError if there is none)."""
        for ln in self.lines:
            if ln.id == line_id:
                return ln
        raise KeyError(line_id)

    def wire_segments(self, line_id: str) -> list[tuple[np.ndarray, np.ndarray]]:
        """Pieces of straight wire on line ``line_id`` as (start, end) centre-line points, mm in F.

        A line's wire runs from its start to its end but is interrupted by every bead
        threaded on it: a piece ends where it butts against a ball, one ball radius from the
        bead centre along the line. Pieces of zero length (beads touching, or a bead at an
        end-point) are dropped.
        """
        ln = self.line(line_id)
        L = ln.length
        cuts = [
            (float(ln.parameter(p.center)) * L - p.diameter / 2, float(ln.parameter(p.center)) * L + p.diameter / 2)
            for p in self.beads_on(line_id)
        ]
        pieces, pos = [], 0.0
        for lo, hi in cuts:
            if lo > pos + 1e-9:
                pieces.append((pos, min(lo, L)))
            pos = max(pos, hi)
        if L > pos + 1e-9:
            pieces.append((pos, L))
        return [(ln.sample(a / L), ln.sample(b / L)) for a, b in pieces]

    @cached_property
    def wire_pieces(self) -> tuple[tuple[str, np.ndarray, np.ndarray], ...]:
        """Every line's straight wire pieces as (line id, start, end), mm in F, lines in order
        (:meth:`wire_segments`); a line its beads cover whole gives its centre line, so every
        line has a piece. Computed once per Features (the image path samples them per pose)."""
        return tuple((ln.id, a, b) for ln in self.lines for a, b in (self.wire_segments(ln.id) or [(ln.start, ln.end)]))

    def wire_length(self, feature_id: str) -> float:
        """Length of wire (mm) that feature ``feature_id`` takes: an ellipse's whole
        circumference, or the sum of a line's pieces between its beads."""
        for e in self.ellipses:
            if e.id == feature_id:
                return e.circumference
        return float(sum(np.linalg.norm(b - a) for a, b in self.wire_segments(feature_id)))

    def subset(self, keep: set[str] | list[str]) -> "Features":
        """A copy holding only the features whose id is in ``keep`` (frames and body kept)."""
        keep = set(keep)
        return Features(
            name=self.name,
            source=self.source,
            sha256=self.sha256,
            nominal_beam_direction=self.nominal_beam_direction,
            points=tuple(p for p in self.points if p.id in keep),
            lines=tuple(ln for ln in self.lines if ln.id in keep),
            ellipses=tuple(e for e in self.ellipses if e.id in keep),
            frames=dict(self.frames),
            body=self.body,
        )

    def scaled(self, factor: float) -> "Features":
        """A copy with every position, semi-axis, wire and bead diameter multiplied by
        ``factor`` about the F origin (the paper's Fig. 7e size study: same configuration,
        different size). Frames are dropped: the mount does not scale with it; the body is kept as
        it is (the size study scales the features alone)."""
        k = float(factor)
        if not k > 0:
            raise ValueError("scale factor must be positive")
        return Features(
            name=f"{self.name}_x{k:g}",
            source=self.source,
            sha256=self.sha256,
            nominal_beam_direction=self.nominal_beam_direction,
            points=tuple(PointFeature(p.id, p.center * k, p.diameter * k, p.line) for p in self.points),
            lines=tuple(LineFeature(ln.id, ln.start * k, ln.end * k, ln.wire_diameter * k) for ln in self.lines),
            ellipses=tuple(
                EllipseFeature(
                    e.id,
                    e.center * k,
                    e.major_axis,
                    e.minor_axis,
                    e.semi_major * k,
                    e.semi_minor * k,
                    e.wire_diameter * k,
                )
                for e in self.ellipses
            ),
            frames={},
            body=self.body,
        )
