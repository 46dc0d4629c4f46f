"""How well a pose accounts for the image, with no labels: the wire it predicts and the
ridges the image shows.

A labelling that is right puts every wire on a ridge of the image; a wrong one that happens
to fit its beads and a few contours puts some wire on bare background, which these measures
see without any contour extraction. The evidence is the ridge strength across the predicted
curve's normal in units of its noise (:meth:`.detection.Scene.ridge_evidence`): a second
derivative reads about zero on background whatever its level, so a wire shows the same
whether it lies over bone or soft tissue, on a raw or a display image. Samples under a
predicted ball, outside the image or where it cannot be read (``Scene.valid``) count
neither way.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from . import identify
from .detection import Scene

#: readable length (px) a predicted curve needs to be judged at all
MIN_FREE_PX = 8.0


def _curve_normals(pts: np.ndarray, closed: bool) -> np.ndarray:
    """Unit normals (n, 2) of a densely sampled curve (n, 2) from its neighbouring samples."""
    if len(pts) < 2:
        return np.zeros_like(pts)
    if closed:
        tv = np.roll(pts, -1, axis=0) - np.roll(pts, 1, axis=0)
    else:
        tv = np.gradient(pts, axis=0)
    nrm = np.stack([-tv[:, 1], tv[:, 0]], -1)
    return nrm / np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-12)


def _free_samples(scene: Scene, R: np.ndarray, t: np.ndarray, bead_radius_px: np.ndarray):
    """Per predicted curve: id → (kind, samples (n, 2), normals (n, 2)) of the samples that
    can be read (inside the image, valid, clear of every predicted ball)."""
    features = scene.features
    curves = identify.curve_samples(features, scene.camera, R, t)
    bu = identify.project(scene.camera, R, t, features.point_centers())[0] if len(features.points) else np.zeros((0, 2))
    rad = np.asarray(bead_radius_px, float)
    out = {}
    for fid, (kind, pts) in curves.items():
        nrm = _curve_normals(pts, kind == "ellipse")
        ok = scene.readable(pts, margin_px=1.0)
        if len(bu) and ok.any():
            idx = np.flatnonzero(ok)
            dd = np.linalg.norm(pts[idx, None] - bu[None], axis=-1)
            ok[idx[(dd <= rad[None]).any(1)]] = False
        out[fid] = (kind, pts[ok], nrm[ok])
    return out


def median_spread(scene: Scene, samples: int) -> float:
    """The spread (noise units) of the median ridge evidence of ``samples`` curve samples on
    bare background: ~1.25 / √n_eff, the samples (0.5 px apart) correlated over the ridge
    scale's 2σ."""
    corr = 2.0 * scene.scales.ridge_sigma_px
    return 1.25 / float(np.sqrt(max(samples * 0.5 / corr, 1.0)))


@dataclass(frozen=True)
class CurveSupport:
    """What the image shows where a pose puts one line or ellipse.

    Attributes
    ----------
    ridge : the median ridge evidence across the curve (noise units).
    samples : the readable samples it is the median of (0.5 px apart).
    learned : the learned detector's median wire probability there (0 on the classical
        path, and where a long curve's ridge contradicts it: see :data:`RIDGE_OVERRULES`).
    """

    ridge: float
    samples: int
    learned: float


#: how far (in :func:`median_spread`) the median ridge evidence of a curve with at least
#: ``OVERRULE_MIN_PX`` of readable length must stand below zero for it to overrule the learned
#: detector: the network's wire map reads 0.25–0.6 all over a dewarping plate's lattice of
#: balls, where the ridge of an ellipse a pose put there read 0.6–3.3 spreads below zero.
#: A short stretch of wire between balls reads their blurred flanks (a blob's second
#: derivative changes sign outside it), so its median can sit below zero whatever is there:
#: true ftrac_mini wires of 15–17 px read down to −1.9 spreads. On the tuning images no true
#: wire of 100 px or more that the network vouched for read below −0.5 spreads; of the
#: curves it vouched for on wrong poses 27 of 657 did, on 21 dewarping plates 38 of 63
RIDGE_OVERRULES = 0.5
OVERRULE_MIN_PX = 100.0


def curve_support(
    scene: Scene, R: np.ndarray, t: np.ndarray, bead_radius_px: np.ndarray, min_free_px: float = MIN_FREE_PX
) -> dict[str, CurveSupport]:
    """How much wire the image shows where pose (R, t) puts each line and ellipse.

    Each curve's centre-line is sampled every 0.5 px; the samples that can be read (see the
    module; ``bead_radius_px`` per model bead) give the ridge evidence across the curve and
    the learned detector's wire probability along it. Curves with less than ``min_free_px``
    of readable length are left out. Returns id → :class:`CurveSupport`."""
    out: dict[str, CurveSupport] = {}
    for fid, (_, pts, nrm) in _free_samples(scene, R, t, bead_radius_px).items():
        if len(pts) * 0.5 < min_free_px:
            continue
        ridge = float(np.median(scene.ridge_evidence(pts, nrm)))
        overruled = len(pts) * 0.5 >= OVERRULE_MIN_PX and ridge < -RIDGE_OVERRULES * median_spread(scene, len(pts))
        learned = 0.0
        if scene.learned is not None and not overruled:
            learned = float(np.median(scene.learned_wire(pts)))
        out[fid] = CurveSupport(ridge, len(pts), learned)
    return out


