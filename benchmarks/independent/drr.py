"""Perspective DRR: basis-material line integrals of a voxel volume, by ray marching.

Each ray from the source is clipped to the volume's x and y extent and sampled every
``step_mm`` with trilinear interpolation of both basis densities (numba, parallel over rays);
the sums times the step are the line integrals ∫ρ dl in g/cm². Beyond the volume's ends in z
the first and last slices continue unchanged, so the body does not stop inside the field of
view. The C-arm geometry is the SPEC §1 pinhole: a ray through detector point (u, v) runs
along ``R_pxᵀ [(u − o_x) s_x, (v − o_y) s_y, f]`` from the source ``−R_pxᵀ t_px`` in the
volume's frame, where (R_px, t_px) maps the volume's frame into the camera's.
"""

from __future__ import annotations

import numba
import numpy as np

from ftrac_design.pose import Camera

from .phantom import Volume


@numba.njit(parallel=True, fastmath=True, cache=True)
def _march(vol, lo, inv_vox, src, dirs, step):  # pragma: no cover - compiled
    nx, ny, nz, nc = vol.shape
    n = dirs.shape[0]
    out = np.zeros((n, nc), np.float64)
    hi = np.array([nx - 1.0, ny - 1.0, nz - 1.0])
    for r in numba.prange(n):
        # ray in index space: p(t) = a + t b, t in mm along the unit direction
        a = np.empty(3)
        b = np.empty(3)
        for k in range(3):
            a[k] = (src[k] - lo[k]) * inv_vox
            b[k] = dirs[r, k] * inv_vox
        t0, t1 = -1e30, 1e30
        for k in range(2):  # x and y slabs; along z the end slices extend the body
            if abs(b[k]) < 1e-12:
                if a[k] < 0.0 or a[k] > hi[k]:
                    t1 = -1e30
                continue
            ta = (0.0 - a[k]) / b[k]
            tb = (hi[k] - a[k]) / b[k]
            if ta > tb:
                ta, tb = tb, ta
            t0 = max(t0, ta)
            t1 = min(t1, tb)
        t0 = max(t0, 0.0)
        if t1 <= t0:
            continue
        m = int((t1 - t0) / step)
        acc0 = 0.0
        acc1 = 0.0
        for s in range(m):
            t = t0 + (s + 0.5) * step
            x = a[0] + t * b[0]
            y = a[1] + t * b[1]
            z = a[2] + t * b[2]
            i = min(max(int(x), 0), nx - 2)
            j = min(max(int(y), 0), ny - 2)
            k = min(max(int(z), 0), nz - 2)
            fx, fy = x - i, y - j
            fz = min(max(z - k, 0.0), 1.0)
            for c in range(nc):
                c00 = vol[i, j, k, c] * (1 - fx) + vol[i + 1, j, k, c] * fx
                c10 = vol[i, j + 1, k, c] * (1 - fx) + vol[i + 1, j + 1, k, c] * fx
                c01 = vol[i, j, k + 1, c] * (1 - fx) + vol[i + 1, j, k + 1, c] * fx
                c11 = vol[i, j + 1, k + 1, c] * (1 - fx) + vol[i + 1, j + 1, k + 1, c] * fx
                v = (c00 * (1 - fy) + c10 * fy) * (1 - fz) + (c01 * (1 - fy) + c11 * fy) * fz
                if c == 0:
                    acc0 += v
                else:
                    acc1 += v
        out[r, 0] = acc0 * step
        if nc > 1:
            out[r, 1] = acc1 * step
    return out


def ray_directions(camera: Camera, R: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Unit directions (n, 3) in the object frame of rays through detector points (u, v) px.

    ``R`` maps that frame into the camera frame X.
    """
    sx, sy = camera.pixel_size_mm
    ox, oy = camera.principal_point_px
    d = np.stack(
        [(np.ravel(u) - ox) * sx, (np.ravel(v) - oy) * sy, np.full(np.size(u), camera.focal_length_mm)], -1
    ) @ np.asarray(R, float)
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def line_integrals(
    basis: np.ndarray,
    volume: Volume,
    camera: Camera,
    R_px: np.ndarray,
    t_px: np.ndarray,
    u: np.ndarray,
    v: np.ndarray,
    step_mm: float = 0.5,
) -> np.ndarray:
    """Basis line integrals (g/cm²) along the rays through detector points (u, v).

    Parameters
    ----------
    basis : numpy.ndarray
        (nx, ny, nz, c) float32 basis densities (g/cm³) on ``volume``'s grid.
    volume : Volume
        Grid geometry (origin, voxel pitch; frame P).
    camera : Camera
        Intrinsics (SPEC §1).
    R_px, t_px : numpy.ndarray
        Pose of frame P in the camera frame X: ``P_X = R_px P_P + t_px`` (mm).
    u, v : numpy.ndarray
        Detector coordinates (pixels), any matching shapes.
    step_mm : float
        Sampling step along the ray, mm.

    Returns
    -------
    numpy.ndarray
        ``u.shape + (c,)`` line integrals ∫ρ dl, g/cm².
    """
    R_px, t_px = np.asarray(R_px, float), np.asarray(t_px, float)
    src = -R_px.T @ t_px
    dirs = ray_directions(camera, R_px, u, v)
    out = _march(basis, np.asarray(volume.origin, float), 1.0 / volume.voxel_mm, src, dirs, float(step_mm))
    return (out / 10.0).reshape(np.shape(u) + (basis.shape[-1],))
