"""Image-intensifier distortion: a 2-D polynomial from ideal (pinhole) pixels to the pixels
as imaged, its inverse, image resampling both ways and the ``ftrac-distortion`` JSON file.

**Model.** Pixel coordinates are those of the image's own grid: ``u`` the column, ``v`` the
row, the centre of pixel (row i, column j) at (u, v) = (j, i) (SPEC §1, the grid the
principal point is given in). With a centre ``c`` and a scale ``s`` (px, stored in the model)

    x = (u − c_u) / s,   y = (v − c_v) / s
    u_d = c_u + s Σ_k a_k x^i y^j,   v_d = c_v + s Σ_k b_k x^i y^j,   i + j ≤ degree,

mapping the **ideal** pixel (u, v), where a pinhole camera (SPEC §1) would image a point, to
the **distorted** pixel (u_d, v_d), where the intensifier shows it. Terms are ordered by total
degree, then by falling power of x: 1, x, y, x², xy, y², x³, x²y, … (:func:`monomial_exponents`).
The forward map is exact; the inverse (:meth:`DistortionModel.undistort`) is Newton's method.

**Degree 5** (the default). Global polynomials are the usual model of X-ray image-intensifier
distortion (Cerveri et al., Med. Biol. Eng. Comput. 41:151, 2003: "global polynomial methods
have been widely used" for 30–40 cm intensifiers), and fifth order is the degree the C-arm
literature settles on: Liu, Rudin & Bednarek (Med. Phys. 26:1802, 1999) left 0.20 px RMS
with fifth-order single-plane global corrections on a 9-inch intensifier. Both physical
components have their leading terms within degree 5: pincushion from the curved input
phosphor is radial, Δ ∝ r³ + r⁵, and the S-distortion from the earth's and the room's
magnetic fields is a rotation growing with radius, whose displacement is ∝ r³, r⁵ as well.
"""

from __future__ import annotations

import functools
import json
import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Literal

import cv2
import numpy as np

from ..errors import InputError
from ..fileio import atomic_file, parse_json, read_text_input

FORMAT = "ftrac-distortion"
VERSION = 1
MODEL = "polynomial-2d"
DIRECTION = "ideal_to_distorted"
#: highest degree a file may state (degree 10 has 66 terms per axis; beyond it the
#: monomial basis is too ill-conditioned on an image to be worth storing)
MAX_DEGREE = 10

Interpolation = Literal["linear", "cubic"]
#: which way a frame is resampled: onto the ideal pinhole grid, or back onto the imaged one
Direction = Literal["undistort", "distort"]


def monomial_exponents(degree: int) -> np.ndarray:
    """Exponents (n, 2) = (i, j) of the terms x^i y^j of a 2-D polynomial of ``degree``, in
    the model's order: by total degree, then by falling power of x; n = (d+1)(d+2)/2."""
    return np.array([(k - j, j) for k in range(degree + 1) for j in range(k + 1)], int)


def n_terms(degree: int) -> int:
    """Number of monomials of total degree ≤ ``degree`` in two variables."""
    return (degree + 1) * (degree + 2) // 2


def identity_coefficients(degree: int) -> tuple[np.ndarray, np.ndarray]:
    """Coefficients (a, b) of the identity map: a has 1 on x, b has 1 on y."""
    a, b = np.zeros(n_terms(degree)), np.zeros(n_terms(degree))
    if degree >= 1:
        a[1], b[2] = 1.0, 1.0
    return a, b


def _powers(x: np.ndarray, degree: int) -> list[np.ndarray]:
    p = [np.ones_like(x)]
    for _ in range(degree):
        p.append(p[-1] * x)
    return p


