"""The views a shop drawing shows, as plain 2-D polylines: a view's frame, a hidden-line
projection and a plane section.

A view is given by a :class:`ViewFrame`: the 2-D x axis ``x_dir`` and the direction
``toward_viewer`` (pointing from the part to the eye); the 2-D y axis is
``toward_viewer × x_dir``. All coordinates mm, in the part's own frame (F for the body, M
for the mount, T for the connector).

The sheets (:mod:`ftrac_design.manufacture.drawings`) ask a :class:`PartViews` for the
projections and sections they draw; :class:`ftrac_design.cad.views.SolidViews` computes them
from a CAD solid with OpenCASCADE, so nothing here needs CadQuery.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np


@dataclass(frozen=True)
class ViewFrame:
    """A parallel view: ``x_dir`` is the drawing's +x, ``toward_viewer`` points at the eye."""

    name: str
    x_dir: tuple[float, float, float]
    toward_viewer: tuple[float, float, float]
    origin: tuple[float, float, float] = (0.0, 0.0, 0.0)

    @property
    def y_dir(self) -> np.ndarray:
        """The drawing's +y: ``toward_viewer × x_dir``."""
        return np.cross(self.toward_viewer, self.x_dir)

    def to_2d(self, p: np.ndarray) -> np.ndarray:
        """Points (n, 3) in the part frame → (n, 2) in the view."""
        q = np.atleast_2d(np.asarray(p, float)) - np.asarray(self.origin, float)
        return np.column_stack([q @ np.asarray(self.x_dir, float), q @ self.y_dir])


@dataclass(frozen=True)
class Projection:
    """Visible and hidden edges of one view, each a polyline (n, 2) in mm."""

    frame: ViewFrame
    visible: tuple[np.ndarray, ...]
    hidden: tuple[np.ndarray, ...]

    def bounds(self) -> tuple[float, float, float, float]:
        """(xmin, xmax, ymin, ymax) of every edge."""
        pts = np.vstack(self.visible + self.hidden)
        return float(pts[:, 0].min()), float(pts[:, 0].max()), float(pts[:, 1].min()), float(pts[:, 1].max())


@dataclass(frozen=True)
class Section:
    """The faces a plane cuts from a solid: each face as (outer loop, inner loops), mm in 2-D."""

    frame: ViewFrame
    faces: tuple[tuple[np.ndarray, tuple[np.ndarray, ...]], ...]

    def loops(self) -> list[np.ndarray]:
        """Every loop of every face, outer loops and holes alike."""
        return [loop for outer, inner in self.faces for loop in (outer, *inner)]

    def bounds(self) -> tuple[float, float, float, float]:
        """(xmin, xmax, ymin, ymax) of every loop."""
        pts = np.vstack(self.loops())
        return float(pts[:, 0].min()), float(pts[:, 0].max()), float(pts[:, 1].min()), float(pts[:, 1].max())


class PartViews(Protocol):
    """What a sheet needs of a part's solid: its projections and its sections."""

    def project(self, frame: ViewFrame) -> Projection:
        """The hidden-line projection of the part in ``frame``."""
        ...

    def section(self, frame: ViewFrame) -> Section:
        """The part cut by the plane through ``frame.origin`` normal to ``toward_viewer``."""
        ...


def chain(polylines: list[np.ndarray], tol: float = 1e-6) -> list[np.ndarray]:
    """Join polylines that share end points into longer ones (a mesh's hidden-line removal
    returns one short edge per triangle side; drawing them one by one is slow).

    Parameters
    ----------
    polylines : list of numpy.ndarray
        Polylines (n, 2), mm.
    tol : float
        End points closer than this (mm, per coordinate) are the same point.

    Returns
    -------
    list of numpy.ndarray
        The joined polylines, each edge once.
    """

    def key(p: np.ndarray) -> tuple[int, int]:
        return int(round(p[0] / tol)), int(round(p[1] / tol))

    ends: dict[tuple[int, int], list[int]] = {}
    for i, pl in enumerate(polylines):
        ends.setdefault(key(pl[0]), []).append(i)
        ends.setdefault(key(pl[-1]), []).append(i)
    used = [False] * len(polylines)

    def extend(path: list[np.ndarray]) -> None:
        while True:
            cand = [j for j in ends.get(key(path[-1][-1]), []) if not used[j]]
            if not cand:
                return
            j = cand[0]
            used[j] = True
            nxt = polylines[j]
            path.append(nxt[1:] if key(nxt[0]) == key(path[-1][-1]) else nxt[::-1][1:])

    out = []
    for i, pl in enumerate(polylines):
        if used[i]:
            continue
        used[i] = True
        fwd = [pl]
        extend(fwd)
        back = [pl[::-1]]
        extend(back)
        joined = np.vstack([*[b[::-1] for b in back[:0:-1]], *fwd]) if len(back) > 1 else np.vstack(fwd)
        out.append(joined)
    return out
