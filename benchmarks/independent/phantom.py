"""A 3-D voxel patient: a lower lumbar spine and pelvis built from geometric solids, in HU.

No real CT volume could be installed here: pydicom's test files hold one 128² CT slice
(``CT_small.dcm``), the ``pydicom-data`` package two frames of a head (``eCT_Supplemental``),
and the DRR packages on PyPI (deepdrr, diffdrr) download their CTs at run time. So the patient
is made of solids (ellipsoids, elliptic cylinders, capsules, shells) in a 1 mm grid,
350 (left–right) × 250 (anterior–posterior) × 300 (inferior–superior) mm:

- the body: an elliptic cylinder of soft tissue (40 HU) in a 15 mm fat layer (−100 HU);
- bowel gas (−800 HU) and contents in the abdomen, a fluid bladder;
- lumbar vertebrae L3–L5: bodies with a 1.5 mm cortical shell (1100 HU) round trabecular
  bone (220 HU), discs (90 HU), pedicles, laminae, transverse and spinous processes;
- the sacrum (a tilted shelled plate), iliac wings (curved shells, cortical faces round
  trabecular bone), acetabula, femoral heads, necks, trochanters and shafts, pubic and
  ischial rami.

Frame P (mm): origin at the volume's centre, ``+x`` patient left, ``+y`` posterior, ``+z``
superior. :func:`hu_to_basis` turns HU into two basis densities (soft tissue, cortical bone)
whose line integrals the DRR projects.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

#: grid size (x, y, z) in voxels and voxel pitch (mm)
SHAPE = (350, 250, 300)
VOXEL_MM = 1.0

HU_FAT, HU_SOFT, HU_GAS, HU_FLUID = -100.0, 40.0, -800.0, 10.0
HU_CORTICAL, HU_TRABECULAR, HU_DISC = 1100.0, 220.0, 90.0

#: HU of pure cortical bone in :func:`hu_to_basis`'s ramp
HU_BONE_FULL = 1400.0
RHO_SOFT, RHO_BONE = 1.06, 1.92


@dataclass(frozen=True)
class Volume:
    """A voxel volume indexed ``[ix, iy, iz]``; voxel (0, 0, 0)'s centre at ``origin`` (mm, P)."""

    data: np.ndarray
    origin: np.ndarray
    voxel_mm: float

    def coords(self, axis: int) -> np.ndarray:
        """Voxel-centre coordinates (mm) along ``axis``."""
        return self.origin[axis] + self.voxel_mm * np.arange(self.data.shape[axis])


class _Painter:
    """Sets HU inside solids, each evaluated on its own bounding sub-box only."""

    def __init__(self, shape=SHAPE, voxel=VOXEL_MM, fill=-1000.0):
        self.hu = np.full(shape, fill, np.float32)
        self.origin = -0.5 * voxel * (np.array(shape) - 1)
        self.voxel = voxel

    def _box(self, lo, hi):
        i0 = np.clip(np.floor((np.asarray(lo) - self.origin) / self.voxel).astype(int), 0, np.array(self.hu.shape))
        i1 = np.clip(np.ceil((np.asarray(hi) - self.origin) / self.voxel).astype(int) + 1, 0, np.array(self.hu.shape))
        sl = tuple(slice(a, b) for a, b in zip(i0, i1))
        ax = [self.origin[k] + self.voxel * np.arange(i0[k], i1[k]) for k in range(3)]
        return sl, np.meshgrid(*ax, indexing="ij", sparse=True)

    def paint(self, lo, hi, inside, value: float) -> None:
        """Set ``value`` where ``inside(x, y, z)`` holds within the box [lo, hi] (mm)."""
        sl, (x, y, z) = self._box(lo, hi)
        m = inside(x, y, z)
        if np.any(m):
            self.hu[sl][np.broadcast_to(m, self.hu[sl].shape)] = value

    def ellipsoid(self, c, r, value, rot: np.ndarray | None = None) -> None:
        c, r = np.asarray(c, float), np.asarray(r, float)
        R = np.eye(3) if rot is None else np.asarray(rot, float)
        ext = np.abs(R) @ r  # half-extent of the rotated ellipsoid's box

        def inside(x, y, z):
            d = [x - c[0], y - c[1], z - c[2]]
            q = [(R[0, k] * d[0] + R[1, k] * d[1] + R[2, k] * d[2]) / r[k] for k in range(3)]
            return q[0] ** 2 + q[1] ** 2 + q[2] ** 2 <= 1.0

        self.paint(c - ext, c + ext, inside, value)

    def shelled_ellipsoid(self, c, r, shell, outer_hu, inner_hu, rot=None) -> None:
        self.ellipsoid(c, r, outer_hu, rot)
        self.ellipsoid(c, np.maximum(np.asarray(r, float) - shell, 0.1), inner_hu, rot)

    def capsule(self, a, b, radius, value) -> None:
        a, b = np.asarray(a, float), np.asarray(b, float)
        d = b - a
        L2 = float(d @ d)

        def inside(x, y, z):
            s = np.clip(((x - a[0]) * d[0] + (y - a[1]) * d[1] + (z - a[2]) * d[2]) / L2, 0.0, 1.0)
            return (x - a[0] - s * d[0]) ** 2 + (y - a[1] - s * d[1]) ** 2 + (z - a[2] - s * d[2]) ** 2 <= radius**2

        self.paint(np.minimum(a, b) - radius, np.maximum(a, b) + radius, inside, value)

    def shelled_capsule(self, a, b, radius, shell, outer_hu, inner_hu) -> None:
        self.capsule(a, b, radius, outer_hu)
        self.capsule(a, b, radius - shell, inner_hu)

    def elliptic_cylinder(self, c, ax, ay, z0, z1, value) -> None:
        def inside(x, y, z):
            return (((x - c[0]) / ax) ** 2 + ((y - c[1]) / ay) ** 2 <= 1.0) & (z >= z0) & (z <= z1)

        self.paint((c[0] - ax, c[1] - ay, z0), (c[0] + ax, c[1] + ay, z1), inside, value)