def evaluate_polynomial(coef: np.ndarray, x: np.ndarray, y: np.ndarray, degree: int, derivatives: bool = False):
    """Σ coef_k x^i y^j (and, with ``derivatives``, its x and y derivatives) at arrays x, y
    of one shape; ``coef`` (n_terms, m) gives m polynomials at once (result (..., m))."""
    coef = np.asarray(coef, float)
    px, py = _powers(x, degree), _powers(y, degree)
    shape = x.shape + coef.shape[1:]
    val = np.zeros(shape)
    dx = np.zeros(shape) if derivatives else None
    dy = np.zeros(shape) if derivatives else None
    for k, (i, j) in enumerate(monomial_exponents(degree)):
        c = coef[k]
        if not np.any(c):
            continue
        m = px[i] * py[j]
        val += m[..., None] * c if coef.ndim == 2 else m * c
        if derivatives:
            if i:
                t = i * px[i - 1] * py[j]
                dx += t[..., None] * c if coef.ndim == 2 else t * c
            if j:
                t = j * px[i] * py[j - 1]
                dy += t[..., None] * c if coef.ndim == 2 else t * c
    return (val, dx, dy) if derivatives else val


def design_matrix(x: np.ndarray, y: np.ndarray, degree: int) -> np.ndarray:
    """Monomials (n, n_terms) at points x, y (n,), in the model's order."""
    px, py = _powers(np.asarray(x, float), degree), _powers(np.asarray(y, float), degree)
    return np.stack([px[i] * py[j] for i, j in monomial_exponents(degree)], -1)


