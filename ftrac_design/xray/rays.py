"""Rays and primitives of the radiograph simulator, shared with the intensity model.

Both :mod:`.render` (which makes images) and :mod:`ftrac_design.intensity.model` (which
differentiates them) cast the same rays through the same primitives, so they agree to
rounding: :class:`Rays` gives each detector pixel's ray in the fiducial's frame F,
:func:`feature_pieces` the beads and wire pieces of a design, :func:`capsule_pixels` the
pixels a projected primitive can touch, :func:`subsample_offsets` the pixel-integration
sub-samples and :func:`project_points` the pinhole projection with the depth check. Lengths
mm, image coordinates px (SPEC §3 pixel centres).
"""

from __future__ import annotations

import functools
import math
import weakref

import numpy as np

from ..features.model import Features
from ..pose.camera import Camera
from .geometry import Pieces, ellipse_pieces, straight_pieces

#: body pixels whose 4-neighbour Laplacian exceeds this (line-integral units) are
#: supersampled, with their neighbours: the midpoint rule's error is ≈ Laplacian / 24, so
#: elsewhere it stays below ~4e-4 (measured ≤ 3e-4 against 8 × 8 supersampling everywhere;
#: the quantum noise of the default model is 1e-2)
BODY_ROUGHNESS = 1e-2

_scene_cache: dict[int, tuple] = {}


def feature_pieces(features: Features, mu_steel: float) -> tuple[np.ndarray, np.ndarray, Pieces]:
    """Beads (centres, radii) and wire pieces of ``features`` (pose-independent, cached)."""
    key = id(features)
    hit = _scene_cache.get(key)
    if hit is not None and hit[0]() is features and hit[1] == mu_steel:
        return hit[2]
    parts = []
    for k, ln in enumerate(features.lines):
        for a, b in features.wire_segments(ln.id):
            parts.append(straight_pieces(a, b, ln.wire_diameter / 2, mu_steel, k, max_len_mm=3.0))
    for k, el in enumerate(features.ellipses):
        parts.append(ellipse_pieces(el, mu_steel, len(features.lines) + k))
    centers = features.point_centers()
    radii = np.array([p.diameter / 2 for p in features.points], float)
    out = (centers, radii, Pieces.concat(parts))
    if len(_scene_cache) > 64:
        _scene_cache.clear()
    _scene_cache[key] = (weakref.ref(features), mu_steel, out)
    return out


class Rays:
    """Ray directions in F for image points: d = g0 + u gu + v gv; source at c."""

    def __init__(self, camera: Camera, R: np.ndarray, t: np.ndarray):
        Rt = np.asarray(R, float).T
        sx, sy = camera.pixel_size_mm
        ox, oy = camera.principal_point_px
        self.gu = Rt[:, 0] * sx
        self.gv = Rt[:, 1] * sy
        self.g0 = Rt[:, 2] * camera.focal_length_mm - ox * self.gu - oy * self.gv
        self.c = -Rt @ np.asarray(t, float)

    def __call__(self, u: np.ndarray, v: np.ndarray) -> np.ndarray:
        return self.g0 + u[:, None] * self.gu + v[:, None] * self.gv


