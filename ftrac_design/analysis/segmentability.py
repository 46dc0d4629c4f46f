"""Segmentability: how far apart the features' images stay. numpy only.

The conditioning analysis assumes every feature is segmented; this module asks whether the
image lets it be: at each pose, the image-plane clearance between the projections of
distinct features, in pixels, beyond their projected widths, at the design's camera.

Widths. A bead of diameter d at camera depth Z images as a disc of radius ``f d / (2 Z)``
(f in pixels, √(fx fy)); a wire of diameter w as a band of half-width ``f w / (2 Z)`` with Z
the depth of the wire's centre (its centre-line ± 15 mm changes a 1.7 px width by < 0.05 px).
Both are the tangential semi-axes of the true images: away from the principal ray the
radial ones are longer by 1/cos α (≤ 2.5 % at the corner of a 1024² image at f = 1000 mm,
0.44 mm pixels) — clearances are overstated by at most that share of a radius (< 0.1 px).

Pairs and their clearance (px; negative = the images overlap):

- **bead–bead** (every pair, beads on one line included): centre distance − both radii.
  Negative: the beads merge into one blob.
- **bead–line** (a bead and every line it is not threaded on; a bead on its own line is
  there by design): distance from the bead centre to the projected centre-line segment −
  bead radius − wire half-width. Negative: the bead sits on a foreign line, so which line
  it belongs to — how beads are identified — is ambiguous. For parallel lines this is the
  near-collinear case again, with the bead's width as tolerance.
- **bead–ellipse**: likewise, to the projected ellipse. Reported but *not counted* by
  default: an ellipse wire crossing a bead is a crossing — the 7 px disc is still found by
  its size, the ellipse loses a few px of a 300 px contour — and it happens at most poses
  of every ellipse design (about 60 % of ``ftrac_2005``'s workspace).
- **wire–wire** (line–line, line–ellipse, ellipse–ellipse). Wires' images may cross —
  segmentation handles a crossing point — so what counts is a *stretch*: the clearance is
  the smallest d such that the two centre-lines stay within d of each other along a
  connected stretch of ``stretch_px`` (default 10 px) of image curve, minus both
  half-widths; i.e. with f(s) the distance from the point at arc length s of one curve to
  the other curve, ``min over windows [a, a + stretch_px] of max f`` − widths. A
  transversal crossing at angle θ has f = |s| sin θ, hence clearance
  ``stretch_px sin θ / 2 − widths``: negative only for crossings flatter than
  asin(widths / (stretch_px / 2)) (≈ 20° for two 0.5 mm wires at 1.5× and 0.44 mm pixels);
  parallel wires D px apart have D − widths; two lines on one image line have −widths. It
  is measured along the ellipse for a line–ellipse pair (exact distance to the segment),
  along the first ellipse for two ellipses, and both ways for two lines (the smaller
  value). A curve shorter in the image than ``stretch_px`` (a line seen end-on) is one
  window: its largest distance.

A pose's clearance is the smallest over the counted pairs (:data:`COUNTED`); its features
**overlap** when that is negative.

Sampling and its error. Lines are measured at ``line_samples`` + 1 points, ellipses at
``ellipse_samples`` + 1 points equally spaced in parameter; as a distance target a line is
its exact segment and an ellipse the polygon through its points, which is within its sag
of the true projected ellipse (``PairClearance.sampling_error_px``: 0.07 px for
``ftrac_2005`` over its workspace at 64 points). f is taken as linear between points and
the windows tried start or end at a point, so a wire–wire clearance is overstated by at
most half a point spacing × sin θ: ≤ 0.8 px for crossings near the overlap threshold
(≈ 20°; ~4.7 px spacing on a ~300 px ellipse), up to 2.4 px for right-angle crossings far
from it (against 512/256 points over 1,000 ``ftrac_2005`` poses: the same overlap verdict at
every pose; largest differences bead–ellipse 0.06, line–line 0.02, ellipse–ellipse 0.15,
line–ellipse 2.4 px at steep crossings, 0 for beads; ``benchmarks/segmentability_figures.py``).

Everything is batched over poses: R (B, 3, 3), t (B, 3) mm, F → X.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..features.model import Features
from ..pose.camera import Camera

PAIR_KINDS = ("bead-bead", "bead-line", "bead-ellipse", "line-line", "line-ellipse", "ellipse-ellipse")

#: the kinds whose overlap makes a pose unsegmentable by default: all but a bead on an
#: ellipse's wire (see the module doc)
COUNTED = ("bead-bead", "bead-line", "line-line", "line-ellipse", "ellipse-ellipse")

#: poses per chunk ((chunk, n, n) arrays of the ellipse distances stay a few MB)
CHUNK = 256


@dataclass(frozen=True)
class ClearanceSettings:
    """How clearances are measured (see module doc)."""

    stretch_px: float = 10.0
    ellipse_samples: int = 64
    line_samples: int = 32
    #: pair kinds that count toward a pose's clearance and overlap (the others are reported)
    counted: tuple[str, ...] = COUNTED


@dataclass
class PairClearance:
    """Clearance of every pair at B poses; :attr:`counted` kinds decide a pose's figure."""

    pairs: list[tuple[str, str]]
    kinds: list[str]
    #: (B, P) px beyond both widths; negative = overlap
    clearance_px: np.ndarray
    #: largest sag of the ellipse polygons over these poses, px (the distance error bound)
    sampling_error_px: float
    counted: tuple[str, ...] = COUNTED

    def _counted(self) -> np.ndarray:
        return np.array([k in self.counted for k in self.kinds], bool)

    def minimum(self) -> np.ndarray:
        """(B,) smallest clearance of the counted pairs at each pose (+inf where there are none)."""
        c = self.clearance_px[:, self._counted()]
        return c.min(1) if c.shape[1] else np.full(c.shape[0], np.inf)

    def worst_pair(self) -> np.ndarray:
        """(B,) index into :attr:`pairs` of the counted pair with the smallest clearance (-1: none)."""
        keep = np.flatnonzero(self._counted())
        if not keep.size:
            return np.full(self.clearance_px.shape[0], -1)
        return keep[self.clearance_px[:, keep].argmin(1)]

    def overlap(self) -> np.ndarray:
        """(B, P) True where a pair's images overlap (clearance < 0)."""
        return self.clearance_px < 0.0

    def kind_minimum(self, kind: str) -> np.ndarray:
        """(B,) smallest clearance among pairs of ``kind`` (+inf where there are none)."""
        idx = [i for i, k in enumerate(self.kinds) if k == kind]
        if not idx:
            return np.full(self.clearance_px.shape[0], np.inf)
        return self.clearance_px[:, idx].min(1)

    def pair_name(self, i: int) -> str:
        """``"A–B"`` for pair index ``i``."""
        a, b = self.pairs[i]
        return f"{a}-{b}"