@dataclass(frozen=True)
class DistortionModel:
    """Ideal (pinhole) pixel → distorted (as imaged) pixel, a 2-D polynomial (see the module).

    - ``degree``: total degree of the polynomial.
    - ``image_shape``: (H, W) of the images it applies to, pixels.
    - ``centre_px``: (c_u, c_v), the centre of the normalised coordinates, px.
    - ``scale_px``: s, the length (px) that normalises the coordinates.
    - ``coefficients_u``, ``coefficients_v``: the n_terms coefficients of u_d and v_d (in
      normalised units; the identity has 1 on x in u and 1 on y in v).
    - ``rms_residual_px``, ``max_residual_px``: how well the polynomial matched what it was
      fitted to (0 when it is exact).
    - ``source``: how the model was made (free text).
    - ``support_radius_px``: the model was fitted on data within this distance of the centre
      (None: over the whole image); beyond it the polynomial is an extrapolation.
    """

    degree: int
    image_shape: tuple[int, int]
    centre_px: tuple[float, float]
    scale_px: float
    coefficients_u: tuple[float, ...]
    coefficients_v: tuple[float, ...]
    rms_residual_px: float = 0.0
    max_residual_px: float = 0.0
    source: str = ""
    support_radius_px: float | None = None
    _coef: np.ndarray = field(init=False, repr=False, compare=False, hash=False)

    def __post_init__(self) -> None:
        d = int(self.degree)
        if d != self.degree or not 1 <= d <= MAX_DEGREE:
            raise ValueError(f"degree: an integer 1–{MAX_DEGREE}, got {self.degree!r}")
        H, W = (int(v) for v in self.image_shape)
        if (H, W) != tuple(self.image_shape) or H < 2 or W < 2:
            raise ValueError(f"image_shape: two integers ≥ 2, got {self.image_shape!r}")
        a = np.asarray(self.coefficients_u, float)
        b = np.asarray(self.coefficients_v, float)
        if a.shape != (n_terms(d),) or b.shape != (n_terms(d),):
            raise ValueError(f"coefficients: {n_terms(d)} numbers per axis for degree {d}")
        if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b)) and np.all(np.isfinite(self.centre_px))):
            raise ValueError("coefficients, centre_px: finite numbers")
        if not (math.isfinite(self.scale_px) and self.scale_px > 0):
            raise ValueError(f"scale_px: a positive number, got {self.scale_px!r}")
        object.__setattr__(self, "degree", d)
        object.__setattr__(self, "image_shape", (H, W))
        object.__setattr__(self, "centre_px", tuple(float(c) for c in self.centre_px))
        object.__setattr__(self, "scale_px", float(self.scale_px))
        object.__setattr__(self, "coefficients_u", tuple(float(c) for c in a))
        object.__setattr__(self, "coefficients_v", tuple(float(c) for c in b))
        object.__setattr__(self, "_coef", np.stack([a, b], -1))

    # -- construction -------------------------------------------------------------------

    @classmethod
    def identity(
        cls,
        shape: tuple[int, int],
        degree: int = 5,
        centre: tuple[float, float] | None = None,
        scale: float | None = None,
    ) -> "DistortionModel":
        """The map that moves nothing, in the default normalisation of an image of ``shape``
        (centre: the image centre ((W − 1)/2, (H − 1)/2); scale: max(H, W)/2)."""
        c, s = default_normalisation(shape, centre, scale)
        a, b = identity_coefficients(degree)
        return cls(degree, tuple(shape), c, s, tuple(a), tuple(b), source="identity")

    def with_coefficients(self, a: np.ndarray, b: np.ndarray, **changes: Any) -> "DistortionModel":
        """A copy with new coefficients (and any other field changed)."""
        return replace(
            self, coefficients_u=tuple(np.asarray(a, float)), coefficients_v=tuple(np.asarray(b, float)), **changes
        )

    # -- the maps -----------------------------------------------------------------------

    def normalise(self, uv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Normalised (x, y) of pixels ``uv`` (..., 2)."""
        uv = np.asarray(uv, float)
        return (uv[..., 0] - self.centre_px[0]) / self.scale_px, (uv[..., 1] - self.centre_px[1]) / self.scale_px

    def distort(self, uv: np.ndarray) -> np.ndarray:
        """Distorted pixels (..., 2) of ideal pixels ``uv`` (..., 2) — exact."""
        x, y = self.normalise(uv)
        p = evaluate_polynomial(self._coef, x, y, self.degree)
        return np.asarray(self.centre_px) + self.scale_px * p

    def jacobian(self, uv: np.ndarray) -> np.ndarray:
        """∂(u_d, v_d)/∂(u, v) (..., 2, 2) at ideal pixels ``uv``: rows u_d, v_d; columns u, v."""
        x, y = self.normalise(uv)
        _, dx, dy = evaluate_polynomial(self._coef, x, y, self.degree, derivatives=True)
        return np.stack([dx, dy], -1)

    def displacement(self, uv: np.ndarray) -> np.ndarray:
        """distort(uv) − uv, px (..., 2)."""
        return self.distort(uv) - np.asarray(uv, float)

    def undistort(self, uv: np.ndarray, tol_px: float = 1e-6, max_iter: int = 30) -> np.ndarray:
        """Ideal pixels (..., 2) whose distorted image is ``uv`` (..., 2): Newton's method on
        distort(p) = uv, stopped when |distort(p) − uv| ≤ ``tol_px`` on both axes.

        Refuses rather than raises: NaN where the iteration does not converge within
        ``max_iter`` steps, where the map folds (Jacobian determinant ≤ 0 at the answer)
        and where ``uv`` is not finite.
        """
        q = np.asarray(uv, float)
        shape = q.shape
        q = q.reshape(-1, 2)
        # first-order inverse as the start: p = q − Δ(q)
        p = q - self.displacement(q)
        out = np.full_like(q, np.nan)
        active = np.flatnonzero(np.all(np.isfinite(q), axis=1))
        for _ in range(max_iter + 1):
            if len(active) == 0:
                break
            pa, qa = p[active], q[active]
            x, y = self.normalise(pa)
            val, dx, dy = evaluate_polynomial(self._coef, x, y, self.degree, derivatives=True)
            r = np.asarray(self.centre_px) + self.scale_px * val - qa  # px
            det = dx[:, 0] * dy[:, 1] - dy[:, 0] * dx[:, 1]
            done = np.all(np.abs(r) <= tol_px, axis=1) | ~np.all(np.isfinite(r), axis=1)
            good = done & (det > 0) & np.all(np.isfinite(r), axis=1)
            out[active[good]] = pa[good]
            keep = ~done & (det > 0)
            active, pa, r, dx, dy, det = active[keep], pa[keep], r[keep], dx[keep], dy[keep], det[keep]
            # Newton step: J (in px per px) = [[dx_u, dy_u], [dx_v, dy_v]] (the scales cancel)
            du = (dy[:, 1] * r[:, 0] - dy[:, 0] * r[:, 1]) / det
            dv = (-dx[:, 1] * r[:, 0] + dx[:, 0] * r[:, 1]) / det
            p[active] = pa - np.stack([du, dv], -1)
        return out.reshape(shape)

    # -- summaries ----------------------------------------------------------------------

    def pixel_grid(self, step_px: int = 8) -> np.ndarray:
        """Pixel centres (n, 2) every ``step_px`` over the image (edges included), restricted
        to the support disc when the model has one."""
        H, W = self.image_shape
        us = np.unique(np.r_[np.arange(0, W, step_px), W - 1]).astype(float)
        vs = np.unique(np.r_[np.arange(0, H, step_px), H - 1]).astype(float)
        g = np.stack(np.meshgrid(us, vs), -1).reshape(-1, 2)
        if self.support_radius_px is not None:
            g = g[np.hypot(*(g - np.asarray(self.centre_px)).T) <= self.support_radius_px]
        return g

    @functools.cached_property
    def max_displacement_px(self) -> float:
        """Largest |distort(p) − p| (px) over the image's pixels (sampled every 4 px and at the
        edges; within the support disc when the model has one)."""
        g = self.pixel_grid(4)
        return float(np.max(np.hypot(*self.displacement(g).T))) if len(g) else 0.0

    # -- files --------------------------------------------------------------------------

    def to_dict(self) -> dict[str, Any]:
        """The ``ftrac-distortion`` JSON object (see :func:`write_distortion`)."""
        d = {
            "format": FORMAT,
            "version": VERSION,
            "model": MODEL,
            "degree": self.degree,
            "image_shape": list(self.image_shape),
            "centre_px": list(self.centre_px),
            "scale_px": self.scale_px,
            "coefficients_u": list(self.coefficients_u),
            "coefficients_v": list(self.coefficients_v),
            "direction": DIRECTION,
            "rms_residual_px": self.rms_residual_px,
            "max_residual_px": self.max_residual_px,
            "source": self.source,
            "max_displacement_px": self.max_displacement_px,
        }
        if self.support_radius_px is not None:
            d["support_radius_px"] = self.support_radius_px
        return d

    @classmethod
    def from_dict(cls, d: Any, origin: str | Path = "<distortion>") -> "DistortionModel":
        """Validate a parsed ``ftrac-distortion`` object; InputError(origin, key, expected)."""
        return _model_from_dict(d, origin)


def default_normalisation(
    shape: tuple[int, int], centre: tuple[float, float] | None = None, scale: float | None = None
) -> tuple[tuple[float, float], float]:
    """(centre, scale) px: the image centre ((W − 1)/2, (H − 1)/2) and max(H, W)/2 unless given."""
    H, W = shape
    c = ((W - 1) / 2.0, (H - 1) / 2.0) if centre is None else (float(centre[0]), float(centre[1]))
    return c, float(max(H, W) / 2.0 if scale is None else scale)


# -- factories (tests, simulation) ------------------------------------------------------


def radial(
    shape: tuple[int, int],
    k_mm_at_r: tuple[float, float] = (2.0, 100.0),
    pixel_mm: float = 0.44,
    centre: tuple[float, float] | None = None,
    degree: int = 5,
) -> DistortionModel:
    """Pincushion (k > 0) or barrel (k < 0) distortion: every point moves radially away from
    ``centre`` (px; default the image centre) by ``k (r / r₀)³`` mm, with ``(k, r₀) =
    k_mm_at_r`` in mm at the detector and r its distance from the centre; ``pixel_mm`` the
    pixel pitch. Exact in the polynomial (a cubic), so ``degree`` ≥ 3.
    """
    k, r0 = (float(v) for v in k_mm_at_r)
    if degree < 3:
        raise ValueError("radial: degree ≥ 3 (the displacement is cubic)")
    if not (r0 > 0 and pixel_mm > 0 and math.isfinite(k)):
        raise ValueError("radial: a finite k, a positive r and pixel_mm")
    c, s = default_normalisation(shape, centre)
    # displacement (px) = (k / pixel) (r_px pixel / r0)³ = alpha r_px³, so p_d = p (1 + alpha r_px²)
    alpha = (k / pixel_mm) * (pixel_mm / r0) ** 3
    a, b = identity_coefficients(degree)
    e = [tuple(t) for t in monomial_exponents(degree)]
    g = alpha * s * s
    a[e.index((3, 0))] = a[e.index((1, 2))] = g  # x (x² + y²)
    b[e.index((2, 1))] = b[e.index((0, 3))] = g  # y (x² + y²)
    return DistortionModel(
        degree,
        tuple(shape),
        c,
        s,
        tuple(a),
        tuple(b),
        source=f"radial: {k:g} mm at r = {r0:g} mm, pixel {pixel_mm:g} mm",
    )


def s_distortion(
    shape: tuple[int, int],
    amplitude_px: float,
    *,
    radius_px: float | None = None,
    centre: tuple[float, float] | None = None,
    degree: int = 5,
    step_px: int = 4,
) -> DistortionModel:
    """S-distortion: a rotation about ``centre`` (px; default the image centre) by an angle that
    grows with the square of the radius, θ(r) = (a / R)(r / R)², so that a point at
    ``radius_px`` = R (default min(H, W)/2) moves ``amplitude_px`` = a along the circle (positive:
    from +u toward +v) and a straight line through the centre images as an S.

    The rotation is not a polynomial: its degree-≥ 3 part is fitted by dense least squares (every
    ``step_px`` over the image) with the linear part held at the identity (θ and dθ/dr vanish at
    the centre); the fit's RMS and max error over those samples are the model's residuals.
    """
    if degree < 3:
        raise ValueError("s_distortion: degree ≥ 3 (the leading displacement is cubic)")
    H, W = shape
    R = float(min(H, W) / 2.0 if radius_px is None else radius_px)
    if not (R > 0 and math.isfinite(amplitude_px)):
        raise ValueError("s_distortion: a finite amplitude and a positive radius")
    model = DistortionModel.identity(shape, degree, centre)
    c = np.asarray(model.centre_px)
    g = model.pixel_grid(step_px) - c
    r2 = (g**2).sum(1)
    th = (amplitude_px / R) * r2 / (R * R)
    cs, sn = np.cos(th), np.sin(th)
    target = np.stack([cs * g[:, 0] - sn * g[:, 1], sn * g[:, 0] + cs * g[:, 1]], -1)
    model = fit_displacement(model, g + c, target + c)
    return replace(model, source=f"s-distortion: {amplitude_px:g} px at r = {R:g} px (least squares, degree {degree})")


def fit_displacement(
    model: DistortionModel, ideal_px: np.ndarray, distorted_px: np.ndarray, min_degree: int = 2
) -> DistortionModel:
    """``model`` with its terms of degree ≥ ``min_degree`` fitted by least squares so that
    distort(ideal) ≈ distorted (both (n, 2) px), its lower terms kept; the residuals (px) are
    stored as the model's RMS and max."""
    ideal_px, distorted_px = np.asarray(ideal_px, float), np.asarray(distorted_px, float)
    x, y = model.normalise(ideal_px)
    A = design_matrix(x, y, model.degree)
    low = monomial_exponents(model.degree).sum(1) < min_degree
    coef = model._coef.copy()
    target = (distorted_px - np.asarray(model.centre_px)) / model.scale_px - A[:, low] @ coef[low]
    sol, *_ = np.linalg.lstsq(A[:, ~low], target, rcond=None)
    coef[~low] = sol
    res = model.scale_px * (A @ coef) + np.asarray(model.centre_px) - distorted_px
    err = np.hypot(res[:, 0], res[:, 1])
    return model.with_coefficients(
        coef[:, 0], coef[:, 1], rms_residual_px=float(np.sqrt(np.mean(err**2))), max_residual_px=float(err.max())
    )