def _rot_x(deg: float) -> np.ndarray:
    a = np.radians(deg)
    return np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])


def _soft_tissues(p: _Painter, rng: np.random.Generator) -> None:
    zlo, zhi = -160.0, 160.0
    p.elliptic_cylinder((0, 0), 170, 115, zlo, zhi, HU_FAT)
    p.elliptic_cylinder((0, 2), 155, 100, zlo, zhi, HU_SOFT)
    p.ellipsoid((0, -45, -95), (45, 35, 35), HU_FLUID)  # bladder
    for _ in range(26):  # bowel loops: gas pockets in fluid/faecal content, anterior abdomen
        c = (rng.uniform(-105, 105), rng.uniform(-85, -5), rng.uniform(-30, 150))
        r = rng.uniform(8, 24, 3)
        p.ellipsoid(c, r * 1.25, HU_FLUID + rng.uniform(-10, 30))
        p.ellipsoid(c, r, HU_GAS + rng.uniform(-100, 100))


def _vertebra(p: _Painter, zc: float, height: float) -> None:
    y_body = 35.0
    p.elliptic_cylinder((0, y_body), 25, 19, zc - height / 2, zc + height / 2, HU_CORTICAL)
    p.elliptic_cylinder((0, y_body), 23.5, 17.5, zc - height / 2 + 1.5, zc + height / 2 - 1.5, HU_TRABECULAR)
    for s in (-1, 1):
        p.shelled_capsule((s * 13, 50, zc), (s * 17, 64, zc), 5.5, 1.5, HU_CORTICAL, 500)  # pedicle
        p.shelled_capsule((s * 19, 62, zc), (s * 48, 60, zc + 2), 4.5, 1.5, HU_CORTICAL, 450)  # transverse process
        p.shelled_capsule((s * 17, 66, zc), (s * 4, 78, zc - 3), 5, 1.5, HU_CORTICAL, 450)  # lamina
    p.shelled_ellipsoid((0, 92, zc - 6), (4.5, 16, 10), 1.5, HU_CORTICAL, 450)  # spinous process


def _spine(p: _Painter) -> None:
    for zc in (124.0, 88.0, 52.0):  # L3, L4, L5
        _vertebra(p, zc, 27.0)
    for zd in (106.0, 70.0):
        p.elliptic_cylinder((0, 35), 24, 18, zd - 4.5, zd + 4.5, HU_DISC)
    p.elliptic_cylinder((0, 37), 24, 18, 30, 38, HU_DISC)  # L5–S1


