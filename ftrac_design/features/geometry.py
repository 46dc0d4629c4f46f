"""Design → feature geometry. The only place where feature positions are computed.

Everything downstream — the CAD grooves and pockets, ``features.json``, the solver and the
analysis — takes its geometry from :func:`compute_features`, so the parts that are cut and
the model that is solved cannot drift apart.

Frame F (SPEC §1): origin on the cylinder axis at mid-length, ``+z`` along the axis,
azimuth φ measured about ``+z`` from ``+x`` toward ``+y``. Millimetres throughout.
"""

from __future__ import annotations

import math

import numpy as np

from ..design.schema import Design
from . import mounting
from .model import EllipseFeature, Features, LineFeature, PointFeature


def ellipse_feature(design: Design, index: int) -> EllipseFeature:
    """Seated centre-line of ellipse ``index`` as centre, orthonormal axes and semi-axes.

    The wire lies where the ellipse's plane — through ``(0, 0, z_center)``, normal tilted by
    τ from ``+z`` toward azimuth α — cuts the seating cylinder of radius r. That curve is an
    ellipse with semi-minor ``b = r`` along ``(−sin α, cos α, 0)`` and semi-major
    ``a = r / cos τ`` along ``(cos α cos τ, sin α cos τ, −sin τ)``; its normal is
    ``major × minor``.
    """
    e = design.ellipses[index]
    r, tau, alpha = design.ellipse_seat_radius, e.tilt_rad, e.tilt_azimuth_rad
    major = np.array([math.cos(alpha) * math.cos(tau), math.sin(alpha) * math.cos(tau), -math.sin(tau)])
    minor = np.array([-math.sin(alpha), math.cos(alpha), 0.0])
    return EllipseFeature(
        id=e.id,
        center=np.array([0.0, 0.0, e.z_center]),
        major_axis=major,
        minor_axis=minor,
        semi_major=r / math.cos(tau),
        semi_minor=r,
        wire_diameter=design.wire.diameter,
    )


def line_feature(design: Design, index: int) -> LineFeature:
    """Seated centre-line of straight wire ``index``: a segment parallel to ``+z``."""
    ln = design.lines[index]
    r = design.line_seat_radius
    xy = (r * math.cos(ln.azimuth_rad), r * math.sin(ln.azimuth_rad))
    return LineFeature(
        id=ln.id,
        start=np.array([*xy, ln.z_start]),
        end=np.array([*xy, ln.z_end]),
        wire_diameter=design.wire.diameter,
    )


def point_features(design: Design) -> list[PointFeature]:
    """Seated bead centres. Beads on lines are numbered ``B1…`` line by line, in z order;
    free beads keep their design id or continue the numbering."""
    out: list[PointFeature] = []
    n = 0
    d = design.bead.diameter if design.bead else 0.0
    for i in range(len(design.lines)):
        ln = design.lines[i]
        c = line_feature(design, i)
        for z in sorted(ln.beads_z):
            n += 1
            out.append(PointFeature(id=f"B{n}", center=np.array([c.start[0], c.start[1], z]), diameter=d, line=ln.id))
    r = design.free_bead_seat_radius
    for b in design.beads:
        n += 1
        out.append(
            PointFeature(
                id=b.id or f"B{n}",
                center=np.array([r * math.cos(b.azimuth_rad), r * math.sin(b.azimuth_rad), b.z]),
                diameter=d,
                line=None,
            )
        )
    return out


def mount_from_fiducial(design: Design) -> np.ndarray:
    """4×4 transform F → mount frame M (computed in :mod:`.mounting`).

    M has its origin at the centre of the socket floor, where the cylinder's ``z = −L/2``
    end face rests, and axes parallel to F: ``P_M = P_F + (0, 0, L/2)``.
    """
    return mounting.mount_from_fiducial(design)


def template_from_fiducial(design: Design) -> np.ndarray:
    """4×4 transform F → brachytherapy template frame T (``F_FT`` of paper §IV), computed in
    :mod:`.mounting` from the same mount and connector layout that the CAD builds:
    ``template_from_mount · mount_from_fiducial``.

    T: origin at the template's reference grid hole on its front face, ``+x`` along the grid
    rows, ``+y`` up the columns (anterior), ``+z`` along needle insertion. For a posterior
    X-ray source (``connector.source_side``, the default) F is turned 180° about z in T.
    """
    return mounting.template_from_fiducial(design)


def compute_features(design: Design) -> Features:
    """All seated features, mounting frames and the body of ``design`` (mm, F)."""
    return Features(
        name=design.name,
        source=design.source,
        sha256=design.sha256,
        nominal_beam_direction=design.nominal_beam.copy(),
        points=tuple(point_features(design)),
        lines=tuple(line_feature(design, i) for i in range(len(design.lines))),
        ellipses=tuple(ellipse_feature(design, i) for i in range(len(design.ellipses))),
        frames={
            "mount_from_fiducial": mount_from_fiducial(design),
            "template_from_fiducial": template_from_fiducial(design),
        },
        body=design.body,
    )