def combine(*models: DistortionModel) -> DistortionModel:
    """The model whose displacement is the sum of the models' displacements (same image shape,
    centre, scale and degree); for small distortions, close to applying one after another.
    Residuals add (RMS in quadrature)."""
    if not models:
        raise ValueError("combine: at least one model")
    m0 = models[0]
    for m in models[1:]:
        if (m.image_shape, m.centre_px, m.scale_px, m.degree) != (m0.image_shape, m0.centre_px, m0.scale_px, m0.degree):
            raise ValueError("combine: models with one image shape, centre, scale and degree")
    ident = np.stack(identity_coefficients(m0.degree), -1)
    coef = ident + sum(m._coef - ident for m in models)
    return m0.with_coefficients(
        coef[:, 0],
        coef[:, 1],
        rms_residual_px=float(np.sqrt(sum(m.rms_residual_px**2 for m in models))),
        max_residual_px=float(sum(m.max_residual_px for m in models)),
        source=" + ".join(m.source for m in models),
        support_radius_px=None,
    )


# -- images -----------------------------------------------------------------------------


#: the pixel maps are a polynomial (or its inverse), smooth over a few pixels: evaluated every
#: MAP_STEP px and interpolated bilinearly between, within 0.005 px of evaluating every pixel
#: for a strong intensifier (2.5 mm pincushion at 100 mm plus a 3 px S-distortion, to the
#: image's corners), at a sixteenth of the cost (~240 → ~15 ms for 1024²)
MAP_STEP = 4