#: model samples per line (spread over its wire pieces by length) and per ellipse when many
#: poses are judged at once
COARSE_SAMPLES = 24
#: where a curve's median ridge evidence is clipped when hypotheses are ranked (noise units):
#: a plain wire counts fully at 3 and no more, a curve on bare background about 0, and one
#: on the opposite of a wire (a dark line where a wire would be bright) −1 at most
RANK_CLIP = (-1.0, 3.0)


def _coarse_model_curves(features) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[str]]:
    """Every line and ellipse sampled ``COARSE_SAMPLES`` times in F (a line on its wire
    pieces only): points (m, 3) mm, unit tangents (m, 3), model length per sample (m,) mm
    and the curve ids — each curve's samples one block of ``COARSE_SAMPLES``, in the ids'
    order."""
    n = COARSE_SAMPLES
    pts, tan, step, ids = [], [], [], []
    pieces: dict[str, list] = {}
    for fid, a, b in features.wire_pieces:
        pieces.setdefault(fid, []).append((a, b))
    for fid, ab in pieces.items():
        lengths = np.array([np.linalg.norm(b - a) for a, b in ab])
        total = max(float(lengths.sum()), 1e-9)
        # n samples at the centres of n equal steps of the pieces laid end to end
        s = (np.arange(n) + 0.5) / n * total
        k = np.minimum(np.searchsorted(np.cumsum(lengths), s, side="right"), len(ab) - 1)
        f = (s - np.r_[0.0, np.cumsum(lengths)][k]) / np.maximum(lengths[k], 1e-9)
        A, B = np.array([a for a, _ in ab])[k], np.array([b for _, b in ab])[k]
        pts.append(A + f[:, None] * (B - A))
        tan.append(B - A)
        step.append(np.full(n, total / n))
        ids.append(fid)
    for el in features.ellipses:
        s = np.linspace(0, 2 * np.pi, n, endpoint=False)
        d = el.sample(s + 1e-3) - el.sample(s - 1e-3)
        pts.append(el.sample(s))
        tan.append(d)
        step.append(np.linalg.norm(d, axis=1) / 2e-3 * (2 * np.pi / n))
        ids.append(el.id)
    if not pts:
        z = np.zeros((0, 3))
        return z, z, np.zeros(0), []
    T = np.concatenate(tan)
    T /= np.maximum(np.linalg.norm(T, axis=1, keepdims=True), 1e-12)
    return np.concatenate(pts), T, np.concatenate(step), ids


