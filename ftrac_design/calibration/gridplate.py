"""A dewarping bead-grid plate and its simulated image through a distorting intensifier.

The plate is a :class:`~ftrac_design.features.Features` of free beads on a square lattice in
the plane z = 0 of its own frame F (mm), so that the radiograph simulator renders it like any
fiducial (:func:`ftrac_design.xray.render`, no body); the render is the ideal (pinhole)
image, which :func:`~ftrac_design.images.distortion.distort_image` then warps as the
intensifier would. Used by the tests and for trying :func:`.gridcal.estimate_distortion`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..features.model import Features, PointFeature
from ..images.distortion import DistortionModel, distort_image
from ..pose.camera import Camera
from ..xray import ImagingModel, render


def grid_plate(
    pitch_mm: float,
    rows: int,
    cols: int,
    bead_diameter_mm: float = 1.5,
    missing: tuple[tuple[int, int], ...] = (),
    extra_mm: tuple[tuple[float, float], ...] = (),
    extra_diameter_mm: float | None = None,
) -> Features:
    """A plate of ``rows`` × ``cols`` steel beads ``pitch_mm`` apart, centred on the F origin.

    Bead (i, j) (row i, column j) sits at x = (j − (cols − 1)/2) pitch, y = (i − (rows − 1)/2)
    pitch, z = 0 mm, id ``G{i}_{j}``; the beads at the indices in ``missing`` are left out.
    ``extra_mm`` adds stray beads (ids ``X0``, ``X1``, …) at (x, y) mm, of diameter
    ``extra_diameter_mm`` (default: 1.6 × the grid's), for tests of robustness to clutter.
    """
    pts = []
    gone = {tuple(m) for m in missing}
    for i in range(rows):
        for j in range(cols):
            if (i, j) in gone:
                continue
            c = np.array([(j - (cols - 1) / 2) * pitch_mm, (i - (rows - 1) / 2) * pitch_mm, 0.0])
            pts.append(PointFeature(f"G{i}_{j}", c, float(bead_diameter_mm)))
    d_extra = 1.6 * bead_diameter_mm if extra_diameter_mm is None else float(extra_diameter_mm)
    for k, (x, y) in enumerate(extra_mm):
        pts.append(PointFeature(f"X{k}", np.array([x, y, 0.0]), d_extra))
    return Features(
        name="bead-grid plate",
        source=None,
        sha256=None,
        nominal_beam_direction=np.array([0.0, 0.0, 1.0]),
        points=tuple(pts),
    )


@dataclass(frozen=True)
class GridImage:
    """A simulated grid image: ``raw`` (H, W) counts (dense = dark), the beads' ideal
    (pinhole) pixels ``ideal_px`` and distorted pixels ``distorted_px`` by id (n, 2 each,
    in ``ids`` order), and the camera it was rendered with."""

    raw: np.ndarray
    ids: tuple[str, ...]
    ideal_px: np.ndarray
    distorted_px: np.ndarray
    camera: Camera


def plate_pose(
    rotation_rad: float = 0.0,
    tilt_rad: tuple[float, float] = (0.0, 0.0),
    distance_mm: float = 970.0,
    offset_mm: tuple[float, float] = (0.0, 0.0),
) -> tuple[np.ndarray, np.ndarray]:
    """(R, t) of a plate facing the source: tilted by ``tilt_rad`` about the camera's x then y
    axis, turned by ``rotation_rad`` about the beam, its centre ``distance_mm`` from the source
    (default: taped to the face of an intensifier 1 m from the source) and ``offset_mm`` off the
    principal ray."""

    def rot(axis: int, a: float) -> np.ndarray:
        c, s = np.cos(a), np.sin(a)
        i, j = [k for k in range(3) if k != axis]
        m = np.eye(3)
        m[i, i], m[i, j], m[j, i], m[j, j] = c, -s, s, c
        return m

    R = rot(2, rotation_rad) @ rot(0, tilt_rad[0]) @ rot(1, tilt_rad[1])
    return R, np.array([offset_mm[0], offset_mm[1], distance_mm], float)


def render_grid(
    plate: Features,
    distortion: DistortionModel | None = None,
    *,
    camera: Camera | None = None,
    imaging: ImagingModel | None = None,
    pose: tuple[np.ndarray, np.ndarray] | None = None,
    field_radius_px: float | None = None,
    rng: np.random.Generator | None = None,
) -> GridImage:
    """Simulate the plate's image: the noise-free render (no body) is the pinhole image; it is
    warped by ``distortion`` (``distort_image``, bilinear), cut to a round intensifier field of
    ``field_radius_px`` about the image centre (dark outside, a 2 px soft edge), then given the
    quantum noise of ``imaging`` (Poisson) and quantised as the simulator's raw image.

    Defaults: a 512 × 512 image of 0.44 mm pixels (a 9-inch intensifier), f = 1000 mm, the
    principal point at the image centre; :func:`plate_pose`'s default pose.
    """
    imaging = imaging or ImagingModel(image_shape=(512, 512))
    H, W = imaging.image_shape
    camera = camera or Camera(1000.0, (0.44, 0.44), ((W - 1) / 2, (H - 1) / 2))
    R, t = pose if pose is not None else plate_pose()
    quiet = replace(imaging, photons_per_px=None)
    rad = render(plate, R, t, camera, quiet)
    trans = np.exp(-rad.line_integral)
    ids = tuple(p.id for p in plate.points)
    ideal = camera.project(plate.point_centers() @ R.T + t)
    distorted = ideal.copy()
    if distortion is not None:
        trans = distort_image(trans, distortion, "linear", fill=1.0)
        distorted = distortion.distort(ideal)
    if field_radius_px is not None:
        v, u = np.mgrid[0:H, 0:W]
        r = np.hypot(u - (W - 1) / 2, v - (H - 1) / 2)
        # the intensifier's output is dark outside its round field (1e-3 of the flat field)
        # a logistic edge; the exponent clipped where it is 0 or 1 to double precision anyway
        trans = trans * (1e-3 + (1 - 1e-3) / (1 + np.exp(np.clip((r - field_radius_px) / 0.5, -50, 50))))
    n0 = float(imaging.photons_per_px) if imaging.noisy else 1.0e4
    N = n0 * trans
    if imaging.noisy:
        rng = rng if rng is not None else np.random.default_rng()
        N = rng.poisson(N).astype(float)
    raw = np.clip(np.rint(N * imaging.raw_gain), 0, imaging.full_scale)
    raw = raw.astype(np.uint8 if imaging.bit_depth <= 8 else np.uint16)
    return GridImage(raw, ids, ideal, distorted, camera)
