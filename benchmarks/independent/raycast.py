"""Chord lengths per material along rays through the fiducial's closed meshes (Embree).

Every hit along each ray comes from trimesh's Embree intersector (``embreex``) with
``multiple_hits``; a hit enters its object where the ray runs against the face normal and
leaves it where it runs along it. Each object is cast on its own (only the rays that pass its bounding sphere), so
near-coincident surfaces of two objects (a wire on its groove's floor) cannot hide each
other. Hits are paired per object after dropping repeats (a ray through a shared edge or
vertex can report the same crossing on two faces); a ray whose crossings of an object do not
alternate enter/leave is cast again with its direction turned by a microradian or so, and
as a last resort takes a neighbouring ray's value.

Materials: along a ray, a length where any steel object is open is steel; a length where
the body is open and no steel is, acetal; everything else (the grooves' free space, the
bore, the pockets above the balls) air, which attenuates nothing here.
"""

from __future__ import annotations

import numpy as np

from .fiducial import FiducialScene

#: two crossings of one object closer than this (mm) along a ray are one crossing
DUPLICATE_MM = 1e-6
#: rays re-cast with a perturbed direction before falling back to a neighbour
RETRIES = 3


def check_embree() -> None:
    """Raise ImportError unless trimesh's Embree backend (embreex) is in use."""
    import embreex  # noqa: F401
    from trimesh.ray.ray_pyembree import RayMeshIntersector  # noqa: F401


def _hits(mesh, origins: np.ndarray, dirs: np.ndarray):
    """(ray index, distance along the ray mm, +1 leave / −1 enter) of every hit on ``mesh``."""
    from trimesh.ray.ray_pyembree import RayMeshIntersector

    inter = mesh.ray
    if not isinstance(inter, RayMeshIntersector):
        raise ImportError("trimesh is not using Embree: pip install embreex")
    tri, ray, loc = inter.intersects_id(origins, dirs, multiple_hits=True, return_locations=True, max_hits=200)
    t = np.einsum("ij,ij->i", loc - origins[ray], dirs[ray])
    sign = np.sign(np.einsum("ij,ij->i", mesh.face_normals[tri], dirs[ray])).astype(np.int8)
    return ray, t, sign


def _near(mesh, origins: np.ndarray, dirs: np.ndarray) -> np.ndarray:
    """Indices of the rays passing within ``mesh``'s bounding sphere."""
    c = mesh.bounds.mean(0)
    rad = 0.5 * float(np.linalg.norm(mesh.bounds[1] - mesh.bounds[0])) + 1e-3
    w = c - origins
    along = np.einsum("ij,ij->i", w, dirs)
    d2 = np.einsum("ij,ij->i", w, w) - along**2
    return np.flatnonzero(d2 <= rad * rad)


def _object_crossings(mesh, origins, dirs, rng):
    """Paired crossings (ray, t, sign) of one closed mesh; rays that cannot be paired after
    :data:`RETRIES` re-casts with a turned direction are returned in ``unpaired``."""
    todo = _near(mesh, origins, dirs)
    out_r, out_t, out_s = [], [], []
    d = dirs[todo]
    for attempt in range(RETRIES + 1):
        if not len(todo):
            break
        ray, t, sign = _hits(mesh, origins[todo], d)
        ray, t, sign, bad = _pair(ray, t, sign, len(todo))
        good = ~bad[ray]
        out_r.append(todo[ray[good]])
        out_t.append(t[good])
        out_s.append(sign[good])
        todo = todo[bad]
        d = _turn(dirs[todo], rng, 1e-6 * 10**attempt)
    return _cat(out_r, np.int64), _cat(out_t, float), _cat(out_s, np.int8), todo


def _cat(parts: list[np.ndarray], dtype) -> np.ndarray:
    return np.concatenate(parts) if parts else np.zeros(0, dtype)