def _pelvis(p: _Painter) -> None:
    tilt = _rot_x(-35.0)  # the sacrum leans back from the L5–S1 disc
    p.shelled_ellipsoid((0, 62, -8), (52, 16, 46), 2.0, 900, 300, tilt)
    p.shelled_ellipsoid((0, 82, -60), (22, 10, 22), 2.0, 900, 300, _rot_x(-55.0))  # coccygeal end
    for s in (-1, 1):
        c = np.array([s * 30.0, 25.0, 15.0])
        r_out = np.array([118.0, 78.0, 92.0])

        def wing(x, y, z, c=c, r=r_out, s=s, t=0.0):
            q = ((x - c[0]) / (r[0] - t)) ** 2 + ((y - c[1]) / (r[1] - t)) ** 2 + ((z - c[2]) / (r[2] - t)) ** 2
            return q, (s * x > 55) & (y > -25) & (y < 80) & (z > -55) & (z < 95)

        def shell(t_out, t_in):
            def inside(x, y, z):
                q_out, keep = wing(x, y, z, t=t_out)
                q_in, _ = wing(x, y, z, t=t_in)
                return keep & (q_out <= 1.0) & (q_in > 1.0)

            return inside

        lo = (min(s * 55, s * 150), -25, -55)
        hi = (max(s * 55, s * 150), 80, 95)
        p.paint(lo, hi, shell(0.0, 9.0), HU_CORTICAL)  # iliac wing: cortical faces …
        p.paint(lo, hi, shell(2.0, 7.0), 280)  # … round trabecular bone
        head = np.array([s * 92.0, 5.0, -88.0])
        p.shelled_ellipsoid(head, (33, 33, 30), 4.0, 950, 350)  # acetabulum round the head
        p.shelled_ellipsoid(head, (24, 24, 24), 2.0, 1000, 330)  # femoral head
        p.shelled_capsule(head, (s * 128, 14, -118), 15, 2.5, 1000, 300)  # neck
        p.shelled_ellipsoid((s * 138, 18, -118), (17, 19, 22), 2.5, 950, 280)  # greater trochanter
        p.shelled_capsule((s * 134, 18, -125), (s * 140, 20, -170), 14, 5.0, 1400, 60)  # shaft
        p.shelled_capsule((s * 70, -18, -100), (s * 12, -52, -108), 10, 2.0, 950, 320)  # superior pubic ramus
        p.shelled_capsule((s * 12, -50, -118), (s * 62, 5, -140), 8, 2.0, 950, 320)  # inferior ramus
        p.shelled_capsule((s * 82, 22, -100), (s * 62, 12, -142), 12, 2.0, 950, 300)  # ischium
        p.shelled_capsule((s * 28, 70, 25), (s * 60, 55, 20), 9, 2.0, 900, 300)  # sacro-iliac joint
    p.capsule((-3, -54, -110), (3, -54, -110), 6, HU_DISC)  # pubic symphysis


@lru_cache(maxsize=2)
def pelvis_phantom(seed: int = 7) -> Volume:
    """The HU volume of the lower spine and pelvis (the bowel gas drawn with ``seed``).

    Parameters
    ----------
    seed : int
        Seed for the bowel loops' placement.

    Returns
    -------
    Volume
        float32 HU, shape :data:`SHAPE`, 1 mm voxels centred on P's origin.
    """
    p = _Painter()
    _soft_tissues(p, np.random.default_rng(seed))
    _spine(p)
    _pelvis(p)
    return Volume(p.hu, p.origin.astype(float), VOXEL_MM)


def hu_to_basis(hu: np.ndarray) -> np.ndarray:
    """Two basis densities (g/cm³) per voxel: soft tissue and cortical bone, stacked last.

    Below 0 HU a voxel is soft tissue thinned toward air, ρ_soft = 1.06 (1 + HU/1000);
    above, a volume mixture of soft tissue and cortical bone with bone fraction
    f = HU / 1400 (clipped to 1): ρ_soft = 1.06 (1 − f), ρ_bone = 1.92 f.

    Parameters
    ----------
    hu : numpy.ndarray
        Hounsfield units.

    Returns
    -------
    numpy.ndarray
        float32, shape ``hu.shape + (2,)``.
    """
    hu = np.asarray(hu, np.float32)
    f = np.clip(hu / HU_BONE_FULL, 0.0, 1.0)
    soft = np.where(hu < 0, RHO_SOFT * np.clip(1.0 + hu / 1000.0, 0.0, None), RHO_SOFT * (1.0 - f))
    return np.stack([soft, RHO_BONE * f], -1).astype(np.float32)