@functools.lru_cache(maxsize=4)
def _maps(model: DistortionModel, direction: Direction) -> tuple[np.ndarray, np.ndarray]:
    """cv2.remap maps (float32, H × W) giving, for each output pixel, where to read the input.

    undistort: the output is on the ideal grid, read at distort(p); distort: the output is on
    the distorted grid, read at undistort(q); where Newton refuses, the pixel reads itself.
    Interpolated between samples every :data:`MAP_STEP` px where every sample is finite;
    evaluated at every pixel otherwise (:func:`exact_maps`)."""
    H, W = model.image_shape
    s = MAP_STEP
    # samples one step beyond every edge, placed where cv2.resize's pixel-centre convention
    # reads them: output column x of w samples resized to s·w columns reads sample
    # (x + ½)/s − ½, which at sample j = (u + s + ½)/s − ½ is pixel u
    h, w = -(-H // s) + 2, -(-W // s) + 2
    us = (np.arange(w) + 0.5) * s - 0.5 - s
    vs = (np.arange(h) + 0.5) * s - 0.5 - s
    p = np.stack(np.meshgrid(us, vs), -1)
    src = model.distort(p) if direction == "undistort" else model.undistort(p)
    if not np.all(np.isfinite(src)):
        return exact_maps(model, direction)
    maps = []
    for k in range(2):
        full = cv2.resize(np.ascontiguousarray(src[..., k]), (w * s, h * s), interpolation=cv2.INTER_LINEAR)
        m = np.ascontiguousarray(full[s : s + H, s : s + W], dtype=np.float32)
        m.setflags(write=False)
        maps.append(m)
    return maps[0], maps[1]


def exact_maps(model: DistortionModel, direction: Direction) -> tuple[np.ndarray, np.ndarray]:
    """The maps of :func:`_maps` evaluated at every pixel (float32, H × W)."""
    H, W = model.image_shape
    mx = np.empty((H, W), np.float32)
    my = np.empty((H, W), np.float32)
    us = np.arange(W, dtype=float)
    rows = max(1, 262144 // W)  # ~2¹⁸ points per chunk
    for r0 in range(0, H, rows):
        vs = np.arange(r0, min(H, r0 + rows), dtype=float)
        p = np.stack(np.meshgrid(us, vs), -1)
        src = model.distort(p) if direction == "undistort" else model.undistort(p)
        src = np.where(np.isfinite(src), src, p)
        mx[r0 : r0 + len(vs)] = src[..., 0]
        my[r0 : r0 + len(vs)] = src[..., 1]
    mx.setflags(write=False)
    my.setflags(write=False)
    return mx, my


def _remap(
    image: np.ndarray, model: DistortionModel, direction: Direction, interpolation: Interpolation, fill: float | None
) -> np.ndarray:
    img = np.asarray(image)
    if img.ndim != 2 or img.shape != model.image_shape:
        raise InputError(
            None, "image", f"an image of shape {model.image_shape} (the distortion model's), got {img.shape}"
        )
    if interpolation not in ("linear", "cubic"):
        raise ValueError(f"interpolation: linear or cubic, got {interpolation!r}")
    mx, my = _maps(model, direction)
    flag = cv2.INTER_LINEAR if interpolation == "linear" else cv2.INTER_CUBIC
    work = img if img.dtype in (np.uint8, np.uint16, np.int16, np.float32, np.float64) else img.astype(np.float64)
    if fill is None:
        out = cv2.remap(work, mx, my, flag, borderMode=cv2.BORDER_REPLICATE)
    else:
        out = cv2.remap(work, mx, my, flag, borderMode=cv2.BORDER_CONSTANT, borderValue=float(fill))
    return out.astype(img.dtype, copy=False)


def undistort_image(
    image: np.ndarray, model: DistortionModel, interpolation: Interpolation = "linear", fill: float | None = None
) -> np.ndarray:
    """The image on the ideal (pinhole) grid: output pixel p takes the input's value at
    ``model.distort(p)`` (``cv2.remap``). Same shape and dtype as ``image`` (H, W).

    Bilinear by default. It never overshoots: raw counts stay within the input's range (the
    log of a dense-dark image stays defined) and no ringing halo appears beside a bead or a
    wire, where OpenCV's cubic (Keys, a = −0.75) does. Neither is free of bias: resampling a
    rendered bead grid by a constant sub-pixel shift moved the fitted bead centres on average
    by up to 0.019 px (bilinear) and 0.025 px (cubic), varying with the shift's fraction (a
    prefiltered cubic B-spline, scipy's, stayed within 0.002 px at ~10× the time). OpenCV also
    tabulates the weights at 1/32 px, so positions are honoured to ±1/64 px. On noise:
    bilinear averages up to four pixels, so the variance drops by a factor that depends on
    the map's sub-pixel phase (1 at a whole pixel, 0.39 at ¼, 0.25 at ½ on both axes; cubic
    1, 0.73, 0.52): the output's noise is no longer stationary and neighbouring pixels are
    correlated, which a segmentation that estimates one noise level per image should allow.
    ``fill``: the value of pixels whose source lies outside the image (None: the nearest edge
    pixel's value, which adds no step for the segmentation to see).
    """
    return _remap(image, model, "undistort", interpolation, fill)


def distort_image(
    image: np.ndarray, model: DistortionModel, interpolation: Interpolation = "linear", fill: float | None = None
) -> np.ndarray:
    """An ideal (pinhole) render as the intensifier would show it: output pixel q takes the
    input's value at ``model.undistort(q)`` (Newton per pixel, cached per model). Same shape
    and dtype as ``image``; ``interpolation`` and ``fill`` as for :func:`undistort_image`
    (a pixel where the inverse is refused, which only a folding polynomial far outside its
    support gives, keeps its own input value)."""
    return _remap(image, model, "distort", interpolation, fill)


# -- files ------------------------------------------------------------------------------


def _model_from_dict(d: Any, origin: str | Path) -> DistortionModel:
    if not isinstance(d, dict):
        raise InputError(origin, None, f'a JSON object (an "{FORMAT}")')
    for key, want in (("format", FORMAT), ("version", VERSION), ("model", MODEL), ("direction", DIRECTION)):
        if d.get(key) != want:
            raise InputError(origin, key, f"{json.dumps(want)}, got {json.dumps(d.get(key))[:40]}")

    def number(key: str, positive: bool = False, optional: bool = False) -> float | None:
        v = d.get(key)
        if v is None and optional:
            return None
        if (
            isinstance(v, bool)
            or not isinstance(v, (int, float))
            or not math.isfinite(v)
            or (positive and v <= 0)
            or v < 0
        ):
            raise InputError(origin, key, "a positive number" if positive else "a non-negative number")
        return float(v)

    deg = d.get("degree")
    if isinstance(deg, bool) or not isinstance(deg, int) or not 1 <= deg <= MAX_DEGREE:
        raise InputError(origin, "degree", f"an integer 1–{MAX_DEGREE}")
    shape = d.get("image_shape")
    if not (
        isinstance(shape, list)
        and len(shape) == 2
        and all(isinstance(v, int) and not isinstance(v, bool) and v >= 2 for v in shape)
    ):
        raise InputError(origin, "image_shape", "[H, W], two integers ≥ 2")
    centre = d.get("centre_px")
    if not (isinstance(centre, list) and len(centre) == 2 and all(_finite(v) for v in centre)):
        raise InputError(origin, "centre_px", "[u, v], two finite numbers (px)")
    coefs = []
    for key in ("coefficients_u", "coefficients_v"):
        c = d.get(key)
        if not (isinstance(c, list) and len(c) == n_terms(deg) and all(_finite(v) for v in c)):
            raise InputError(origin, key, f"{n_terms(deg)} finite numbers (degree {deg})")
        coefs.append(tuple(float(v) for v in c))
    source = d.get("source", "")
    if not isinstance(source, str):
        raise InputError(origin, "source", "a string")
    rms = number("rms_residual_px", optional=True)
    mx = number("max_residual_px", optional=True)
    return DistortionModel(
        deg,
        tuple(shape),
        tuple(float(v) for v in centre),
        number("scale_px", positive=True),
        coefs[0],
        coefs[1],
        0.0 if rms is None else rms,
        0.0 if mx is None else mx,
        source,
        number("support_radius_px", positive=True, optional=True),
    )


def _finite(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def read_distortion(path: str | Path) -> DistortionModel:
    """Read an ``ftrac-distortion`` JSON file; InputError naming the file and the key on any
    missing or malformed entry (unknown keys are ignored)."""
    return _model_from_dict(parse_json(read_text_input(path), path), path)


def write_distortion(path: str | Path, model: DistortionModel) -> Path:
    """Write ``model`` as ``ftrac-distortion`` JSON, atomically (temporary name, then rename):

    ``{"format": "ftrac-distortion", "version": 1, "model": "polynomial-2d", "degree",
    "image_shape": [H, W], "centre_px": [u, v], "scale_px", "coefficients_u",
    "coefficients_v", "direction": "ideal_to_distorted", "rms_residual_px",
    "max_residual_px", "source"}`` plus ``max_displacement_px`` and, when set,
    ``support_radius_px``. An unwritable path is an InputError.
    """
    path = Path(path)
    text = json.dumps(model.to_dict(), indent=2, allow_nan=False) + "\n"
    try:
        with atomic_file(path) as tmp:
            tmp.write_text(text, encoding="utf-8")
    except OSError as exc:
        raise InputError(path, None, f"a writable output path ({exc.strerror or exc})") from None
    return path
