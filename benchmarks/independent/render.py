"""``render_independent``: a held-out radiograph of a built fiducial over a voxel patient.

Image formation (see the sibling modules for each step):

1. Spectrum: tungsten Kramers, 1 keV bins, 3 mm Al + 0.1 mm Cu (:mod:`.spectrum`), or one
   energy (``mono_kev``) for checks against closed forms.
2. Patient: perspective DRR of the voxel pelvis (:mod:`.phantom`, :mod:`.drr`) on a grid of
   every ``coarse``-th pixel, bilinear in between; it lies between the source and the
   fiducial, which rests on its anterior skin (:func:`patient_placement`).
3. Fiducial: steel and acetal chords along a ray through every ``subsample``² point of each
   pixel inside the fiducial's projected bounding box (:mod:`.raycast`; Embree on the CAD
   body's STL and the steel meshes).
4. Per energy bin, Beer–Lambert through patient and fiducial; an energy-integrating
   detector sums quanta × energy; the focal spot and the detector MTF filter that photon
   field at sub-sample resolution (:mod:`.detector`), then sub-samples are averaged to pixels.
5. Scatter (a broad field at the requested SPR), the tube output set so the expected quanta
   behind the patient at the fiducial's projected centre are ``dose_behind_patient``,
   compound-Poisson noise, read noise, offset and gain to uint16.

Nothing here imports ``ftrac_design.xray``; the package supplies only the camera model,
feature loading and the build (``ftrac-design build``).
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import asdict, dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np
from _common import folder_digest
from scipy.ndimage import map_coordinates

from ftrac_design.pose import Camera

from .attenuation import linear_attenuation, mass_attenuation
from .detector import DetectorModel, auto_gain, blur, draw_counts, otf, read_out, scatter_field
from .drr import line_integrals, ray_directions
from .fiducial import FiducialScene, build_digest, design_path, load_scene
from .phantom import hu_to_basis, pelvis_phantom
from .raycast import material_chords
from .spectrum import Spectrum, tungsten_spectrum

TRUTH_FORMAT = "ftrac-independent-truth"

#: half-width (mm, in P) of the anterior skin ellipse the fiducial rests on
SKIN_X_MM, SKIN_Y_MM = 170.0, 115.0


@dataclass(frozen=True)
class RenderSettings:
    """Sampling and detector settings of :func:`render_independent`."""

    image_shape: tuple[int, int] = (1024, 1024)
    subsample: int = 4
    margin_px: int = 24
    coarse: int = 2
    drr_step_mm: float = 1.0
    al_mm: float = 3.0
    cu_mm: float = 0.1
    detector: DetectorModel = field(default_factory=DetectorModel)


@lru_cache(maxsize=1)
def _patient_basis(seed: int):
    vol = pelvis_phantom(seed)
    return vol, hu_to_basis(vol.data)


def patient_placement(scene: FiducialScene, rng: np.random.Generator | None) -> tuple[np.ndarray, np.ndarray]:
    """Pose of the patient frame P in F: ``P_F = R_pf P_P + t_pf`` (mm).

    The patient's posterior (+y_P) faces the source (−nominal beam), its superior axis
    (+z_P) is F's +z turned about the beam by up to ±15°, and the fiducial rests 3 mm above
    the anterior skin, shifted up to ±40 mm left–right and ±50 mm along the body
    (no shift and no turn when ``rng`` is None).
    """
    n = np.asarray(scene.features.nominal_beam_direction, float)
    n /= np.linalg.norm(n)
    y = -n
    z = np.array([0.0, 0.0, 1.0]) - n[2] * n
    z = z / np.linalg.norm(z) if np.linalg.norm(z) > 1e-6 else np.array([1.0, 0.0, 0.0])
    turn = math.radians(rng.uniform(-15, 15)) if rng is not None else 0.0
    z = math.cos(turn) * z + math.sin(turn) * np.cross(n, z)
    x = np.cross(y, z)
    R_pf = np.stack([x, y, z], 1)
    x_off = rng.uniform(-40, 40) if rng is not None else 0.0
    z_off = rng.uniform(-50, 50) if rng is not None else 0.0
    depth = float(np.max(scene.vertices @ -n))  # the fiducial's reach toward the patient
    y_skin = -SKIN_Y_MM * math.sqrt(1.0 - (x_off / SKIN_X_MM) ** 2)
    p0 = np.array([x_off, y_skin - depth - 3.0, z_off])  # the F origin in P
    return R_pf, -R_pf @ p0


def _mu_table(spec: Spectrum) -> dict[str, np.ndarray]:
    e = spec.energy_kev
    return {
        "steel": linear_attenuation("steel", e),
        "acetal": linear_attenuation("acetal", e),
        "soft": mass_attenuation("soft_tissue", e),
        "bone": mass_attenuation("bone", e),
    }


def _spectral_sums(spec: Spectrum, mu: dict, A: np.ndarray | None, steel=None, acetal=None):
    """Σ_E w E T and Σ_E w E² T over the spectrum, per sample (per unit open-field photon)."""
    shape = A.shape[:-1] if A is not None else np.shape(steel)
    S = np.zeros(shape)
    V = np.zeros(shape)
    for k, (e, w) in enumerate(zip(spec.energy_kev, spec.photons)):
        p = np.zeros(shape)
        if A is not None:
            p += A[..., 0] * mu["soft"][k] + A[..., 1] * mu["bone"][k]
        if steel is not None:
            p += steel * mu["steel"][k] + acetal * mu["acetal"][k]
        T = np.exp(-p)
        S += (w * e) * T
        V += (w * e * e) * T
    return S, V


def _coarse_sample(A: np.ndarray, u: np.ndarray, v: np.ndarray, c: int) -> np.ndarray:
    """Bilinear samples of a coarse-grid field (sample k at pixel c k + (c − 1)/2) at pixels (u, v)."""
    cu = (u - (c - 1) / 2) / c
    cv = (v - (c - 1) / 2) / c
    if A.ndim == 2:
        return map_coordinates(A, [cv, cu], order=1, mode="nearest")
    return np.stack([map_coordinates(A[..., k], [cv, cu], order=1, mode="nearest") for k in range(A.shape[-1])], -1)


def _fiducial_box(scene: FiducialScene, R, t, camera: Camera, shape, margin: int):
    """(cast box, blur box) as (row0, row1, col0, col1) pixel ranges, clipped to the image."""
    lo, hi = scene.bounds
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    X = corners @ np.asarray(R, float).T + t
    if np.any(X[:, 2] <= 1.0):
        raise ValueError("the pose puts part of the fiducial behind the source")
    uv = camera.project(X)
    c0, r0 = np.floor(uv.min(0)).astype(int) - 1
    c1, r1 = np.ceil(uv.max(0)).astype(int) + 2
    H, W = shape
    cast = (max(r0, 0), min(r1, H), max(c0, 0), min(c1, W))
    box = (max(r0 - margin, 0), min(r1 + margin, H), max(c0 - margin, 0), min(c1 + margin, W))
    return cast, box


def _subsample_grid(box, s: int):
    r0, r1, c0, c1 = box
    off = (np.arange(s) + 0.5) / s - 0.5
    u = (np.arange(c0, c1)[:, None] + off[None, :]).ravel()
    v = (np.arange(r0, r1)[:, None] + off[None, :]).ravel()
    return np.meshgrid(u, v)


def _fiducial_chords(scene, R, t, camera, cast, box, s):
    """Steel and acetal chords on the blur box's sub-sample grid (zero outside the cast box)."""
    U, V = _subsample_grid(box, s)
    steel = np.zeros(U.shape)
    acetal = np.zeros(U.shape)
    rs = slice((cast[0] - box[0]) * s, (cast[1] - box[0]) * s)
    cs = slice((cast[2] - box[2]) * s, (cast[3] - box[2]) * s)
    u, v = U[rs, cs], V[rs, cs]
    if u.size == 0:
        return U, V, steel, acetal
    src = -np.asarray(R, float).T @ np.asarray(t, float)
    d = ray_directions(camera, R, u, v)
    start = max(float(np.linalg.norm(src)) - scene.bounding_radius - 1.0, 0.0)
    idx = np.arange(u.size).reshape(u.shape)
    nb = np.roll(idx, 1, axis=1).ravel()
    ch = material_chords(scene, src + start * d, d, neighbours=nb)
    steel[rs, cs] = ch["steel"].reshape(u.shape)
    acetal[rs, cs] = ch["acetal"].reshape(u.shape)
    return U, V, steel, acetal


