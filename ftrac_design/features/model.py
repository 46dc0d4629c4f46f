"""The fiducial as the pose solver and the analysis see it: seated feature centre-lines.

Plain numpy dataclasses with no dependency on the design schema or on CadQuery, so that
``pose`` and ``analysis`` can load ``features.json`` cheaply. All coordinates are in the
fiducial frame F (SPEC §1), millimetres.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


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
        return (self.center + self.semi_major * np.cos(s) * self.major_axis
                + self.semi_minor * np.sin(s) * self.minor_axis)

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
    homogeneous transform taking F coordinates (mm) into that frame.
    """

    name: str
    source: str | None
    sha256: str | None
    nominal_beam_direction: np.ndarray
    points: tuple[PointFeature, ...] = ()
    lines: tuple[LineFeature, ...] = ()
    ellipses: tuple[EllipseFeature, ...] = ()
    frames: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def ids(self) -> list[str]:
        """All feature ids: points, then lines, then ellipses."""
        return [f.id for f in (*self.points, *self.lines, *self.ellipses)]

    def point_centers(self) -> np.ndarray:
        """Bead centres (n, 3), mm in F."""
        return np.array([p.center for p in self.points], float).reshape(-1, 3)

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

    def subset(self, keep: set[str] | list[str]) -> "Features":
        """A copy holding only the features whose id is in ``keep`` (frames kept)."""
        keep = set(keep)
        return Features(
            name=self.name, source=self.source, sha256=self.sha256,
            nominal_beam_direction=self.nominal_beam_direction,
            points=tuple(p for p in self.points if p.id in keep),
            lines=tuple(ln for ln in self.lines if ln.id in keep),
            ellipses=tuple(e for e in self.ellipses if e.id in keep),
            frames=dict(self.frames),
        )
