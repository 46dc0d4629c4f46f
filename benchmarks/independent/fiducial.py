"""The fiducial as built: the CAD body's STL and steel wire and ball meshes, all in frame F.

``ftrac-design build`` writes the body (``fiducial.stl``: the acetal hollow cylinder with
its real grooves, pockets and key slot, frame F, mm) and ``features.json`` (the seated
wire centre-lines and ball centres, frame F); the bought parts are in the STEP assembly
only. So the steel is meshed here from ``features.json`` with trimesh, exactly as the
build seats it (``ftrac_design.cad.parts``):

- a ball: an icosphere on its seated centre, scaled so its volume is the sphere's;
- an ellipse wire: a circle of the wire diameter swept once around the seated ellipse,
  its section kept normal to the wire and its in-surface axis along the cylinder's normal;
- a straight wire: one capped cylinder per piece between the balls it is threaded on.

Polygonal sections are scaled to the circle's area, so line integrals through them are
right on average; the facet count keeps the radial gap to the true surface below
:data:`MAX_GAP_MM`. Every object is a
separate mesh (see :class:`FiducialScene`). Builds are cached under ``outputs/independent_cache/<preset>/<sha>/``,
because CadQuery takes seconds per build: keyed by the design file and the package's code, so a
build of parts the package no longer makes is never rendered (the build is byte-for-byte the same
for the same code, and :func:`build_digest` names what a render read).
"""

from __future__ import annotations

import hashlib
import math
import os
import subprocess
import sys
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np
import trimesh
from _common import code_fingerprint

from ftrac_design.design.presets import resolve_design
from ftrac_design.features import Features, load_features

ROOT = Path(__file__).resolve().parents[2]
CACHE = ROOT / "outputs" / "independent_cache"
#: environment variable that moves the build cache (the tests point it at a temporary folder)
CACHE_ENV = "FTRAC_INDEPENDENT_CACHE"

#: largest radial gap (mm) between a steel mesh and the ideal surface it stands for
MAX_GAP_MM = 2e-4

STEEL, ACETAL = "steel", "acetal"


@dataclass(frozen=True)
class FiducialScene:
    """The fiducial's closed meshes (outward normals, frame F, mm), one per object.

    ``objects``, ``materials`` and ``meshes`` are parallel: the body (acetal) first when
    present, then every ball and wire piece (steel). Each object is cast on its own, so a
    crossing of one object can never hide a crossing of another close behind it (a wire
    touching its groove's floor).
    """

    features: Features
    objects: tuple[str, ...]
    materials: tuple[str, ...]
    meshes: tuple[trimesh.Trimesh, ...]
    build_dir: Path | None

    @property
    def bounds(self) -> np.ndarray:
        """(2, 3) axis-aligned bounds of every mesh, mm in F."""
        b = np.array([m.bounds for m in self.meshes])
        return np.array([b[:, 0].min(0), b[:, 1].max(0)])

    @property
    def vertices(self) -> np.ndarray:
        """All meshes' vertices (n, 3), mm in F."""
        return np.concatenate([m.vertices for m in self.meshes])

    @property
    def bounding_radius(self) -> float:
        """Radius (mm) about the F origin of a sphere that holds every mesh."""
        return float(np.linalg.norm(self.vertices, axis=1).max())


def design_path(preset: str) -> Path:
    """The design file of ``preset``: a preset's name (``models/``) or a design TOML path."""
    return resolve_design(preset)


def build_path(preset: str) -> Path:
    """Where :func:`cached_build` keeps the build of ``preset`` (a preset's name or a design
    TOML path) as the package's code is now: ``<cache>/<design name>/<sha256[:16]>/``, the
    sha256 of the design file and :func:`_common.code_fingerprint`."""
    design = design_path(preset)
    sha = hashlib.sha256(design.read_bytes() + code_fingerprint().encode()).hexdigest()
    return Path(os.environ.get(CACHE_ENV) or CACHE) / design.stem / sha[:16]


def cached_build(preset: str) -> Path:
    """The directory of a ``ftrac-design build`` of ``preset``, built on first use.

    Parameters
    ----------
    preset : str
        A preset's name (``ftrac-design presets``) or a path to a design TOML.

    Returns
    -------
    pathlib.Path
        :func:`build_path` (under ``outputs/independent_cache/`` or ``$FTRAC_INDEPENDENT_CACHE``),
        holding ``fiducial.stl`` and ``features.json``.
    """
    out = build_path(preset)
    design = design_path(preset)
    if (out / "fiducial.stl").is_file() and (out / "features.json").is_file():
        return out
    out.parent.mkdir(parents=True, exist_ok=True)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    cmd = [sys.executable, "-m", "ftrac_design.cli.main", "build", str(design), "-o", str(out)]
    res = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True)
    if res.returncode != 0:
        raise RuntimeError(f"ftrac-design build {design.name} failed:\n{res.stdout}\n{res.stderr}")
    return out


def build_digest(build_dir: Path) -> str:
    """The sha256 (hex) of what a render reads from the build in ``build_dir``: its
    ``fiducial.stl`` and ``features.json``, in that order. An image rendered from a build
    of another digest shows other parts."""
    h = hashlib.sha256()
    for name in ("fiducial.stl", "features.json"):
        h.update((Path(build_dir) / name).read_bytes())
    return h.hexdigest()


def _sphere_subdivisions(radius: float) -> int:
    """Icosphere subdivisions whose facets stay within MAX_GAP_MM of a sphere of ``radius``."""
    for k in range(3, 9):
        edge_angle = 1.1071487 / 2**k  # icosahedron edge (63.4°) halved k times
        if radius * edge_angle**2 / 8 <= MAX_GAP_MM:
            return k
    return 8