def _project(X: np.ndarray, intr: np.ndarray, R: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pixels (B, n, 2) and camera depths (B, n) of F points X (n, 3)."""
    Pc = np.matmul(np.asarray(X, float), np.swapaxes(R, 1, 2)) + t[:, None, :]
    z = Pc[..., 2]
    return np.stack([intr[0] * Pc[..., 0] / z + intr[2], intr[1] * Pc[..., 1] / z + intr[3]], -1), z


@dataclass
class _Curve:
    id: str
    kind: str
    target: np.ndarray  # (B, k+1, 2) the curve as a distance target: a segment, or the closed polygon
    vertices: np.ndarray  # (B, n+1, 2) where distances along the curve are measured (closed: last = first)
    half_width: np.ndarray  # (B,) px
    sag: float  # largest polygon sag, px (0 for a line)

    @property
    def closed(self) -> bool:
        return self.kind == "ellipse"


def _curves(features: Features, intr: np.ndarray, f_px: float, R, t, cs: ClearanceSettings) -> list[_Curve]:
    out = []
    for ln in features.lines:
        vert, _ = _project(ln.sample(np.linspace(0.0, 1.0, cs.line_samples + 1)), intr, R, t)
        _, zc = _project((ln.start + ln.end)[None] / 2, intr, R, t)
        out.append(_Curve(ln.id, "line", vert[:, [0, -1]], vert, 0.5 * ln.wire_diameter * f_px / zc[:, 0], 0.0))
    for el in features.ellipses:
        s = np.linspace(0.0, 2 * np.pi, cs.ellipse_samples + 1)
        vert, _ = _project(el.sample(s), intr, R, t)
        mid, _ = _project(el.sample((s[:-1] + s[1:]) / 2), intr, R, t)
        _, zc = _project(el.center[None], intr, R, t)
        out.append(_Curve(el.id, "ellipse", vert, vert, 0.5 * el.wire_diameter * f_px / zc[:, 0], _sag(vert, mid)))
    return out


def _sag(vert: np.ndarray, mid: np.ndarray) -> float:
    """Largest distance (px) from the curve's point mid-way in parameter to its polygon's
    chord: how far the polygon can be from the true curve."""
    if vert.shape[0] == 0:
        return 0.0
    a, b = vert[:, :-1], vert[:, 1:]
    e = b - a
    cross = e[..., 0] * (mid[..., 1] - a[..., 1]) - e[..., 1] * (mid[..., 0] - a[..., 0])
    return float(np.max(np.abs(cross) / np.maximum(np.linalg.norm(e, axis=-1), 1e-300)))


def _segment_distance(P: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance (...) from points P (..., 2) to segments a–b (..., 2)."""
    ex, ey = b[..., 0] - a[..., 0], b[..., 1] - a[..., 1]
    dx, dy = P[..., 0] - a[..., 0], P[..., 1] - a[..., 1]
    ee = ex * ex + ey * ey
    u = np.clip((dx * ex + dy * ey) / np.where(ee > 0, ee, 1.0), 0.0, 1.0)
    return np.hypot(dx - u * ex, dy - u * ey)


def distance_to_polyline(P: np.ndarray, V: np.ndarray, closed: bool = False) -> np.ndarray:
    """Euclidean distance (B, m) from points P (B, m, 2) to the polyline through V (B, k+1, 2)
    (``closed``: V[:, -1] = V[:, 0]).

    Up to 4 segments: every segment exactly. More (a sampled ellipse): the two segments
    at the nearest vertex — exact for a convex polygon whose segments are shorter than the
    point's distance to it is large, and never off by more than half a segment otherwise.
    """
    k = V.shape[1] - 1
    if k <= 4:
        return _segment_distance(P[:, :, None, :], V[:, None, :-1, :], V[:, None, 1:, :]).min(-1)
    # nearest vertex by argmin of |v|² − 2 p·v, one batched matrix product (3× faster than
    # the differences)
    Vk = V[:, :k]
    A = np.concatenate([-2.0 * P, np.ones(P.shape[:2] + (1,))], -1)
    W = np.concatenate([Vk, (Vk * Vk).sum(-1, keepdims=True)], -1)
    j = np.argmin(A @ np.swapaxes(W, 1, 2), -1)  # (B, m) nearest vertex
    prev = (j - 1) % k if closed else np.maximum(j - 1, 0)
    nxt = j + 1  # V has k + 1 rows
    take = lambda idx: np.take_along_axis(V, idx[..., None], 1)  # noqa: E731 — (B, m, 2)
    vj = take(j)
    return np.minimum(_segment_distance(P, take(prev), vj), _segment_distance(P, vj, take(nxt)))


def _batched_search(s: np.ndarray, q: np.ndarray, side: str) -> np.ndarray:
    """Row-wise ``searchsorted`` of q (B, n) in increasing rows s (B, L): one search over
    all rows made increasing by a per-row offset."""
    B, L = s.shape
    off = (np.abs(s).max() + np.abs(q).max() + 1.0) * np.arange(B)[:, None]
    return np.searchsorted((s + off).ravel(), (q + off).ravel(), side).reshape(q.shape) - np.arange(B)[:, None] * L


def stretch_distance(f: np.ndarray, P: np.ndarray, stretch: float, closed: bool = False) -> np.ndarray:
    """(..., B) the smallest d such that the curve through P (B, m, 2) stays within d of
    another curve along a connected stretch of ``stretch`` px: min over windows of that arc
    length of the largest distance f (..., B, m) to it in the window. Leading axes of f are
    other curves measured along the same one (the windows depend only on P: found once).

    f is taken as linear in arc length between the points; the windows tried are those that
    start or end at a point, so the result exceeds the exact minimax by at most half a point
    spacing × the slope of f there (sin θ for a crossing at θ). A curve shorter than
    ``stretch`` is one window: its largest distance. ``closed``: P[:, -1] = P[:, 0].
    """
    lead = f.shape[:-2]
    B, m = f.shape[-2:]
    f = f.reshape((-1, B, m))
    K = f.shape[0]
    s = np.concatenate([np.zeros((B, 1)), np.cumsum(np.hypot(*np.moveaxis(np.diff(P, axis=1), -1, 0)), 1)], 1)
    total = s[:, -1].copy()
    if closed:  # once more round: windows may wrap
        f = np.concatenate([f, f[..., 1:]], -1)
        s = np.concatenate([s, s[:, 1:] + total[:, None]], 1)
        starts, ends = np.arange(m - 1), np.arange(m - 1, 2 * m - 1)
    else:
        starts = ends = np.arange(m)
    L = s.shape[1]
    rows = np.arange(B)[:, None]
    # where the windows starting at a vertex end (inside segment j−1 … j) and where those
    # ending at a vertex start (inside segment i … i+1)
    end = s[:, starts] + stretch
    j = _batched_search(s, end, "left")
    beg = s[:, ends] - stretch
    i = _batched_search(s, beg, "right") - 1
    # sparse table: level p holds the largest f over 2^p vertices from each one, up to the
    # longest window
    longest = max(int((j - starts).max()), int((ends - i).max()), 1)
    levels = [f]
    while (2 << (len(levels) - 1)) <= min(longest, L):
        h = 1 << (len(levels) - 1)
        prev = levels[-1]
        levels.append(np.concatenate([np.maximum(prev[..., :-h], prev[..., h:]), prev[..., -h:]], -1))
    table = np.stack(levels).ravel()
    log2 = np.minimum(np.floor(np.log2(np.arange(1, L + 1))).astype(int), len(levels) - 1)
    # flat indices (np.take beats fancy indexing): level, curve, pose, vertex
    base = (np.arange(K)[:, None, None] * B + rows) * L
    fl, sl = f.ravel(), s.ravel()

    def range_max(lo, hi):  # inclusive vertex ranges (B, n) → (K, B, n)
        p = log2[hi - lo]
        q = p * (K * B * L) + base
        return np.maximum(table.take(q + lo), table.take(q + hi - (1 << p) + 1))

    def lerp(i, x):  # f at arc position x in segment i … i+1
        k = rows * L + i
        s0, s1 = sl.take(k), sl.take(k + 1)
        lam = np.clip((x - s0) / np.where(s1 > s0, s1 - s0, 1.0), 0.0, 1.0)
        f0, f1 = fl.take(base + i), fl.take(base + i + 1)
        return f0 + lam * (f1 - f0)

    ok = j < L  # an open curve's windows may run off its end
    j = np.clip(j, 1, L - 1)
    best = np.where(ok, np.maximum(range_max(np.broadcast_to(starts, j.shape), j - 1), lerp(j - 1, end)), np.inf).min(
        -1
    )
    ok = i >= 0
    i = np.clip(i, 0, L - 2)
    jj = np.broadcast_to(ends, i.shape)
    best = np.minimum(
        best, np.where(ok, np.maximum(range_max(np.minimum(i + 1, jj), jj), lerp(i, beg)), np.inf).min(-1)
    )
    return np.where(total < stretch, f[..., :m].max(-1), best).reshape(lead + (B,))


def _wire_pairs(curves: list[_Curve], stretch: float) -> dict[tuple[int, int], np.ndarray]:
    """(B,) stretch clearance of every pair of curves (index pairs ia < ib; see module doc):
    along the ellipse for a line and an ellipse, along the first of two ellipses, both ways
    for two lines — all curves measured along one curve at once."""
    along: dict[int, list[int]] = {}
    for ia in range(len(curves)):
        for ib in range(ia + 1, len(curves)):
            a, b = curves[ia], curves[ib]
            if a.kind == "line" and b.kind == "ellipse":
                along.setdefault(ib, []).append(ia)
            else:
                along.setdefault(ia, []).append(ib)
                if a.kind == "line" and b.kind == "line":
                    along.setdefault(ib, []).append(ia)
    out: dict[tuple[int, int], np.ndarray] = {}
    for ia, targets in along.items():
        a = curves[ia]
        f = np.stack([distance_to_polyline(a.vertices, curves[ib].target, curves[ib].closed) for ib in targets])
        d = stretch_distance(f, a.vertices, stretch, a.closed)
        for k, ib in enumerate(targets):
            key = (min(ia, ib), max(ia, ib))
            out[key] = np.minimum(out[key], d[k]) if key in out else d[k]
    for (ia, ib), d in out.items():
        d -= curves[ia].half_width + curves[ib].half_width
    return out


def _pair_chunk(features: Features, camera: Camera, R: np.ndarray, t: np.ndarray, settings: ClearanceSettings):
    """Pairs, kinds, clearances (B, P) and the largest sag at one chunk of poses."""
    intr = camera.intrinsics
    f_px = float(np.sqrt(intr[0] * intr[1]))
    pairs: list[tuple[str, str]] = []
    kinds: list[str] = []
    cols: list[np.ndarray] = []
    pts = features.points
    if pts:
        c, z = _project(features.point_centers(), intr, R, t)  # (B, P, 2), (B, P)
        r = 0.5 * np.array([p.diameter for p in pts]) * f_px / z
        i, j = np.triu_indices(len(pts), 1)
        if i.size:
            cols.append(np.linalg.norm(c[:, i] - c[:, j], axis=-1) - r[:, i] - r[:, j])
            pairs += [(pts[a].id, pts[b].id) for a, b in zip(i, j)]
            kinds += ["bead-bead"] * i.size
    curves = _curves(features, intr, f_px, R, t, settings)
    for cv in curves:
        own = [k for k, p in enumerate(pts) if not (cv.kind == "line" and p.line == cv.id)]
        if not own:
            continue
        d = distance_to_polyline(c[:, own], cv.target, cv.closed)
        cols.append(d - r[:, own] - cv.half_width[:, None])
        pairs += [(pts[k].id, cv.id) for k in own]
        kinds += [f"bead-{cv.kind}"] * len(own)
    wires = _wire_pairs(curves, settings.stretch_px)
    for ia in range(len(curves)):
        for ib in range(ia + 1, len(curves)):
            a, b = curves[ia], curves[ib]
            cols.append(wires[ia, ib][:, None])
            pairs.append((a.id, b.id))
            kinds.append("-".join(sorted((a.kind, b.kind), key=("line", "ellipse").index)))
    C = np.concatenate(cols, 1) if cols else np.zeros((R.shape[0], 0))
    return pairs, kinds, C, max((cv.sag for cv in curves), default=0.0)


def pair_clearances(
    features: Features,
    camera: Camera,
    R: np.ndarray,
    t: np.ndarray,
    settings: ClearanceSettings = ClearanceSettings(),
    chunk: int = CHUNK,
) -> PairClearance:
    """Clearance (px, beyond both widths) of every pair of distinct ``features`` at poses
    R (B, 3, 3), t (B, 3) mm (F → X), seen by ``camera``. See the module doc.

    Works ``chunk`` poses at a time (on threads when there are several: numpy's loops
    release the GIL)."""
    R = np.asarray(R, float).reshape(-1, 3, 3)
    t = np.asarray(t, float).reshape(-1, 3)
    starts = list(range(0, R.shape[0], chunk)) or [0]

    def one(a: int):
        return _pair_chunk(features, camera, R[a : a + chunk], t[a : a + chunk], settings)

    if len(starts) == 1:
        parts = [one(starts[0])]
    else:
        from concurrent.futures import ThreadPoolExecutor

        from .poses import _workers

        with ThreadPoolExecutor(max_workers=_workers()) as pool:
            parts = list(pool.map(one, starts))
    pairs, kinds = parts[0][0], parts[0][1]
    return PairClearance(
        pairs, kinds, np.concatenate([p[2] for p in parts]), max(p[3] for p in parts), tuple(settings.counted)
    )


def image_clearance(
    features: Features, camera: Camera, R: np.ndarray, t: np.ndarray, settings: ClearanceSettings = ClearanceSettings()
) -> tuple[np.ndarray, np.ndarray]:
    """The segmentability constraint at poses R (B, 3, 3), t (B, 3) mm (F → X).

    Returns the smallest image-plane clearance between distinct features at each pose (B,),
    in pixels beyond their projected widths (+inf for a single feature), and whether any
    features overlap there (B,) bool (clearance < 0): beads merging, a bead on a foreign
    line, or two wires within their widths of each other along ``settings.stretch_px`` of
    image curve (a bead on an ellipse wire is not counted by default). Every feature must
    be in front of the source (as at every workspace pose). About 0.1 ms of CPU per pose
    for ``ftrac_2005``, batched (``benchmarks/segmentability_figures.py``). Pair
    definitions in the module doc; :func:`pair_clearances` gives every pair.
    """
    pc = pair_clearances(features, camera, R, t, settings)
    m = pc.minimum()
    return m, m < 0.0


# ---- summaries for the analysis (analysis.json, plots) ---------------------------------------


def _stats(a: np.ndarray) -> dict:
    """min / 5th percentile / median (None where infinite: no pair of that kind)."""
    a = np.asarray(a, float)
    if a.size == 0 or not np.isfinite(a).any():
        return {"min": None, "p5": None, "median": None}
    return {"min": float(np.min(a)), "p5": float(np.percentile(a, 5)), "median": float(np.median(a))}


@dataclass
class Segmentability:
    """Clearances of a design at workspace poses, with what analysis.json reports of them."""

    name: str
    settings: ClearanceSettings
    R: np.ndarray
    t: np.ndarray
    pairs: PairClearance
    nominal_beam: np.ndarray

    @property
    def clearance_px(self) -> np.ndarray:
        """(B,) each pose's smallest counted clearance, px."""
        return self.pairs.minimum()

    @property
    def overlap_share(self) -> float:
        """Share of the poses where counted features overlap."""
        return float(np.mean(self.clearance_px < 0.0))

    @property
    def clearance_p5_px(self) -> float | None:
        """5th percentile over the poses of the smallest clearance (None: nothing to clear)."""
        return _stats(self.clearance_px)["p5"]

    def to_dict(self, n_worst: int = 5) -> dict:
        """The ``segmentability`` block of analysis.json (px, shares of poses)."""
        from .sampling import angle_from

        pc = self.pairs
        kinds = {}
        for k in PAIR_KINDS:
            if k not in pc.kinds:
                continue
            km = pc.kind_minimum(k)
            kinds[k] = {"counted": k in pc.counted, "overlap_share": float(np.mean(km < 0)), "clearance_px": _stats(km)}
        share = pc.overlap().mean(0) if pc.clearance_px.size else np.zeros(0)
        pairs = {pc.pair_name(i): float(share[i]) for i in np.argsort(-share, kind="stable") if share[i] > 0}
        m = self.clearance_px
        worst = []
        if np.isfinite(m).any():
            order = np.argsort(m, kind="stable")[:n_worst]
            wp = pc.worst_pair()
            beams = self.R[order, 2, :]
            polar, az = angle_from(self.nominal_beam, beams)
            for k, i in enumerate(order):
                worst.append(
                    {
                        "beam_direction": [float(v) for v in beams[k]],
                        "angle_from_nominal_deg": float(polar[k]),
                        "azimuth_deg": float(az[k]),
                        "translation_mm": [float(v) for v in self.t[i]],
                        "clearance_px": float(m[i]),
                        "pair": pc.pair_name(int(wp[i])),
                        "kind": pc.kinds[int(wp[i])],
                    }
                )
        s = self.settings
        return {
            "settings": {
                "stretch_px": s.stretch_px,
                "ellipse_samples": s.ellipse_samples,
                "line_samples": s.line_samples,
                "counted": list(s.counted),
                "poses": int(m.size),
            },
            "sampling_error_px": pc.sampling_error_px,
            "clearance_px": _stats(m),
            "overlap_share": self.overlap_share,
            "kinds": kinds,
            "pairs_overlap_share": pairs,
            "worst_poses": worst,
        }


def segmentability(
    features: Features, camera: Camera, R: np.ndarray, t: np.ndarray, settings: ClearanceSettings = ClearanceSettings()
) -> Segmentability:
    """Clearances of ``features`` at workspace poses R (B, 3, 3), t (B, 3) mm (F → X)."""
    R = np.asarray(R, float).reshape(-1, 3, 3)
    t = np.asarray(t, float).reshape(-1, 3)
    return Segmentability(
        features.name,
        settings,
        R,
        t,
        pair_clearances(features, camera, R, t, settings),
        np.asarray(features.nominal_beam_direction, float),
    )


@dataclass
class SegmentabilityAtlas:
    """The smallest counted clearance over every view direction (fiducial origin on the
    principal ray at the workspace depth — there clearances do not depend on the roll, an
    image rotation about the principal point): on the sphere grid ``lon``, ``lat`` (deg,
    (nlat, nlon)) and on the workspace cone grid ``polar``, ``azimuth`` (deg)."""

    lon: np.ndarray
    lat: np.ndarray
    sphere: PairClearance
    polar: np.ndarray
    azimuth: np.ndarray
    cone: PairClearance
    cone_deg: float
    nominal_beam: np.ndarray

    def sphere_grid(self) -> np.ndarray:
        """(nlat, nlon) smallest counted clearance, px."""
        return self.sphere.minimum().reshape(self.lon.shape)

    def cone_grid(self) -> np.ndarray:
        """(npolar, naz) smallest counted clearance, px."""
        return self.cone.minimum().reshape(self.polar.shape)

    def to_dict(self) -> dict:
        """The atlas part of the ``segmentability`` block (shares of grid directions; the
        sphere's cells are equal-angle, so its share is weighted by cos latitude)."""
        ms, mc = self.sphere.minimum(), self.cone.minimum()
        w = np.cos(np.radians(self.lat)).ravel()
        wp = self.sphere.worst_pair()
        kinds = {}
        for k in sorted(set(self.sphere.kinds[i] for i in wp[ms < 0])) if (ms < 0).any() else []:
            kinds[k] = float(np.sum(w * ((ms < 0) & (np.array(self.sphere.kinds)[wp] == k))) / w.sum())
        # the cone grid's cells are equal in polar angle: weight by sin(polar) for area
        wc = np.sin(np.radians(self.polar)).ravel()
        return {
            "sphere_step_deg": float(abs(self.lon[0, 1] - self.lon[0, 0])) if self.lon.shape[1] > 1 else None,
            "directions": int(ms.size),
            "overlap_share_of_sphere": float(np.sum(w * (ms < 0)) / w.sum()),
            "overlap_share_of_sphere_by_worst_kind": kinds,
            "overlap_share_of_cone": float(np.sum(wc * (mc < 0)) / wc.sum()),
            "clearance_px_in_cone": _stats(mc),
        }


def segmentability_atlas(
    features: Features,
    camera: Camera,
    depth_mm: float,
    cone_deg: float,
    step_deg: float = 3.0,
    settings: ClearanceSettings = ClearanceSettings(),
) -> SegmentabilityAtlas:
    """Clearances over the whole sphere of view directions (``step_deg`` grid) and the
    workspace cone (1° × 5° polar grid), fiducial origin at ``depth_mm`` on the principal ray."""
    from .sampling import cone_grid, isocentre_poses, sphere_grid

    lon, lat, d = sphere_grid(step_deg)
    R, t = isocentre_poses(d.reshape(-1, 3), depth_mm)
    sph = pair_clearances(features, camera, R, t, settings)
    nb = np.asarray(features.nominal_beam_direction, float)
    pol, az, dc = cone_grid(nb, cone_deg)
    Rc, tc = isocentre_poses(dc.reshape(-1, 3), depth_mm)
    cone = pair_clearances(features, camera, Rc, tc, settings)
    return SegmentabilityAtlas(lon, lat, sph, pol, az, cone, cone_deg, nb)
