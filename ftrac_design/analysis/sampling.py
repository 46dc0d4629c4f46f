"""Where the analysis looks from: workspace poses and view-direction grids (SPEC §1).

The workspace sampler is the simulator's (:class:`ftrac_design.pose.simulate.Workspace`):
beam directions uniform over the spherical cap within ``cone_deg`` of the design's nominal
beam, any roll, the fiducial origin within ``depth_range_mm`` of ``depth_mm`` from the source
and within ``lateral_mm`` of the principal ray. ``cone_deg = 180`` is the whole sphere.

The atlas grids put the fiducial origin on the principal ray at the isocentre depth and
roll 0: there the singular values and the RMS errors do not depend on the roll (an image
rotation about the principal point; tested), so one pose per direction maps a direction.
"""

from __future__ import annotations

import numpy as np

from ..pose.simulate import Workspace, beam_azimuth_basis, cone_directions, rotations_from_beams

__all__ = ["Workspace", "workspace_poses", "sphere_grid", "cone_grid", "isocentre_poses", "angle_from"]


def workspace_poses(workspace: Workspace, nominal_beam: np.ndarray, n: int, seed: int = 0):
    """``n`` random workspace poses, reproducible from ``seed``: R (n, 3, 3), t (n, 3) mm, F → X."""
    return workspace.sample(n, np.asarray(nominal_beam, float), np.random.default_rng(seed))


def sphere_grid(step_deg: float = 2.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Cell centres of a longitude/latitude grid over the whole sphere of beam directions.

    Longitude is the azimuth about the fiducial axis ``+z`` from ``+x`` toward ``+y``,
    latitude the elevation toward ``+z`` (degrees at this edge). Returns lon (nlat, nlon),
    lat (nlat, nlon) in degrees and unit directions (nlat, nlon, 3) in F.
    """
    nlon = int(round(360.0 / step_deg))
    nlat = int(round(180.0 / step_deg))
    lon = -180.0 + (np.arange(nlon) + 0.5) * 360.0 / nlon
    lat = -90.0 + (np.arange(nlat) + 0.5) * 180.0 / nlat
    LON, LAT = np.meshgrid(lon, lat)
    lo, la = np.radians(LON), np.radians(LAT)
    d = np.stack([np.cos(la) * np.cos(lo), np.cos(la) * np.sin(lo), np.sin(la)], -1)
    return LON, LAT, d


def cone_grid(
    nominal_beam: np.ndarray, cone_deg: float = 25.0, polar_step_deg: float = 1.0, azimuth_step_deg: float = 5.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A polar grid of beam directions within ``cone_deg`` of the nominal beam.

    Azimuth 0 tilts the beam toward the fiducial's ``+z`` (see
    :func:`~ftrac_design.pose.simulate.beam_azimuth_basis`). Returns polar (np, na) deg,
    azimuth (np, na) deg at cell centres and unit directions (np, na, 3) in F.
    """
    npol = max(1, int(round(cone_deg / polar_step_deg)))
    naz = int(round(360.0 / azimuth_step_deg))
    pol = (np.arange(npol) + 0.5) * cone_deg / npol
    az = (np.arange(naz) + 0.5) * 360.0 / naz
    POL, AZ = np.meshgrid(pol, az, indexing="ij")
    d = cone_directions(nominal_beam, np.radians(POL), np.radians(AZ))
    return POL, AZ, d


def isocentre_poses(directions: np.ndarray, depth_mm: float, roll_rad: float = 0.0):
    """Poses looking along ``directions`` (n, 3) in F with the fiducial origin on the
    principal ray at ``depth_mm`` from the source: R (n, 3, 3), t (n, 3)."""
    d = np.asarray(directions, float).reshape(-1, 3)
    R = rotations_from_beams(d, np.full(len(d), roll_rad))
    t = np.zeros((len(d), 3))
    t[:, 2] = depth_mm
    return R, t


def angle_from(nominal_beam: np.ndarray, directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Angle (deg) of ``directions`` (n, 3) from the nominal beam and their azimuth (deg)
    about it, measured as in :func:`cone_grid`."""
    a = np.asarray(nominal_beam, float) / np.linalg.norm(nominal_beam)
    e1, e2 = beam_azimuth_basis(a)
    d = np.asarray(directions, float).reshape(-1, 3)
    polar = np.degrees(np.arccos(np.clip(d @ a, -1.0, 1.0)))
    az = np.degrees(np.arctan2(d @ e2, d @ e1)) % 360.0
    return polar, az
