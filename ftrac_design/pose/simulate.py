"""Synthetic images: workspace poses, projected features, the paper's error models.

- Workspace (SPEC §1): beam directions (camera ``+z`` in F) uniform over the spherical cap
  within ``cone_deg`` of the design's nominal beam, any roll about the beam, the fiducial
  origin at ``depth_mm`` ± ``depth_range_mm`` from the source and within
  ``lateral_mm`` of the principal ray (uniform). ``cone_deg = 180`` is the whole sphere.
- Segmentation error (paper §III.A): a displacement of uniformly distributed magnitude in
  [0, e] mm at the detector, in a uniformly random direction, added to every bead centre
  and every contour point (per-axis σ = e/√6).
- Contours: ``ContourSampling.ellipse`` points evenly spaced in the ellipse parameter and
  ``ContourSampling.line`` points evenly spaced between the line's end-points.
- C-arm parameter errors (paper §III.A): the image is made with the true camera and solved
  with one whose focal length, pixel size and principal point are off by uniform errors.

:func:`synthetic_problem` builds the solver's arrays for noise-free images directly (exact
projected conics, the information the contour fit would report) — the analysis uses it to
get the solver's Jacobian at thousands of poses without fitting anything.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import partial

import numpy as np

from ..features.model import Features
from . import so3
from .camera import Camera
from .fitting import conic_vector, normalisation, sampson_theta_jacobian, tangent_basis
from .observation import CurveObservation, Observation
from .problem import ELLIPSE_MODEL_POINTS, NoiseModel, Problem, paper_k


@dataclass(frozen=True)
class Workspace:
    """Where the C-arm may look from (SPEC §1). Angles in degrees at this edge only."""

    cone_deg: float = 25.0
    depth_mm: float = 667.0
    depth_range_mm: float = 25.0
    lateral_mm: float = 25.0
    roll_deg: tuple[float, float] = (0.0, 360.0)

    def sample(self, n: int, nominal_beam: np.ndarray, rng: np.random.Generator):
        """``n`` poses: rotations (n, 3, 3) and translations (n, 3) mm, F → X."""
        c = math.cos(math.radians(self.cone_deg))
        cos_t = rng.uniform(c, 1.0, n)
        az = rng.uniform(0.0, 2 * np.pi, n)
        roll = np.radians(rng.uniform(*self.roll_deg, n))
        beams = cone_directions(nominal_beam, np.arccos(cos_t), az)
        R = rotations_from_beams(beams, roll)
        t = np.stack(
            [
                rng.uniform(-self.lateral_mm, self.lateral_mm, n),
                rng.uniform(-self.lateral_mm, self.lateral_mm, n),
                rng.uniform(self.depth_mm - self.depth_range_mm, self.depth_mm + self.depth_range_mm, n),
            ],
            -1,
        )
        return R, t


def _perp_basis(d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    d = d / np.linalg.norm(d)
    helper = np.array([0.0, 0.0, 1.0]) if abs(d[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    e1 = np.cross(helper, d)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(d, e1)


def cone_directions(axis: np.ndarray, polar: np.ndarray, azimuth: np.ndarray) -> np.ndarray:
    """Unit vectors at ``polar`` angles (rad) from ``axis``, turned by ``azimuth`` (rad)
    about it, measured from the axis's first perpendicular (see :func:`beam_azimuth_basis`)."""
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    e1, e2 = beam_azimuth_basis(axis)
    polar, azimuth = np.asarray(polar, float), np.asarray(azimuth, float)
    return np.cos(polar)[..., None] * axis + np.sin(polar)[..., None] * (
        np.cos(azimuth)[..., None] * e1 + np.sin(azimuth)[..., None] * e2
    )