def _pair(ray, t, sign, n_rays: int):
    """Drop repeated crossings of one object and flag rays whose crossings do not alternate.

    Returns (ray, t, sign) sorted by ray then distance, and ``bad`` (n_rays,) bool.
    """
    order = np.lexsort((t, ray))
    ray, t, sign = ray[order], t[order], sign[order]
    same = np.zeros(len(t), bool)
    same[1:] = (ray[1:] == ray[:-1]) & (sign[1:] == sign[:-1]) & (np.abs(t[1:] - t[:-1]) < DUPLICATE_MM)
    ray, t, sign = ray[~same], t[~same], sign[~same]
    # per ray the signs must read −1, +1, −1, +1, …: running sum in {−1, 0}, ending at 0
    bad = np.zeros(n_rays, bool)
    if len(t):
        start = np.r_[True, ray[1:] != ray[:-1]]
        grp = np.cumsum(start) - 1
        csum = np.cumsum(sign.astype(np.int64))
        run = csum - np.r_[0, csum][np.flatnonzero(start)][grp]
        end = np.r_[start[1:], True]
        wrong = (run < -1) | (run > 0) | (end & (run != 0))
        bad[ray[wrong]] = True
    return ray, t, sign, bad


def _sweep(ray, t, sign, obj, steel_obj: np.ndarray, n_rays: int) -> tuple[np.ndarray, np.ndarray]:
    """Steel and acetal chord (mm) per ray from sorted, paired crossings."""
    steel = np.zeros(n_rays)
    acetal = np.zeros(n_rays)
    if len(t) < 2:
        return steel, acetal
    is_steel = steel_obj[obj]
    first = np.flatnonzero(np.r_[True, ray[1:] != ray[:-1]])
    grp = np.cumsum(np.r_[True, ray[1:] != ray[:-1]]) - 1

    def running(delta):  # open objects after each crossing, counted from the ray's start
        c = np.cumsum(delta)
        return c - np.r_[0, c][first][grp]

    n_steel = running(np.where(is_steel, -sign, 0).astype(np.int64))
    n_body = running(np.where(is_steel, 0, -sign).astype(np.int64))
    seg = ray[1:] == ray[:-1]
    length = np.where(seg, t[1:] - t[:-1], 0.0)
    in_steel = seg & (n_steel[:-1] > 0)
    in_acetal = seg & (n_steel[:-1] <= 0) & (n_body[:-1] > 0)
    steel = np.bincount(ray[:-1][in_steel], weights=length[in_steel], minlength=n_rays)
    acetal = np.bincount(ray[:-1][in_acetal], weights=length[in_acetal], minlength=n_rays)
    return steel, acetal


def _turn(dirs: np.ndarray, rng: np.random.Generator, angle: float) -> np.ndarray:
    d = dirs + angle * rng.standard_normal(dirs.shape)
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def material_chords(
    scene: FiducialScene, origins: np.ndarray, dirs: np.ndarray, neighbours: np.ndarray | None = None
) -> dict[str, np.ndarray]:
    """Steel and acetal path length (mm) along each ray through the fiducial.

    Parameters
    ----------
    scene : FiducialScene
        The meshes (frame F).
    origins : numpy.ndarray
        (n, 3) ray origins in F, mm, outside every mesh (before the fiducial).
    dirs : numpy.ndarray
        (n, 3) unit ray directions in F.
    neighbours : numpy.ndarray, optional
        (n,) index of a nearby ray whose value a ray takes if some object's crossings
        cannot be paired after :data:`RETRIES` re-casts (default: the previous ray).

    Returns
    -------
    dict
        ``{"steel": (n,), "acetal": (n,), "unpaired": int}``: chord lengths in mm and the
        number of rays that took a neighbour's value.
    """
    origins = np.ascontiguousarray(origins, float)
    dirs = np.ascontiguousarray(dirs, float)
    n = len(origins)
    rng = np.random.default_rng(0)
    rays, ts, signs, objs, unpaired = [], [], [], [], []
    for k, mesh in enumerate(scene.meshes):
        r, t, s, left = _object_crossings(mesh, origins, dirs, rng)
        rays.append(r)
        ts.append(t)
        signs.append(s)
        objs.append(np.full(len(r), k))
        unpaired.append(left)
    ray, t, sign, obj = (np.concatenate(x) for x in (rays, ts, signs, objs))
    order = np.lexsort((t, ray))
    steel_obj = np.array([m == "steel" for m in scene.materials])
    steel, acetal = _sweep(ray[order], t[order], sign[order], obj[order], steel_obj, n)
    left = np.unique(np.concatenate(unpaired)) if unpaired else np.zeros(0, int)
    if len(left):
        nb = np.asarray(neighbours) if neighbours is not None else np.maximum(np.arange(n) - 1, 0)
        steel[left], acetal[left] = steel[nb[left]], acetal[nb[left]]
    return {"steel": steel, "acetal": acetal, "unpaired": int(len(left))}