def _feather(shape, margin: int) -> np.ndarray:
    """Weights rising from 0 at a box's border to 1 at ``margin`` px inside."""
    ry = np.minimum(np.arange(shape[0]), np.arange(shape[0])[::-1])
    rx = np.minimum(np.arange(shape[1]), np.arange(shape[1])[::-1])
    w = np.minimum(ry[:, None], rx[None, :]) / max(margin / 2, 1)
    return np.clip(w, 0.0, 1.0)


def render_independent(
    preset: str,
    R: np.ndarray,
    t: np.ndarray,
    camera: Camera = Camera(),
    *,
    kvp: float = 80.0,
    dose_behind_patient: float = 1000.0,
    patient: bool = True,
    seed: int = 0,
    spr: float = 1.5,
    focal_spot_mm: float = 0.8,
    mono_kev: float | None = None,
    noise: bool = True,
    body: bool = True,
    steel: bool = True,
    settings: RenderSettings = RenderSettings(),
    patient_pose: tuple[np.ndarray, np.ndarray] | None = None,
) -> tuple[np.ndarray, dict[str, Any]]:
    """A raw C-arm image (uint16, dense = dark) of the built ``preset`` at pose (R, t).

    Parameters
    ----------
    preset : str
        A preset's name (or a design TOML path); built and cached on first use.
    R, t : numpy.ndarray
        Pose F → X (SPEC §1): ``P_X = R P_F + t``, mm.
    camera : Camera
        Intrinsics; the image is ``settings.image_shape``.
    kvp : float
        Tube voltage, kV (polychromatic unless ``mono_kev``).
    dose_behind_patient : float
        Expected detected quanta per pixel (primary + scatter) behind the patient at the
        fiducial's projected origin, without the fiducial; without a patient, in the open field.
    patient : bool
        Put the voxel pelvis between the source and the fiducial.
    seed : int
        Draws the patient's placement (shift, turn) and the noise.
    spr : float
        Scatter-to-primary ratio behind the pelvis (with a patient).
    focal_spot_mm : float
        Focal spot size (uniform square), mm.
    mono_kev : float, optional
        One photon energy instead of the spectrum (checks against closed forms).
    noise : bool
        False: the expected image (no quantum or read noise).
    body, steel : bool
        False leaves out the acetal body, or the steel balls and wires.
    settings : RenderSettings
        Sampling and detector model.
    patient_pose : (R_pf, t_pf), optional
        The patient frame's pose in F; default :func:`patient_placement` with ``seed``.

    Returns
    -------
    (counts, truth)
        ``counts`` (H, W) uint16 raw detector values; ``truth`` a JSON-ready dict with the
        pose, camera, physics settings, the expected-energy image's scale and the projected
        bead centres.
    """
    rng = np.random.default_rng(seed)
    R, t = np.asarray(R, float), np.asarray(t, float)
    scene = load_scene(preset, body, steel)
    H, W = settings.image_shape
    det = DetectorModel(**{**asdict(settings.detector), "focal_spot_mm": focal_spot_mm})
    spec = (
        Spectrum(float(mono_kev), np.array([float(mono_kev)]), np.array([1.0]))
        if mono_kev
        else tungsten_spectrum(kvp, settings.al_mm, settings.cu_mm)
    )
    mu = _mu_table(spec)
    placement = None
    if patient:
        placement = patient_pose if patient_pose is not None else patient_placement(scene, rng)
        fld = _patient_field(spec, mu, camera, R, t, placement, settings, det, spr)
    else:
        S_open = float(np.sum(spec.photons * spec.energy_kev))
        V_open = float(np.sum(spec.photons * spec.energy_kev**2))
        fld = _Field(np.full((H, W), S_open), np.full((H, W), V_open), np.zeros((H, W)), None, (S_open, V_open))
    cast = _add_fiducial(fld, scene, R, t, camera, spec, mu, settings, det)

    # tube output: the requested quanta behind the patient at the fiducial's projected origin
    e_mean = fld.V / np.maximum(fld.S, 1e-300)
    u0, v0 = camera.project(t)
    iu, iv = int(np.clip(round(u0), 0, W - 1)), int(np.clip(round(v0), 0, H - 1))
    ref_S, ref_V = fld.reference
    ref_quanta = (ref_S + float(fld.scatter[iv, iu])) / (ref_V / ref_S)
    n0 = float(dose_behind_patient) / ref_quanta
    energy = n0 * (fld.S + fld.scatter)
    gain = auto_gain(energy, det)
    counts = read_out(draw_counts(energy, e_mean, rng) if noise else energy, gain, det, rng if noise else None)
    truth = _truth(
        preset,
        scene,
        R,
        t,
        camera,
        spec,
        kvp,
        mono_kev,
        dose_behind_patient,
        patient,
        seed,
        spr,
        det,
        settings,
        placement,
        n0,
        gain,
        cast,
        e_mean[iv, iu],
    )
    return counts, truth