def _row_medians(x: np.ndarray) -> np.ndarray:
    """Median of each row of ``x`` (H, n) over its finite entries; NaN for a row with none."""
    k = np.isfinite(x).sum(1)
    srt = np.sort(np.where(np.isfinite(x), x, np.inf), axis=1)
    lo = np.take_along_axis(srt, np.maximum((k - 1) // 2, 0)[:, None], 1)[:, 0]
    hi = np.take_along_axis(srt, np.maximum(k // 2, 0)[:, None], 1)[:, 0]
    return np.where(k > 0, 0.5 * (lo + hi), np.nan)


def _near_any(uv: np.ndarray, bu: np.ndarray, rad: np.ndarray) -> np.ndarray:
    """Whether each sample uv (H, m, 2) px lies within ``rad`` (k,) px of one of its pose's
    balls bu (H, k, 2): ball by ball, so no (H, m, k, 2) array is made."""
    near = np.zeros(uv.shape[:2], bool)
    for j in range(bu.shape[1]):
        du = uv[..., 0] - bu[:, j, None, 0]
        dv = uv[..., 1] - bu[:, j, None, 1]
        near |= np.sqrt(du * du + dv * dv) <= rad[j]
    return near


def ranking_support(
    scene: Scene, R: np.ndarray, t: np.ndarray, bead_radius_px: np.ndarray, chunk: int = 256
) -> np.ndarray:
    """How plainly the image shows the wires of each of many poses (R (H, 3, 3), t (H, 3)):
    per pose, the sum over its lines and ellipses of the median ridge evidence along the
    curve (noise units, clipped to ``RANK_CLIP``); a curve with less than ``MIN_FREE_PX`` of
    readable length adds nothing. Returns (H,).

    The ridge measure of :func:`curve_support` on ``COARSE_SAMPLES`` samples a curve instead of one
    every 0.5 px, for every bead hypothesis of an image at once (hundreds to thousands):
    ranking them by it puts first the poses whose wires the image shows, which a pose must
    have to pass (:func:`.acceptance.absent_wires`)."""
    features, camera = scene.features, scene.camera
    R, t = np.asarray(R, float).reshape(-1, 3, 3), np.asarray(t, float).reshape(-1, 3)
    out = np.zeros(len(R))
    S, T, ds, ids = _coarse_model_curves(features)
    if not len(S) or not len(R):
        return out
    centers = features.point_centers() if len(features.points) else np.zeros((0, 3))
    rad = np.asarray(bead_radius_px, float)
    lo, hi = RANK_CLIP
    h = 0.05  # mm along the tangent: the curve's direction in the image
    m, nc = len(S), len(ids)
    ahead = np.concatenate([S, S + h * T])
    for i0 in range(0, len(R), chunk):
        Ri, ti = R[i0 : i0 + chunk], t[i0 : i0 + chunk]
        both, Zb = identify.project(camera, Ri, ti, ahead)
        uv, Z = both[:, :m], Zb[:, :m]
        tv = both[:, m:] - uv
        px = np.sqrt(tv[..., 0] * tv[..., 0] + tv[..., 1] * tv[..., 1]) / h * ds  # image length per sample
        ok = scene.readable(uv, margin_px=1.0) & (Z > 0) & np.isfinite(px)
        if len(centers) and ok.any():
            bu = identify.project(camera, Ri, ti, centers)[0]
            ok &= ~_near_any(uv, bu, np.broadcast_to(rad, (len(centers),)))
        ev = np.full(ok.shape, np.nan)
        if ok.any():
            nrm = np.stack([-tv[..., 1], tv[..., 0]], -1)[ok]
            nrm /= np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-12)
            ev[ok] = scene.ridge_evidence(uv[ok], nrm)
        # each curve's samples are a block of COARSE_SAMPLES columns: one median per block
        length = np.where(ok, px, 0.0).reshape(len(Ri), nc, -1).sum(-1)
        med = _row_medians(np.where(ok, ev, np.nan).reshape(len(Ri) * nc, -1)).reshape(len(Ri), nc)
        med = np.where((length >= MIN_FREE_PX) & np.isfinite(med), np.clip(med, lo, hi), 0.0)
        out[i0 : i0 + chunk] = med.sum(1)
    return out


def learned_confirms_wires(scene: Scene, R: np.ndarray, t: np.ndarray, min_probability: float = 0.3) -> bool:
    """Whether the learned detector shows every readable wire pose (R, t) predicts (median
    probability ≥ ``min_probability`` where the ridge does not overrule it, see
    :func:`curve_support`; at least two wires): the evidence that confirms a ball labelling
    where the wires' contours could not be measured. False on the classical path."""
    if scene.learned is None:
        return False
    sup = curve_support(scene, R, t, scene.bead_exclusion())
    return len(sup) >= 2 and min(c.learned for c in sup.values()) >= min_probability


def image_agreement(
    scene: Scene, R: np.ndarray, t: np.ndarray, bead_radius_px: np.ndarray, tol_px: float, min_snr: float = 3.0
) -> tuple[float, float]:
    """How well pose (R, t) accounts for the image, with no labels: ``(unexplained,
    unsupported)`` in pixels of length. *Unexplained*: ridge points farther than ``tol_px``
    from every predicted wire and outside every predicted ball (each ridge point stands for
    ~1 px of wire). *Unsupported*: readable predicted wire where the ridge evidence is below
    ``min_snr``. Both are the same for every hypothesis where the image has clutter; between
    two labellings the right one has less of each (a near-mirror labelling of ftrac_mini put
    its ellipses where the image has hardly any wire and left the real ellipses' ridges
    unexplained, while dropping its own ellipses as "crowded" made its χ² the smaller)."""
    features, ridges = scene.features, scene.ridges
    curves = identify.curve_samples(features, scene.camera, R, t)
    bu = identify.project(scene.camera, R, t, features.point_centers())[0] if len(features.points) else np.zeros((0, 2))
    rad = np.asarray(bead_radius_px, float)
    pts = [p for _, p in curves.values()]
    allp = np.concatenate(pts) if pts else np.zeros((0, 2))
    allp = allp[np.isfinite(allp).all(1)]
    unexplained = 0.0
    if ridges is not None and len(ridges):
        d = (
            cKDTree(allp).query(ridges.uv, distance_upper_bound=tol_px)[0]
            if len(allp)
            else np.full(len(ridges), np.inf)
        )
        far = ~np.isfinite(d)
        if len(bu) and far.any():
            db = np.linalg.norm(ridges.uv[far][:, None] - bu[None], axis=-1)
            far[np.flatnonzero(far)[(db <= rad[None] + 1.0).any(1)]] = False
        unexplained = float(far.sum())
    unsupported = 0.0
    for _, q, nrm in _free_samples(scene, R, t, rad).values():
        if len(q):
            unsupported += 0.5 * float((scene.ridge_evidence(q, nrm) < min_snr).sum())  # samples every 0.5 px
    return unexplained, unsupported