def beam_azimuth_basis(axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The two unit vectors (F) from which beam azimuths about ``axis`` are measured: the
    first is the fiducial axis ``+z`` made perpendicular to ``axis`` (so azimuth 0 tilts the
    beam toward ``+z``, i.e. cranial/caudal along the cylinder), the second completes a
    right-handed frame. Falls back to ``+x`` when ``axis`` is along z."""
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    ref = np.array([0.0, 0.0, 1.0])
    if abs(axis @ ref) > 0.999:
        ref = np.array([1.0, 0.0, 0.0])
    e1 = ref - (ref @ axis) * axis
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(axis, e1)


def rotations_from_beams(beams: np.ndarray, roll: np.ndarray) -> np.ndarray:
    """Rotations F → X whose camera ``+z`` is ``beams`` (n, 3) in F, rolled by ``roll`` rad."""
    beams = np.atleast_2d(beams) / np.linalg.norm(np.atleast_2d(beams), axis=-1, keepdims=True)
    roll = np.broadcast_to(np.asarray(roll, float), beams.shape[:1])
    helper = np.where(np.abs(beams[:, 2:3]) < 0.9, [[0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0]])
    u = np.cross(helper, beams)
    u /= np.linalg.norm(u, axis=-1, keepdims=True)
    v = np.cross(beams, u)
    xa = np.cos(roll)[:, None] * u + np.sin(roll)[:, None] * v
    ya = np.cross(beams, xa)
    return np.stack([xa, ya, beams], 1)


@dataclass(frozen=True)
class ContourSampling:
    """How many segmented contour points each curve yields."""

    ellipse: int = 24
    line: int = 12


@dataclass(frozen=True)
class CalibrationError:
    """Maximum C-arm parameter errors, drawn uniformly in ± these (paper §III.A: 2 mm,
    0.5 mm of principal point, 1 µm of pixel size)."""

    focal_mm: float = 0.0
    principal_point_mm: float = 0.0
    pixel_mm: float = 0.0

    def draw(self, camera: Camera, rng: np.random.Generator) -> Camera:
        """The miscalibrated camera the solver is given."""
        px = np.asarray(camera.pixel_size_mm)
        dpp = rng.uniform(-self.principal_point_mm, self.principal_point_mm, 2) / px
        return camera.perturbed(
            rng.uniform(-self.focal_mm, self.focal_mm), tuple(rng.uniform(-self.pixel_mm, self.pixel_mm, 2)), tuple(dpp)
        )


PAPER_CALIBRATION_ERROR = CalibrationError(focal_mm=2.0, principal_point_mm=0.5, pixel_mm=0.001)


def segmentation_noise(shape: tuple[int, ...], e_mm: float, pixel_mm, rng: np.random.Generator) -> np.ndarray:
    """Displacements (…, 2) px: magnitude uniform in [0, e] mm, direction uniform."""
    mag = rng.uniform(0.0, e_mm, shape)
    ang = rng.uniform(0.0, 2 * np.pi, shape)
    return np.stack([mag * np.cos(ang) / pixel_mm[0], mag * np.sin(ang) / pixel_mm[1]], -1)


def simulate_observation(
    features: Features,
    camera: Camera,
    R: np.ndarray,
    t: np.ndarray,
    segmentation_error_mm: float = 0.0,
    rng: np.random.Generator | None = None,
    contour: ContourSampling = ContourSampling(),
    include: set[str] | None = None,
    solve_camera: Camera | None = None,
    as_coefficients: bool = False,
    error_factors: tuple[float, float] = (1.0, 1.0),
) -> Observation:
    """One synthetic image of ``features`` at pose (R, t) (F → X, mm).

    ``segmentation_error_mm``: the paper's uniform error magnitude at the detector, times
    ``error_factors`` (bead, wire) for beads and for contour points. ``include`` limits the
    observed feature ids; ``solve_camera`` is the (miscalibrated) camera written into the
    observation; ``as_coefficients`` reports curves as fitted coefficients from the exact
    projection instead of contour points.
    """
    rng = rng or np.random.default_rng()
    e = segmentation_error_mm
    eb, ew = e * error_factors[0], e * error_factors[1]
    px = camera.pixel_size_mm
    keep = (lambda fid: True) if include is None else (lambda fid: fid in include)

    def proj(P: np.ndarray) -> np.ndarray:
        return camera.project(np.asarray(P) @ R.T + t)

    obs = Observation(solve_camera or camera, origin="<simulated>")
    pts = [p for p in features.points if keep(p.id)]
    if pts:
        uv = proj(np.array([p.center for p in pts])) + segmentation_noise((len(pts),), eb, px, rng)
        obs.points = {p.id: uv[i] for i, p in enumerate(pts)}
    for ln in features.lines:
        if not keep(ln.id):
            continue
        if as_coefficients:
            a, b = proj(np.array([ln.start, ln.end]))
            n = np.array([a[1] - b[1], b[0] - a[0]])
            obs.lines[ln.id] = CurveObservation(coefficients=np.array([n[0], n[1], -n @ a]))
            continue
        s = np.linspace(0.0, 1.0, contour.line)[:, None]
        P = ln.start + s * (ln.end - ln.start)
        obs.lines[ln.id] = CurveObservation(points=proj(P) + segmentation_noise((contour.line,), ew, px, rng))
    for el in features.ellipses:
        if not keep(el.id):
            continue
        if as_coefficients:
            C = projected_conic(el, camera, R[None], t[None])[0]
            obs.ellipses[el.id] = CurveObservation(coefficients=conic_vector(C))
            continue
        s = np.linspace(0.0, 2 * np.pi, contour.ellipse, endpoint=False)
        obs.ellipses[el.id] = CurveObservation(
            points=proj(el.sample(s)) + segmentation_noise((contour.ellipse,), ew, px, rng)
        )
    return obs


def projected_conic(el, camera: Camera | np.ndarray, R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Pixel conic matrices (B, 3, 3) of ellipse ``el`` seen at poses (B, 3, 3), (B, 3).

    The ellipse is the image of the unit circle under ``s ↦ c + a cos s u + b sin s v``; with
    the homography ``H = K [R a u | R b v | R c + t]`` its image conic is ``H⁻ᵀ diag(1, 1, −1) H⁻¹``.
    """
    intr = camera.intrinsics if isinstance(camera, Camera) else np.asarray(camera)
    intr = np.broadcast_to(intr, (R.shape[0], 4))
    Kmat = np.zeros((R.shape[0], 3, 3))
    Kmat[:, 0, 0], Kmat[:, 1, 1], Kmat[:, 0, 2], Kmat[:, 1, 2], Kmat[:, 2, 2] = (
        intr[:, 0],
        intr[:, 1],
        intr[:, 2],
        intr[:, 3],
        1.0,
    )
    cols = np.stack([R @ (el.semi_major * el.major_axis), R @ (el.semi_minor * el.minor_axis), R @ el.center + t], -1)
    Hinv = np.linalg.inv(Kmat @ cols)
    return np.swapaxes(Hinv, -1, -2) @ np.diag([1.0, 1.0, -1.0]) @ Hinv


def synthetic_problem(
    features: Features,
    camera: Camera | np.ndarray,
    R: np.ndarray,
    t: np.ndarray,
    noise: NoiseModel | None = None,
    contour: ContourSampling = ContourSampling(),
    ellipse_model_points: int = ELLIPSE_MODEL_POINTS,
    distance: str = "sampson",
    pixel_size_mm: float | None = None,
) -> Problem:
    """The solver's arrays for noise-free images of every feature at poses (B, 3, 3), (B, 3).

    Equal (to rounding) to what :func:`compile_problem` makes of
    :func:`simulate_observation` images with zero error, without fitting anything.
    ``camera`` is a :class:`Camera` or intrinsics (B, 4) ``fx, fy, ox, oy``; then
    ``pixel_size_mm`` converts the noise model to pixels.
    """
    from .problem import model_layout  # shared with compile_problem: one model-point layout

    noise = noise or NoiseModel()
    R = np.asarray(R, float).reshape(-1, 3, 3)
    t = np.asarray(t, float).reshape(-1, 3)
    Bn = R.shape[0]
    if isinstance(camera, Camera):
        intr = np.broadcast_to(camera.intrinsics, (Bn, 4)).copy()
        pix = float(np.mean(camera.pixel_size_mm))
    else:
        intr = np.broadcast_to(np.asarray(camera, float), (Bn, 4)).copy()
        if pixel_size_mm is None:
            raise ValueError("pixel_size_mm is needed when camera is given as intrinsics")
        pix = pixel_size_mm
    point_ids = [p.id for p in features.points]
    line_ids = [ln.id for ln in features.lines]
    ellipse_ids = [e.id for e in features.ellipses]
    # the solver sorts ids; do the same so rows line up
    point_ids, line_ids, ellipse_ids = sorted(point_ids), sorted(line_ids), sorted(ellipse_ids)
    K = ellipse_model_points
    X, _ = model_layout(features, point_ids, line_ids, ellipse_ids, K)

    project = partial(_project_batch, R, t, intr)
    pts = {p.id: p for p in features.points}
    P_ = len(point_ids)
    p_obs = project(np.array([pts[i].center for i in point_ids]).reshape(-1, 3)) if P_ else np.zeros((Bn, 0, 2))
    p_w = np.full((Bn, P_), pix / noise.point_mm)
    L, E = len(line_ids), len(ellipse_ids)
    l_n, l_m, l_info, l_sig = _synthetic_lines(features, line_ids, project, Bn, noise.line_mm / pix, contour.line)
    e_theta, e_m, e_s, e_basis, e_info, e_sig = _synthetic_ellipses(
        features, ellipse_ids, project, intr, R, t, noise.ellipse_mm / pix, contour.ellipse
    )
    e_kpaper = paper_k(e_theta) if E else np.zeros((Bn, 0))
    return Problem(
        intr,
        X,
        point_ids,
        line_ids,
        ellipse_ids,
        K,
        p_obs,
        p_w,
        l_n,
        l_m,
        np.zeros((Bn, L)),
        l_info,
        np.zeros(L, bool),
        l_sig,
        e_theta,
        e_m,
        e_s,
        e_basis,
        e_info,
        np.zeros(E, bool),
        e_sig,
        e_kpaper,
        distance,
        np.zeros(Bn),
        np.zeros(Bn),
        [],
        np.full(Bn, pix),
    )


def _project_batch(R: np.ndarray, t: np.ndarray, intr: np.ndarray, P: np.ndarray) -> np.ndarray:
    """Points ``P`` (…, 3) mm in F projected at every pose (B, 3, 3), (B, 3) with intrinsics
    ``intr`` (B, 4): (B, …, 2) px."""
    Bn = R.shape[0]
    Pc = np.einsum("bij,...j->b...i", R, P) + t.reshape((Bn,) + (1,) * (P.ndim - 1) + (3,))
    return np.stack(
        [
            intr[:, 0].reshape((Bn,) + (1,) * (P.ndim - 1)) * Pc[..., 0] / Pc[..., 2]
            + intr[:, 2].reshape((Bn,) + (1,) * (P.ndim - 1)),
            intr[:, 1].reshape((Bn,) + (1,) * (P.ndim - 1)) * Pc[..., 1] / Pc[..., 2]
            + intr[:, 3].reshape((Bn,) + (1,) * (P.ndim - 1)),
        ],
        -1,
    )


def _synthetic_lines(features: Features, line_ids: list[str], project, Bn: int, sigma_px: float, samples: int):
    """The lines' arrays of :func:`synthetic_problem` (normal, anchor, information, σ) for
    noise-free contours of ``samples`` points, noise ``sigma_px``."""
    lns = {ln.id: ln for ln in features.lines}
    L = len(line_ids)
    l_n, l_m, l_info = np.zeros((Bn, L, 2)), np.zeros((Bn, L, 2)), np.zeros((Bn, L, 2, 2))
    l_sig = np.full((Bn, L), sigma_px)
    if L:
        s = np.linspace(0.0, 1.0, samples)[:, None]
        P3 = np.stack([lns[i].start + s * (lns[i].end - lns[i].start) for i in line_ids])  # (L, n, 3)
        q = project(P3)  # (B, L, n, 2)
        d = q[..., -1, :] - q[..., 0, :]
        d /= np.linalg.norm(d, axis=-1, keepdims=True)
        l_n = np.stack([-d[..., 1], d[..., 0]], -1)
        l_m = q.mean(-2)
        along = np.einsum("blni,bli->bln", q - l_m[..., None, :], d)
        l_info[..., 0, 0] = np.sum(along**2, -1)
        l_info[..., 1, 1] = samples
        l_info /= l_sig[..., None, None] ** 2
    return l_n, l_m, l_info, l_sig


def _synthetic_ellipses(features: Features, ellipse_ids: list[str], project, intr, R, t, sigma_px: float, samples: int):
    """The ellipses' arrays of :func:`synthetic_problem` (conic, centre, scale, basis,
    information, σ) for noise-free contours of ``samples`` points, noise ``sigma_px``."""
    Bn = R.shape[0]
    els = {e.id: e for e in features.ellipses}
    E = len(ellipse_ids)
    e_theta, e_m, e_s = np.zeros((Bn, E, 6)), np.zeros((Bn, E, 2)), np.ones((Bn, E))
    e_basis, e_info = np.zeros((Bn, E, 6, 5)), np.zeros((Bn, E, 5, 5))
    e_sig = np.full((Bn, E), sigma_px)
    sj = np.linspace(0.0, 2 * np.pi, samples, endpoint=False)
    for j, fid in enumerate(ellipse_ids):
        el = els[fid]
        q = project(el.sample(sj))  # (B, n, 2)
        m, sc = normalisation(q, np.ones(q.shape[:-1]))
        C = projected_conic(el, intr, R, t)
        N = np.zeros((Bn, 3, 3))
        N[:, 0, 0] = N[:, 1, 1] = sc
        N[:, :2, 2] = m
        N[:, 2, 2] = 1.0
        th = conic_vector(np.swapaxes(N, -1, -2) @ C @ N)
        th /= np.linalg.norm(th, axis=-1, keepdims=True)
        basis = tangent_basis(th)
        qn = (q - m[:, None, :]) / sc[:, None, None]
        _, dd = sampson_theta_jacobian(th, qn[..., 0], qn[..., 1])
        G = dd @ basis
        e_theta[:, j], e_m[:, j], e_s[:, j], e_basis[:, j] = th, m, sc, basis
        e_info[:, j] = np.einsum("bni,bnj->bij", G, G) * (sc * sc / e_sig[:, j] ** 2)[:, None, None]
    return e_theta, e_m, e_s, e_basis, e_info, e_sig


def pose_errors(R_est: np.ndarray, t_est: np.ndarray, R_true: np.ndarray, t_true: np.ndarray):
    """Rotation error vectors (…, 3) rad — ``log(R_est R_trueᵀ)``, left, camera axes — and
    translation errors (…, 3) mm, camera axes."""
    return so3.log(R_est @ np.swapaxes(R_true, -1, -2)), t_est - t_true


def carm_sweep(
    R0: np.ndarray,
    t0: np.ndarray,
    n: int,
    swing_deg: float = 20.0,
    period_frames: float = 120.0,
    tilt_deg: float = 6.0,
    tilt_period_frames: float = 77.0,
    isocentre_offset_mm: float = 100.0,
    drift_mm: tuple[float, float, float] = (8.0, 5.0, 4.0),
) -> tuple[np.ndarray, np.ndarray]:
    """Poses of a fiducial fixed to the patient through a run of a C-arm swinging about its
    isocentre: frame k sees the fiducial at ``Q_k (X₀ − c) + c + d_k`` (camera frame X),
    Q_k the C-arm's rotation and c the isocentre on the principal ray.

    The C-arm swings back and forth about the camera's x axis by ``swing_deg`` sin(2πk /
    ``period_frames``) and tilts about its y axis by ``tilt_deg`` sin(2πk /
    ``tilt_period_frames``); the table drifts by ``drift_mm`` × sin(2πk / (1.7 ·
    ``period_frames``)) per axis. Every motion is smooth, its speed changes from frame to
    frame (a constant-velocity prediction is not exact), and its largest step is about
    2π ``swing_deg`` / ``period_frames`` degrees per frame.

    Parameters
    ----------
    R0, t0 : the pose F → X at frame 0 (rotation (3, 3), translation (3,) mm).
    n : number of frames.
    swing_deg, period_frames, tilt_deg, tilt_period_frames : the C-arm's two rotations'
        amplitudes (degrees, at this edge only) and periods (frames).
    isocentre_offset_mm : how much farther from the source than the fiducial origin the
        isocentre lies on the principal ray (mm): the fiducial then moves by about this
        times the swing's angular step per frame.
    drift_mm : the table's drift amplitude per camera axis (mm).

    Returns
    -------
    R (n, 3, 3), t (n, 3) mm.
    """
    R0, t0 = np.asarray(R0, float), np.asarray(t0, float)
    c = np.array([0.0, 0.0, float(t0[2]) + float(isocentre_offset_mm)])
    k = np.arange(n, dtype=float)
    a = np.radians(swing_deg) * np.sin(2 * np.pi * k / period_frames)
    b = np.radians(tilt_deg) * np.sin(2 * np.pi * k / tilt_period_frames)
    Q = so3.exp(np.stack([a, np.zeros(n), np.zeros(n)], -1)) @ so3.exp(np.stack([np.zeros(n), b, np.zeros(n)], -1))
    drift = np.asarray(drift_mm, float)[None] * np.sin(2 * np.pi * k / (1.7 * period_frames))[:, None]
    R = Q @ R0
    t = np.einsum("nij,j->ni", Q, t0 - c) + c + drift
    return R, t