def capsule_pixels(u0, v0, u1, v1, rad, clip: tuple[int, int, int, int] | None = None):
    """(primitive index, row, col) of every pixel whose centre lies within ``rad`` px of the
    segment (u0, v0)–(u1, v1) of each primitive; with ``clip`` (row0, row1, col0, col1), only
    those with row0 ≤ row < row1 and col0 ≤ col < col1, in the same order. The work and memory
    are then bounded by the box, however large the primitives project (a pose near the
    source)."""
    lo_u = np.floor(np.minimum(u0, u1) - rad).astype(int)
    lo_v = np.floor(np.minimum(v0, v1) - rad).astype(int)
    hi_u = np.ceil(np.maximum(u0, u1) + rad).astype(int)
    hi_v = np.ceil(np.maximum(v0, v1) + rad).astype(int)
    if clip is not None:
        r0, r1, c0, c1 = clip
        lo_v, hi_v = np.maximum(lo_v, r0), np.minimum(hi_v, r1 - 1)
        lo_u, hi_u = np.maximum(lo_u, c0), np.minimum(hi_u, c1 - 1)
        live = (lo_v <= hi_v) & (lo_u <= hi_u)
        if not live.any():
            empty = np.zeros(0, int)
            return empty, empty, empty
        # a primitive wholly outside the box gets an empty one (hi < lo: the mask is false there)
        lo_v, lo_u = np.where(live, lo_v, 0), np.where(live, lo_u, 0)
        hi_v, hi_u = np.where(live, hi_v, -1), np.where(live, hi_u, -1)
    Ku, Kv = int((hi_u - lo_u).max()) + 1, int((hi_v - lo_v).max()) + 1
    iu = lo_u[:, None, None] + np.arange(Ku)[None, None, :]
    iv = lo_v[:, None, None] + np.arange(Kv)[None, :, None]
    du, dv = (u1 - u0)[:, None, None], (v1 - v0)[:, None, None]
    qu, qv = iu - u0[:, None, None], iv - v0[:, None, None]
    ll = du * du + dv * dv
    s = np.clip((qu * du + qv * dv) / np.where(ll > 0, ll, 1.0), 0.0, 1.0)
    eu, ev = qu - s * du, qv - s * dv
    mask = (eu * eu + ev * ev <= (rad * rad)[:, None, None]) & (iu <= hi_u[:, None, None]) & (iv <= hi_v[:, None, None])
    k, jv, ju = np.nonzero(mask)
    return k, lo_v[k] + jv, lo_u[k] + ju


# a search over n candidates asked for by every render of every refinement step: one answer per n
@functools.lru_cache(maxsize=32)
def lattice_generator(n: int) -> int:
    """Generator g of the rank-1 lattice ``{(k/n, k g/n mod 1)}`` of ``n`` points with the largest
    smallest spacing (periodic), ties to the smallest g; n = 25 gives g = 7, a square grid
    turned by atan(3/4) whose spacing equals the 5 × 5 grid's."""
    best, best_d = 1, -1.0
    for g in range(1, max(n, 2)):
        if math.gcd(g, n) != 1:
            continue
        k = np.arange(1, n)
        du = np.minimum(k, n - k)
        dv = np.minimum(k * g % n, n - k * g % n)
        d = float(np.min(du * du + dv * dv)) if n > 1 else 0.0
        if d > best_d:
            best, best_d = g, d
    return best


def subsample_offsets(s: int) -> tuple[np.ndarray, np.ndarray]:
    """Offsets (u, v) in px of the s² sub-samples of a pixel about its centre, each (s²,).

    A rotated grid (the rank-1 lattice of :func:`lattice_generator`): sub-sample k of n = s²
    sits at ``u = (k + ½)/n − ½``, ``v = ((k g mod n) + ½)/n − ½``, so its n projections on
    either pixel axis (and, for odd s, on both diagonals) are all distinct and 1/n px apart. A
    wire along a pixel axis is then integrated across its width with s² samples per pixel
    rather than s: the summed attenuation of a 0.3 mm wire varies < 1 % with its sub-pixel
    phase at s = 5 (on a square 5 × 5 grid about 5 %), at the same cost. The offsets average
    to zero along both axes (the midpoint rule for smooth parts).
    """
    n = s * s
    k = np.arange(n)
    return (k + 0.5) / n - 0.5, (k * lattice_generator(n) % n + 0.5) / n - 0.5


class BehindSourceError(ValueError):
    """A pose puts part of the fiducial within 1 mm of the source plane or behind it: no
    projection exists. A fit that tries such a pose has taken too long a step, not met bad
    input, and can take a shorter one."""


def project_points(camera: Camera, R: np.ndarray, t: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pixel positions (n, 2) and depths Z (n,) in mm of points ``P`` (n, 3) in F at pose (R, t) (F → X).

    Raises :class:`BehindSourceError` (a ValueError) when a point is within 1 mm of the source
    plane or behind it (callers check the pose's depth first; this is the last guard before a
    division by Z)."""
    X = P @ np.asarray(R, float).T + t
    if np.any(X[:, 2] <= 1.0):
        raise BehindSourceError("the pose puts part of the fiducial behind the source")
    uv = camera.project(X)
    return uv, X[:, 2]
