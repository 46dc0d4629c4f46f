"""Batched Fisher information of the pose, per feature, from the solver's own Jacobian.

For a noise-free image at pose (R, t), every observation the solver uses is a set of image
points with independent noise of σ pixels per axis (SPEC §3: beads, and contour points on
the wires). A bead informs the pose through both pixel coordinates; a contour point only
through its displacement along the curve's normal — sliding along the curve changes
nothing the curve fit sees. The information of feature f is therefore

    I_f = Σ_rows aᵀa,   a = (nᵀ ∂q/∂(δ, t)) / σ,

with n = (1, 0) and (0, 1) for a bead and the image normal of the projected curve at each
contour sample otherwise. The rows come from the solver's closed-form Jacobian
(:func:`ftrac_design.pose.problem.jacobian_rows`, paper Eqs. 10–13: left rotation
increment δ rad about the fiducial origin and translation t mm, both in camera axes). For
the solver's Gauss–Markov whitened residuals this is exactly JᵀJ at the true pose (the
curve fit's information mapped through the curve's dependence on the pose; tested against
:func:`ftrac_design.pose.problem.evaluate` on :func:`ftrac_design.pose.simulate.synthetic_problem`),
so (Σ_f I_f)⁻¹ is the Cramér–Rao bound the solver attains (measured efficiency ≈ 1,
``benchmarks/pose_accuracy.py``).

Contour sampling (how many segmented points per curve) follows
:class:`ftrac_design.pose.simulate.ContourSampling`, the same as the simulator's images.
numpy only; poses are processed in chunks so 50,000 poses fit in a few tens of MB.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..features.model import Features
from ..pose.camera import Camera
from ..pose.problem import NoiseModel, jacobian_rows, project_points
from ..pose.simulate import ContourSampling

#: rows per solver residual group: a bead has 2, a line 2 (its two parameters), an
#: ellipse 5 (a conic up to scale) — ``m`` of the observability indices
SOLVER_ROWS = {"point": 2, "line": 2, "ellipse": 5}
#: rank of one feature's own information when it is seen properly (the constraints it
#: puts on the pose): the same numbers
FEATURE_RANK = SOLVER_ROWS

CHUNK = 4096


@dataclass(frozen=True)
class FeatureLayout:
    """The features of a design in analysis order (points, lines, ellipses; sorted ids
    within a kind, as the solver orders them) and one entry per Jacobian row: each bead
    twice (its u and v rows), then every contour sample of the lines and the ellipses."""

    ids: tuple[str, ...]
    kinds: tuple[str, ...]
    X: np.ndarray  # (n, 3) mm in F: the model point of each row
    T: np.ndarray  # (n, 3) unit tangent in F at each contour sample (0 for beads)
    owner: np.ndarray  # (n,) index into ids of the feature each row belongs to
    n_points: int
    bounds: np.ndarray  # (F + 1,) rows of feature f are bounds[f]:bounds[f + 1]

    @property
    def solver_rows(self) -> int:
        """Whitened residual rows of the solver's Jacobian for the whole design."""
        return sum(SOLVER_ROWS[k] for k in self.kinds)

    def index(self, fid: str) -> int:
        """Position of feature ``fid`` in :attr:`ids`."""
        return self.ids.index(fid)


def feature_layout(features: Features, contour: ContourSampling = ContourSampling()) -> FeatureLayout:
    """Sample every feature of ``features`` as the simulator's images do (see module doc)."""
    ids, kinds, X, T, owner = [], [], [], [], []
    for p in sorted(features.points, key=lambda f: f.id):
        owner += [len(ids)] * 2
        ids.append(p.id)
        kinds.append("point")
        X.append(np.stack([p.center, p.center]))
        T.append(np.zeros((2, 3)))
    s = np.linspace(0.0, 1.0, contour.line)
    for ln in sorted(features.lines, key=lambda f: f.id):
        owner += [len(ids)] * contour.line
        ids.append(ln.id)
        kinds.append("line")
        X.append(ln.sample(s))
        T.append(np.broadcast_to(ln.direction, (contour.line, 3)))
    s = np.linspace(0.0, 2 * np.pi, contour.ellipse, endpoint=False)
    for el in sorted(features.ellipses, key=lambda f: f.id):
        owner += [len(ids)] * contour.ellipse
        ids.append(el.id)
        kinds.append("ellipse")
        X.append(el.sample(s))
        T.append(el.tangent(s))
    if not ids:
        raise ValueError(f"{features.name} has no features to analyse")
    owner = np.asarray(owner)
    bounds = np.searchsorted(owner, np.arange(len(ids) + 1))
    return FeatureLayout(
        tuple(ids),
        tuple(kinds),
        np.concatenate(X).astype(float),
        np.concatenate(T).astype(float),
        owner,
        len(features.points),
        bounds,
    )