@dataclass
class _Field:
    """Per-pixel expected energy S and second moment V (per open-field photon), scatter, and
    the patient's coarse basis line integrals A (None without a patient)."""

    S: np.ndarray
    V: np.ndarray
    scatter: np.ndarray
    A: np.ndarray | None
    #: (S, V) of the patient alone (or the open field) at the fiducial's projected origin
    reference: tuple[float, float]


def _patient_field(
    spec, mu, camera: Camera, R, t, placement, settings: RenderSettings, det: DetectorModel, spr: float
) -> _Field:
    """The patient-only field: DRR on the coarse grid, spectral sums, pixel-level blur at the
    patient's magnification, and scatter."""
    H, W = settings.image_shape
    c = settings.coarse
    vol, basis = _patient_basis(7)
    R_pf, t_pf = placement
    R_px, t_px = R @ R_pf, R @ t_pf + t
    cu, cv = np.meshgrid(np.arange(W // c) * c + (c - 1) / 2, np.arange(H // c) * c + (c - 1) / 2)
    A = line_integrals(basis, vol, camera, R_px, t_px, cu, cv, settings.drr_step_mm)
    S_c, V_c = _spectral_sums(spec, mu, A)
    uu, vv = np.meshgrid(np.arange(W, dtype=float), np.arange(H, dtype=float))
    S, V = _coarse_sample(S_c, uu, vv, c), _coarse_sample(V_c, uu, vv, c)
    tr = otf((H + 64, W + 64), tuple(camera.pixel_size_mm[::-1]), det, camera.focal_length_mm / float(t_px[2]))
    S, V = blur(S, tr, 32), blur(V, tr, 32)
    S_open = float(np.sum(spec.photons * spec.energy_kev))
    pix = float(np.mean(camera.pixel_size_mm))
    scatter = _coarse_sample(scatter_field(S_c, S_open, spr, pix * c, det.scatter_sigma_mm), uu, vv, c)
    u0, v0 = camera.project(t)
    ref = tuple(float(_coarse_sample(x, np.array([u0]), np.array([v0]), c)[0]) for x in (S_c, V_c))
    return _Field(S, V, scatter, A, ref)


def _add_fiducial(
    fld: _Field, scene: FiducialScene, R, t, camera: Camera, spec, mu, settings: RenderSettings, det: DetectorModel
):
    """Replace the fiducial's box of ``fld`` by patient × fiducial at sub-sample resolution,
    blurred at the fiducial's magnification and integrated over pixels; returns the cast box."""
    s, c = settings.subsample, settings.coarse
    cast, box = _fiducial_box(scene, R, t, camera, settings.image_shape, settings.margin_px)
    r0, r1, c0, c1 = box
    if r1 <= r0 or c1 <= c0:
        return cast
    U, V, steel, acetal = _fiducial_chords(scene, R, t, camera, cast, box, s)
    A_sub = _coarse_sample(fld.A, U, V, c) if fld.A is not None else None
    S_sub, V_sub = _spectral_sums(spec, mu, A_sub, steel, acetal)
    pad = 8 * s
    tr = otf(
        (S_sub.shape[0] + 2 * pad, S_sub.shape[1] + 2 * pad),
        (camera.pixel_size_mm[1] / s, camera.pixel_size_mm[0] / s),
        det,
        camera.focal_length_mm / float(t[2]),
    )
    S_box = blur(S_sub, tr, pad).reshape(r1 - r0, s, c1 - c0, s).mean((1, 3))
    V_box = blur(V_sub, tr, pad).reshape(r1 - r0, s, c1 - c0, s).mean((1, 3))
    # with a patient, blend into the pixel-level field over the margin (both are the patient alone there)
    w = _feather(S_box.shape, settings.margin_px) if fld.A is not None else np.ones(S_box.shape)
    fld.S[r0:r1, c0:c1] = w * S_box + (1 - w) * fld.S[r0:r1, c0:c1]
    fld.V[r0:r1, c0:c1] = w * V_box + (1 - w) * fld.V[r0:r1, c0:c1]
    return cast


@lru_cache(maxsize=1)
def renderer_digest() -> str:
    """The sha256 (hex) of this renderer's source (:func:`_common.folder_digest` of its
    package): an image saved by another version of it is not this renderer's image."""
    return folder_digest(Path(__file__).resolve().parent)


def _truth(
    preset,
    scene,
    R,
    t,
    camera,
    spec,
    kvp,
    mono_kev,
    dose,
    patient,
    seed,
    spr,
    det,
    settings,
    placement,
    n0,
    gain,
    cast,
    e_ref,
) -> dict[str, Any]:
    f = scene.features
    X = f.point_centers() @ R.T + t
    uv = camera.project(X) if len(X) else np.zeros((0, 2))
    design = design_path(preset)
    return {
        "format": TRUTH_FORMAT,
        "version": 1,
        "renderer": "benchmarks/independent",
        "preset": f.name,
        "design_sha256": hashlib.sha256(design.read_bytes()).hexdigest(),
        "build_sha256": None if scene.build_dir is None else build_digest(scene.build_dir),
        "renderer_sha256": renderer_digest(),
        "rotation": R.tolist(),
        "translation_mm": t.tolist(),
        "camera": camera.to_dict(),
        "image_shape": list(settings.image_shape),
        "spectrum": {
            "kvp": None if mono_kev else kvp,
            "mono_kev": mono_kev,
            "al_mm": settings.al_mm,
            "cu_mm": settings.cu_mm,
            "mean_energy_kev": spec.mean_energy_kev,
        },
        "dose_behind_patient": dose,
        "patient": bool(patient),
        "seed": int(seed),
        "scatter_to_primary": spr if patient else 0.0,
        "detector": asdict(det),
        "subsample": settings.subsample,
        "patient_pose_in_F": None
        if placement is None
        else {"rotation": placement[0].tolist(), "translation_mm": placement[1].tolist()},
        "open_field_quanta_per_px": n0,
        "gain_adu_per_kev": gain,
        "mean_quantum_kev_at_origin": float(e_ref),
        "fiducial_box_rows_cols": [int(x) for x in cast],
        "points_px": {p.id: [float(a), float(b)] for p, (a, b) in zip(f.points, uv)},
    }