def ball_mesh(center: np.ndarray, radius: float) -> trimesh.Trimesh:
    """A closed sphere mesh of ``radius`` (mm) on ``center`` (F) with the sphere's volume."""
    m = trimesh.creation.icosphere(subdivisions=_sphere_subdivisions(radius), radius=1.0)
    scale = (4.0 / 3.0 * math.pi / m.volume) ** (1.0 / 3.0)
    m.apply_scale(radius * scale)
    m.apply_translation(np.asarray(center, float))
    return m


def _sections(radius: float) -> int:
    """Polygon sides whose sagitta on a circle of ``radius`` is at most MAX_GAP_MM."""
    return max(24, int(math.ceil(math.pi / math.acos(max(1.0 - MAX_GAP_MM / radius, -1.0)))))


def _area_radius(radius: float, n: int) -> float:
    """Circumradius of a regular n-gon with the area of a circle of ``radius``."""
    return radius * math.sqrt(2 * math.pi / (n * math.sin(2 * math.pi / n)))


def cylinder_mesh(a: np.ndarray, b: np.ndarray, radius: float) -> trimesh.Trimesh:
    """A closed capped cylinder of ``radius`` (mm) from ``a`` to ``b`` (F)."""
    n = _sections(radius)
    return trimesh.creation.cylinder(radius=_area_radius(radius, n), sections=n, segment=np.array([a, b], float))


def ellipse_tube_mesh(e, radius: float) -> trimesh.Trimesh:
    """A closed tube of ``radius`` (mm) swept once around ellipse feature ``e`` (F).

    The section at each spine point spans the cylinder's outward normal made perpendicular
    to the tangent, and their cross product, as the build's pipe shell does.
    """
    n_around = _sections(radius)
    r_poly = _area_radius(radius, n_around)
    # spine points: the curvature radius is at least b²/a; keep the along-spine sagitta small
    rho = e.semi_minor**2 / e.semi_major
    step = math.sqrt(8 * rho * MAX_GAP_MM)
    n_along = max(64, int(math.ceil(e.circumference / step)))
    s = np.linspace(0.0, 2 * np.pi, n_along, endpoint=False)
    P = e.sample(s)
    T = e.tangent(s)
    T /= np.linalg.norm(T, axis=1, keepdims=True)
    N = np.c_[P[:, 0], P[:, 1], np.zeros(n_along)]
    N -= T * np.sum(N * T, axis=1, keepdims=True)
    N /= np.linalg.norm(N, axis=1, keepdims=True)
    B = np.cross(T, N)
    phi = np.linspace(0.0, 2 * np.pi, n_around, endpoint=False)
    verts = (
        P[:, None, :]
        + r_poly * (np.cos(phi)[None, :, None] * N[:, None, :] + np.sin(phi)[None, :, None] * B[:, None, :])
    ).reshape(-1, 3)
    i = np.arange(n_along)[:, None]
    j = np.arange(n_around)[None, :]
    v00 = i * n_around + j
    v01 = i * n_around + (j + 1) % n_around
    v10 = ((i + 1) % n_along) * n_around + j
    v11 = ((i + 1) % n_along) * n_around + (j + 1) % n_around
    faces = np.concatenate([np.stack([v00, v10, v11], -1).reshape(-1, 3), np.stack([v00, v11, v01], -1).reshape(-1, 3)])
    m = trimesh.Trimesh(verts, faces, process=False)
    if m.volume < 0:
        m.invert()
    return m


def steel_meshes(features: Features) -> list[tuple[str, trimesh.Trimesh]]:
    """(name, mesh) of every ball and wire piece of ``features``, frame F."""
    out = [(f"bead_{p.id}", ball_mesh(p.center, p.diameter / 2)) for p in features.points]
    for e in features.ellipses:
        out.append((f"wire_{e.id}", ellipse_tube_mesh(e, e.wire_diameter / 2)))
    for ln in features.lines:
        for k, (a, b) in enumerate(features.wire_segments(ln.id), start=1):
            out.append((f"wire_{ln.id}_{k}", cylinder_mesh(a, b, ln.wire_diameter / 2)))
    return out


def assemble(
    features: Features, parts: list[tuple[str, str, trimesh.Trimesh]], build_dir: Path | None = None
) -> FiducialScene:
    """One scene from (name, material, mesh) parts; each mesh must be a closed volume."""
    for name, _, m in parts:
        if not m.is_volume:
            raise ValueError(f"{name}: not a closed, consistently oriented volume")
    return FiducialScene(
        features,
        tuple(n for n, _, _ in parts),
        tuple(mat for _, mat, _ in parts),
        tuple(m for _, _, m in parts),
        build_dir,
    )


@lru_cache(maxsize=8)
def load_scene(preset: str, body: bool = True, steel: bool = True) -> FiducialScene:
    """The built fiducial of ``preset``: the CAD body (acetal) and every ball and wire (steel).

    Parameters
    ----------
    preset : str
        A preset's name or a design TOML path.
    body, steel : bool
        False leaves the body (acetal) or the balls and wires (steel) out.

    Returns
    -------
    FiducialScene
        All meshes in frame F (mm).
    """
    d = cached_build(preset)
    features = load_features(d / "features.json")
    parts = [(n, STEEL, m) for n, m in steel_meshes(features)] if steel else []
    if body:
        stl = trimesh.load_mesh(str(d / "fiducial.stl"), file_type="stl", process=True)
        parts.insert(0, ("body", ACETAL, stl))
    return assemble(features, parts, d)