def _intrinsics(camera: Camera | np.ndarray, B: int) -> np.ndarray:
    intr = camera.intrinsics if isinstance(camera, Camera) else np.asarray(camera, float)
    return np.broadcast_to(intr, (B, 4))


def _sigmas_px(layout: FeatureLayout, camera: Camera, noise: NoiseModel) -> np.ndarray:
    pix = float(np.mean(camera.pixel_size_mm))
    by_kind = {"point": noise.point_mm, "line": noise.line_mm, "ellipse": noise.ellipse_mm}
    return np.array([by_kind[k] / pix for k in layout.kinds])


def whitened_rows(
    layout: FeatureLayout,
    camera: Camera,
    R: np.ndarray,
    t: np.ndarray,
    noise: NoiseModel = NoiseModel(),
    columns: bool = False,
) -> np.ndarray:
    """Rows a (B, n, 6) of the whitened Jacobian at poses (B, 3, 3), (B, 3), one per
    :class:`FeatureLayout` row — per bead two (u, v), per contour sample one (its normal).

    Columns: δ (rad, left rotation about the fiducial origin, camera axes), t (mm, camera
    axes); rows in units of 1/σ. ``columns=True`` returns the transpose (B, 6, n).
    """
    R = np.asarray(R, float).reshape(-1, 3, 3)
    t = np.asarray(t, float).reshape(-1, 3)
    B, P2 = R.shape[0], 2 * layout.n_points
    _, Z, pr = project_points(layout.X, _intrinsics(camera, B), R, t)
    _, x, y, fxz, fyz = pr
    # image tangent of each contour sample: ∂(u, v)/∂P_X applied to the rotated 3-D tangent
    RT = (R.reshape(3 * B, 3) @ layout.T[P2:].T).reshape(B, 3, -1)  # (B, 3, n-P2)
    du = fxz[:, P2:] * (RT[:, 0] - x[:, P2:] * RT[:, 2])
    dv = fyz[:, P2:] * (RT[:, 1] - y[:, P2:] * RT[:, 2])
    norm = np.hypot(du, dv)
    # an exactly end-on line or an ellipse's turning point seen edge-on has no image
    # tangent; such a sample's normal is undefined and it is given no weight
    w = 1.0 / _sigmas_px(layout, camera, noise)[layout.owner]
    with np.errstate(divide="ignore", invalid="ignore"):
        k = np.where(norm > 1e-12 * fxz[:, P2:], w[P2:] / norm, 0.0)
    cu = np.empty(x.shape)
    cv = np.empty(x.shape)
    cu[:, :P2] = np.tile([1.0, 0.0], layout.n_points) * w[:P2]
    cv[:, :P2] = np.tile([0.0, 1.0], layout.n_points) * w[:P2]
    cu[:, P2:] = -dv * k
    cv[:, P2:] = du * k
    # every row has its own model point, so no gather is needed
    return jacobian_rows(pr, slice(None), cu, cv, columns)


def total_information(
    layout: FeatureLayout,
    camera: Camera,
    R: np.ndarray,
    t: np.ndarray,
    noise: NoiseModel = NoiseModel(),
    chunk: int = CHUNK,
) -> np.ndarray:
    """Fisher information (B, 6, 6) of the whole design: the fast path, JᵀJ in one product."""
    R = np.asarray(R, float).reshape(-1, 3, 3)
    t = np.asarray(t, float).reshape(-1, 3)
    out = np.empty((R.shape[0], 6, 6))
    for a in range(0, R.shape[0], chunk):
        b = min(R.shape[0], a + chunk)
        cols = whitened_rows(layout, camera, R[a:b], t[a:b], noise, columns=True)
        out[a:b] = cols @ np.swapaxes(cols, 1, 2)
    return out


def feature_information(
    layout: FeatureLayout,
    camera: Camera,
    R: np.ndarray,
    t: np.ndarray,
    noise: NoiseModel = NoiseModel(),
    chunk: int = CHUNK,
) -> np.ndarray:
    """Fisher information (B, F, 6, 6) of each feature at poses (B, 3, 3), (B, 3).

    Unscaled: rotation in rad, translation in mm, camera axes; ``Σ_f`` of it is the
    solver's JᵀJ at the true pose and its inverse the Cramér–Rao bound.
    """
    R = np.asarray(R, float).reshape(-1, 3, 3)
    t = np.asarray(t, float).reshape(-1, 3)
    B, F = R.shape[0], len(layout.ids)
    out = np.empty((B, F, 6, 6))
    bd = layout.bounds
    for a in range(0, B, chunk):
        b = min(B, a + chunk)
        cols = whitened_rows(layout, camera, R[a:b], t[a:b], noise, columns=True)
        for f in range(F):
            c = cols[:, :, bd[f] : bd[f + 1]]
            out[a:b, f] = c @ np.swapaxes(c, 1, 2)
    return out
