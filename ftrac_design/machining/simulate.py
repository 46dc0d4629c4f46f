"""Material removal on radial dexels, and the check of a program against the reference cuts.

**Dexels.** The stock's outer surface is unrolled onto a grid of azimuth θ (spacing
``h/R``) and height z (spacing ``h``). Each cell is a radial ray ``ρ e_r(θ) + z e_z``; what a
flat end mill removes from a ray is one exact interval of ρ (:func:`.model.cylinder_ray_interval`),
so nothing is lost across the ray. The tool is placed along every move at steps of at most
``δ`` (measured at the outer surface, A and the tip together); between two placements the
swept envelope is missed by at most the scallop ``δ² / (4 d)`` for an end mill ``d`` wide
(:func:`scallop`), 1 µm by default. Each run of cutting moves between two rapids is one
layer (its rays' intervals are unions of overlapping placements); the reference cuts are
cast onto the same rays exactly.

**Check** (:func:`verify`):

- *overcut* — every end of a removed interval that lies inside the stock is a point of the
  machined surface; its signed distance to the union of the reference cuts (exact for slots
  and pockets, to second order for the swept ellipse grooves) is how far the program cut
  into material the CAD keeps. A point more than ``tolerance`` out is a *gouge*, named by
  the feature whose moves cut it and the nearest reference cut.
- *undercut* — every end of a reference interval inside the stock that no removed interval
  covers is material the CAD removes and the program leaves; its distance to the machined
  region is the smaller of the distance along its ray to the removed interval there and
  the exact distance to the nearest tool placement.
- *volume* — removed and reference volumes, ``∫ (ρ_hi² − ρ_lo²)/2 dθ dz`` over the merged
  intervals of each ray, clipped to the stock.
- *rapids* — no rapid may bring the tool tip below the stock's outer radius within its length.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from .gcode import ParsedMove, ParsedProgram
from .model import CutPlan, EllipseCut, SlotCut, Stock, cylinder_ray_interval

#: default dexel spacing at the outer surface, mm
GRID = 0.02
#: default scallop bound between tool placements, mm
SCALLOP = 1e-3
#: default limits of the check: max deviation (mm) and removed-volume difference (fraction)
TOLERANCE = 0.01
VOLUME_TOLERANCE = 0.01


def scallop(step: float, diameter: float) -> float:
    """Largest gap (mm) between the swept envelope of an end mill ``diameter`` wide and its
    placements ``step`` apart: ``r − √(r² − step²/4) ≈ step² / (4 d)``."""
    r = diameter / 2
    return r - math.sqrt(max(r * r - step * step / 4, 0.0))


def placement_step(diameter: float, bound: float = SCALLOP) -> float:
    """The step between placements whose scallop is ``bound`` (mm)."""
    r = diameter / 2
    return 2 * math.sqrt(r * r - (r - bound) ** 2)


@dataclass(frozen=True)
class Grid:
    """The dexel grid over the stock: column ``i`` at θ = (i + ½)·dθ, row ``j`` at z = −L/2 + (j + ½)·dz."""

    stock: Stock
    n_theta: int
    n_z: int

    @classmethod
    def for_stock(cls, stock: Stock, h: float = GRID) -> "Grid":
        return cls(
            stock, max(8, math.ceil(2 * math.pi * stock.outer_radius / h)), max(1, math.ceil(2 * stock.half_length / h))
        )

    @property
    def d_theta(self) -> float:
        return 2 * math.pi / self.n_theta

    @property
    def d_z(self) -> float:
        return 2 * self.stock.half_length / self.n_z

    def theta(self, i):
        return (np.asarray(i) % self.n_theta + 0.5) * self.d_theta

    def z(self, j):
        return -self.stock.half_length + (np.asarray(j) + 0.5) * self.d_z


@dataclass
class Layer:
    """Removed intervals ``[lo, hi]`` (mm from the axis, clipped to the stock) on rays ``keys``
    (``i * n_z + j``); ``lo_free``/``hi_free``: that end is a cut surface, not the stock's."""

    name: str
    keys: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    lo_free: np.ndarray
    hi_free: np.ndarray


def _clip(grid: Grid, name: str, keys, lo, hi) -> Layer:
    s = grid.stock
    ok = np.isfinite(lo) & ~np.isnan(hi)  # hi = inf: a tool reaching out of the stock
    keys, lo, hi = keys[ok], lo[ok], hi[ok]
    lo_c, hi_c = np.maximum(lo, s.bore_radius), np.minimum(hi, s.outer_radius)
    keep = lo_c < hi_c
    return Layer(name, keys[keep], lo_c[keep], hi_c[keep], (lo > s.bore_radius)[keep], (hi < s.outer_radius)[keep])


# ---- tool placements ----------------------------------------------------------------------------


@dataclass
class Placements:
    """Tool placements: machine X, Y, Z (mm), A (rad), tool radius, and the run each belongs to."""

    x: np.ndarray
    y: np.ndarray
    z: np.ndarray
    a: np.ndarray
    radius: np.ndarray
    run: np.ndarray
    run_names: list[str] = field(default_factory=list)


def _sample(m: ParsedMove, outer: float, step: float, tool_radius: float = 0.0) -> np.ndarray:
    """(n, 4) placements along one move (X, Y, Z, A rad), ends included.

    Straight moves are stepped at the outer surface (A and X, Y, Z together); arcs at the
    tool's outer edge, radius + ``tool_radius``, which sweeps faster than the centre.
    """
    s, e = np.array(m.start, float), np.array(m.end, float)
    s[3], e[3] = math.radians(s[3]), math.radians(e[3])
    if m.kind == "arc":
        cx, cy = m.centre
        r, sweep = m.radius, m.sweep
        n = max(1, math.ceil(math.hypot((r + tool_radius) * sweep, e[2] - s[2]) / step))
        t = np.linspace(0.0, 1.0, n + 1)
        a0 = math.atan2(s[1] - cy, s[0] - cx)
        ang = a0 + (1 if m.ccw else -1) * sweep * t
        return np.column_stack(
            [cx + r * np.cos(ang), cy + r * np.sin(ang), s[2] + (e[2] - s[2]) * t, np.full_like(t, s[3])]
        )
    d = e - s
    length = math.sqrt(d[0] ** 2 + d[1] ** 2 + d[2] ** 2 + (outer * d[3]) ** 2)
    n = max(1, math.ceil(length / step))
    t = np.linspace(0.0, 1.0, n + 1)[:, None]
    return s + t * d


def placements(
    prog: ParsedProgram, tools: dict[int, float], stock: Stock, bound: float = SCALLOP
) -> tuple[Placements, list[str]]:
    """Every cutting move of ``prog`` sampled into placements; and the rapid faults."""
    rows, faults = [], []
    run, names, in_run = -1, [], False
    for m in prog.moves:
        if m.kind == "rapid":
            in_run = False
            if not (np.all(np.isfinite(m.start)) and np.all(np.isfinite(m.end))):
                continue
            dia = tools.get(m.tool, 0.0) if m.tool is not None else 0.0
            p = _sample(m, stock.outer_radius, 0.05)
            inside = (p[:, 2] < stock.outer_radius - 1e-6) & (np.abs(p[:, 0]) < stock.half_length + dia / 2)
            if inside.any():
                faults.append(
                    f"line {m.line}: a rapid brings the tool below the stock's surface "
                    f"(Z{p[inside, 2].min():.4f} < {stock.outer_radius:g})"
                )
            continue
        if m.tool is None or m.tool not in tools:
            raise ValueError(f"line {m.line}: cutting with tool {m.tool}, whose diameter is not known")
        if not in_run:
            run += 1
            names.append(m.feature or f"run {run + 1}")
            in_run = True
        p = _sample(m, stock.outer_radius, placement_step(tools[m.tool], bound), tools[m.tool] / 2)
        rows.append(np.column_stack([p, np.full(len(p), tools[m.tool] / 2), np.full(len(p), run)]))
    arr = np.concatenate(rows) if rows else np.zeros((0, 6))
    return Placements(arr[:, 0], arr[:, 1], arr[:, 2], arr[:, 3], arr[:, 4], arr[:, 5].astype(int), names), faults


def _window(grid: Grid, a: np.ndarray, half: int) -> tuple[int, int]:
    """(first column, number of columns) that covers azimuths ``a`` (rad) ± ``half`` columns."""
    cols = np.unique(np.floor((a % (2 * math.pi)) / grid.d_theta).astype(int) % grid.n_theta)
    gaps = np.diff(np.concatenate([cols, [cols[0] + grid.n_theta]]))
    k = int(np.argmax(gaps))
    start = int(cols[(k + 1) % len(cols)])
    span = grid.n_theta - int(gaps[k]) + 1
    if span + 2 * half + 1 >= grid.n_theta:
        return 0, grid.n_theta
    return start - half, span + 2 * half


def stamp(grid: Grid, pl: Placements, run: int, batch: int = 256) -> Layer:
    """The intervals that the placements of ``run`` remove from every ray they reach."""
    sel = pl.run == run
    x, y, z, a, r = pl.x[sel], pl.y[sel], pl.z[sel], pl.a[sel], pl.radius[sel]
    reach = np.arcsin(np.clip((np.abs(y) + r) / np.maximum(z, 1e-9), 0.0, 1.0))
    wi = int(math.ceil(reach.max() / grid.d_theta)) + 1
    wj = int(math.ceil(r.max() / grid.d_z)) + 1
    c0, nc = _window(grid, a, wi)
    j0 = max(0, int(math.floor((x.min() - r.max() + grid.stock.half_length) / grid.d_z)) - 1)
    j1 = min(grid.n_z, int(math.ceil((x.max() + r.max() + grid.stock.half_length) / grid.d_z)) + 1)
    nr = max(0, j1 - j0)
    lo = np.full(nc * nr, np.inf)
    hi = np.full(nc * nr, -np.inf)
    di = np.arange(-wi, wi + 1)
    dj = np.arange(-wj, wj + 1)
    for b in range(0, len(x), batch):
        sl = slice(b, b + batch)
        ic = np.floor((a[sl] % (2 * math.pi)) / grid.d_theta).astype(int)
        jc = np.floor((x[sl] + grid.stock.half_length) / grid.d_z).astype(int)
        i = ic[:, None, None] + di[None, :, None]
        j = jc[:, None, None] + dj[None, None, :]
        i, j = np.broadcast_arrays(i, j)
        li, hi_ = cylinder_ray_interval(
            grid.theta(i),
            grid.z(j),
            a[sl, None, None],
            y[sl, None, None],
            x[sl, None, None],
            z[sl, None, None],
            r[sl, None, None],
        )
        col = (i - c0) % grid.n_theta
        ok = np.isfinite(li) & (j >= j0) & (j < j1) & (col < nc)
        idx = col[ok] * nr + (j[ok] - j0)
        np.minimum.at(lo, idx, li[ok])
        np.maximum.at(hi, idx, hi_[ok])
    cell = np.flatnonzero(lo < hi)
    keys = ((cell // nr + c0) % grid.n_theta) * grid.n_z + (cell % nr + j0)
    return _clip(grid, pl.run_names[run], keys, lo[cell], hi[cell])


# ---- the reference cuts on the same rays --------------------------------------------------------


def reference_layer(grid: Grid, cut, margin: float = 2.0) -> Layer:
    """The reference cut ``cut`` cast onto the grid's rays (exact intervals)."""
    s = grid.stock
    R = s.outer_radius
    if isinstance(cut, EllipseCut):
        i = np.arange(grid.n_theta)
        th = grid.theta(i)
        slope = np.hypot(cut.seat_radius, cut.dz(th)) / cut.seat_radius
        half = int(math.ceil((cut.width / 2 * slope.max() + cut.floor_depth) / grid.d_z)) + 2
        jc = np.floor((cut.z(th) + s.half_length) / grid.d_z).astype(int)
        jj = jc[:, None] + np.arange(-half, half + 1)[None, :]
        ii = np.broadcast_to(i[:, None], jj.shape)
        ok = (jj >= 0) & (jj < grid.n_z)
        ii, jj = ii[ok], jj[ok]
        lo, hi = cut.ray_interval(grid.theta(ii), grid.z(jj), R)
    else:
        if isinstance(cut, SlotCut):
            r_lat, z0, z1, floor = cut.width / 2, cut.z0 - cut.end_radius, cut.z1 + cut.end_radius, cut.floor_radius
        else:
            r_lat, floor = cut.diameter / 2, cut.floor_radius
            z0, z1 = cut.z - r_lat, cut.z + r_lat
        wi = int(math.ceil(math.asin(min(1.0, r_lat / floor)) / grid.d_theta)) + 2
        ic = int(math.floor((cut.azimuth % (2 * math.pi)) / grid.d_theta))
        j0 = max(0, int(math.floor((z0 + s.half_length) / grid.d_z)) - 1)
        j1 = min(grid.n_z, int(math.ceil((z1 + s.half_length) / grid.d_z)) + 1)
        ii, jj = np.meshgrid(np.arange(ic - wi, ic + wi + 1) % grid.n_theta, np.arange(j0, j1), indexing="ij")
        ii, jj = ii.ravel(), jj.ravel()
        lo, hi = cut.ray_interval(grid.theta(ii), grid.z(jj), R)
    return _clip(grid, cut.id, ii * grid.n_z + jj, lo, hi)


def union_volume(grid: Grid, layers: list[Layer]) -> float:
    """Volume (mm³) of the union of the layers' intervals: ``Σ (hi² − lo²)/2 · dθ · dz`` per merged interval."""
    if not layers:
        return 0.0
    keys = np.concatenate([la.keys for la in layers])
    lo = np.concatenate([la.lo for la in layers])
    hi = np.concatenate([la.hi for la in layers])
    order = np.lexsort((lo, keys))
    keys, lo, hi = keys[order], lo[order], hi[order]
    total = 0.0
    single = np.ones(len(keys), bool)
    if len(keys) > 1:
        dup = keys[1:] == keys[:-1]
        single[1:] &= ~dup
        single[:-1] &= ~dup
    total += float(np.sum((hi[single] ** 2 - lo[single] ** 2) / 2))
    multi = np.flatnonzero(~single)
    if len(multi):
        k, l_, h = keys[multi], lo[multi], hi[multi]
        starts = np.flatnonzero(np.concatenate([[True], k[1:] != k[:-1]]))
        ends = np.concatenate([starts[1:], [len(k)]])
        for s0, e0 in zip(starts, ends):
            cur_lo, cur_hi = l_[s0], h[s0]
            for q in range(s0 + 1, e0):
                if l_[q] > cur_hi:
                    total += (cur_hi**2 - cur_lo**2) / 2
                    cur_lo, cur_hi = l_[q], h[q]
                else:
                    cur_hi = max(cur_hi, h[q])
            total += (cur_hi**2 - cur_lo**2) / 2
    return total * grid.d_theta * grid.d_z


def reference_sdf(plan: CutPlan, rho, theta, z) -> tuple[np.ndarray, np.ndarray]:
    """Signed distance (mm) of points to the union of the plan's cuts, and the nearest cut's index."""
    d = np.stack([c.sdf(rho, theta, z) for c in plan.cuts]) if plan.cuts else np.full((1, np.size(rho)), np.inf)
    k = np.argmin(d, axis=0)
    return np.take_along_axis(d, k[None], axis=0)[0], k


def _tool_sdf(px, py, pz, x, y, z, a, r):
    """Signed distance from F points to flat end mills (tip X, Y, Z, A rad, radius), broadcast."""
    er = np.stack([np.cos(a), np.sin(a)])
    et = np.stack([-np.sin(a), np.cos(a)])
    tip_x = z * er[0] + y * (-et[0])
    tip_y = z * er[1] + y * (-et[1])
    rx, ry, rz = px - tip_x, py - tip_y, pz - x
    ax = rx * er[0] + ry * er[1]
    lat = np.hypot(rx * et[0] + ry * et[1], rz)
    dx, dy = lat - r, -ax
    return np.hypot(np.maximum(dx, 0), np.maximum(dy, 0)) + np.minimum(np.maximum(dx, dy), 0)


def placement_distance(pl: Placements, stock: Stock, rho, theta, z, chunk: int = 2000) -> np.ndarray:
    """Distance (mm, ≥ 0) from points (ρ, θ, z) to the nearest tool placement (exact per
    placement; placements found on the unrolled outer surface, periodic in θ)."""
    R = stock.outer_radius
    out = np.full(np.size(rho), np.inf)
    if len(pl.x) == 0:
        return out
    box = 2 * math.pi * R
    pts = np.column_stack([(pl.a % (2 * math.pi)) * R, pl.x + stock.half_length + 1.0])
    tree = cKDTree(pts, boxsize=[box, 4 * stock.half_length + 4 * pl.radius.max() + 10.0])
    reach = float((pl.radius.max() + np.abs(pl.y).max()) * R / max(pl.z.min(), 1e-3)) + 0.05
    q = np.column_stack([(np.asarray(theta) % (2 * math.pi)) * R, np.asarray(z) + stock.half_length + 1.0])
    px, py, pz = rho * np.cos(theta), rho * np.sin(theta), np.asarray(z, float)
    for s in range(0, len(q), chunk):
        lists = tree.query_ball_point(q[s : s + chunk], reach)
        lens = np.array([len(li) for li in lists])
        if lens.sum() == 0:
            continue
        who = np.repeat(np.arange(len(lists)), lens)
        cand = np.concatenate([np.asarray(li, int) for li in lists if li])
        d = _tool_sdf(
            px[s + who], py[s + who], pz[s + who], pl.x[cand], pl.y[cand], pl.z[cand], pl.a[cand], pl.radius[cand]
        )
        best = np.full(len(lists), np.inf)
        np.minimum.at(best, who, np.maximum(d, 0.0))
        out[s : s + chunk] = best
    return out


# ---- the check --------------------------------------------------------------------------------


@dataclass
class Verification:
    """The outcome of :func:`verify` (mm, mm³, s)."""

    grid_mm: float
    scallop_mm: float
    max_overcut_mm: float
    max_undercut_mm: float
    gouges: int
    gouge_examples: list[str]
    removed_mm3: float
    reference_mm3: float
    rapid_faults: list[str]
    program_faults: list[str]
    per_feature_mm: dict[str, dict[str, float]]
    tolerance_mm: float
    volume_tolerance: float
    run_time_s: float

    @property
    def max_deviation_mm(self) -> float:
        return max(self.max_overcut_mm, self.max_undercut_mm)

    @property
    def volume_difference(self) -> float:
        """(removed − reference) / reference."""
        return self.removed_mm3 / self.reference_mm3 - 1.0 if self.reference_mm3 else math.inf

    @property
    def ok(self) -> bool:
        return (
            self.max_deviation_mm <= self.tolerance_mm
            and self.gouges == 0
            and abs(self.volume_difference) <= self.volume_tolerance
            and not self.rapid_faults
            and not self.program_faults
        )

    def as_dict(self) -> dict[str, Any]:
        """Plain JSON."""
        return {
            "ok": self.ok,
            "max_deviation_mm": self.max_deviation_mm,
            "max_overcut_mm": self.max_overcut_mm,
            "max_undercut_mm": self.max_undercut_mm,
            "gouges": self.gouges,
            "gouge_examples": self.gouge_examples,
            "removed_mm3": self.removed_mm3,
            "reference_mm3": self.reference_mm3,
            "volume_difference": self.volume_difference,
            "rapid_faults": self.rapid_faults,
            "program_faults": self.program_faults,
            "per_feature_mm": self.per_feature_mm,
            "tolerance_mm": self.tolerance_mm,
            "volume_tolerance": self.volume_tolerance,
            "grid_mm": self.grid_mm,
            "scallop_mm": self.scallop_mm,
            "run_time_s": self.run_time_s,
        }


def _endpoints(layer: Layer) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(key, ρ, which layer row) of every free end of ``layer``'s intervals."""
    rows = np.arange(len(layer.keys))
    k = np.concatenate([layer.keys[layer.lo_free], layer.keys[layer.hi_free]])
    r = np.concatenate([layer.lo[layer.lo_free], layer.hi[layer.hi_free]])
    w = np.concatenate([rows[layer.lo_free], rows[layer.hi_free]])
    return k, r, w


def _covered_distance(sim: list[Layer], keys: np.ndarray, rho: np.ndarray) -> np.ndarray:
    """Distance along each ray from ρ to the removed intervals on it (0 inside one; inf: none)."""
    out = np.full(len(keys), np.inf)
    for la in sim:
        order = np.argsort(la.keys)
        sk = la.keys[order]
        pos = np.searchsorted(sk, keys)
        pos_c = np.minimum(pos, len(sk) - 1)
        hit = (len(sk) > 0) & (sk[pos_c] == keys) if len(sk) else np.zeros(len(keys), bool)
        if not np.any(hit):
            continue
        lo, hi = la.lo[order][pos_c], la.hi[order][pos_c]
        d = np.where(rho < lo, lo - rho, np.where(rho > hi, rho - hi, 0.0))
        out = np.where(hit, np.minimum(out, d), out)
    return out


def verify(
    prog: ParsedProgram,
    plan: CutPlan,
    tools: dict[int, float] | None = None,
    grid_mm: float = GRID,
    scallop_mm: float = SCALLOP,
    tolerance: float = TOLERANCE,
    volume_tolerance: float = VOLUME_TOLERANCE,
) -> Verification:
    """Sweep the tools of ``prog`` through ``plan``'s stock and compare with ``plan``'s cuts.

    Parameters
    ----------
    prog : ParsedProgram
        The program as :func:`~ftrac_design.machining.gcode.parse_gcode` read it (machine frame).
    plan : CutPlan
        The stock and the reference cuts (frame F, mm).
    tools : dict, optional
        Flat end-mill diameter (mm) per tool number; default: what the program's tool
        comments state (``(T1: 0.4 mm …)``).
    grid_mm, scallop_mm : float
        Dexel spacing at the outer surface, and the largest gap between the swept envelope
        and the tool placements (mm).
    tolerance, volume_tolerance : float
        Largest deviation (mm) and removed-volume difference (fraction) that pass.

    Returns
    -------
    Verification
        Deviations (mm), gouges, volumes (mm³), faults and the run time.

    Raises ``ValueError`` when a cutting tool's diameter is unknown.
    """
    t0 = time.perf_counter()
    tools = dict(prog.tools if tools is None else tools)
    grid = Grid.for_stock(plan.stock, grid_mm)
    pl, rapid_faults = placements(prog, tools, plan.stock, scallop_mm)
    sim = [stamp(grid, pl, k) for k in range(len(pl.run_names))]
    ref = [reference_layer(grid, c) for c in plan.cuts]
    per: dict[str, dict[str, float]] = {}
    over_max, gouges, examples = _overcut(grid, plan, sim, tolerance, per)
    under_max = _undercut(grid, plan, pl, sim, ref, per)
    bound = max((scallop(placement_step(dd, scallop_mm), dd) for dd in tools.values()), default=0.0)
    return Verification(
        grid_mm,
        bound,
        max(over_max, 0.0),
        under_max,
        gouges,
        examples,
        union_volume(grid, sim),
        union_volume(grid, ref),
        rapid_faults,
        list(prog.faults),
        per,
        tolerance,
        volume_tolerance,
        time.perf_counter() - t0,
    )


def _overcut(grid: Grid, plan: CutPlan, sim: list, tolerance: float, per: dict) -> tuple[float, int, list[str]]:
    """Machined surface points outside the reference cuts: the deepest (mm), how many go deeper
    than ``tolerance`` (gouges) and up to five examples; each layer's deepest into ``per``."""
    over_max, gouges, examples = 0.0, 0, []
    for la in sim:
        k, r, _ = _endpoints(la)
        if not len(k):
            continue
        th, zz = grid.theta(k // grid.n_z), grid.z(k % grid.n_z)
        d, near = reference_sdf(plan, r, th, zz)
        worst = float(d.max())
        per.setdefault(la.name, {})["overcut_mm"] = max(worst, 0.0)
        over_max = max(over_max, worst)
        bad = d > tolerance
        gouges += int(bad.sum())
        if bad.any() and len(examples) < 5:
            q = int(np.argmax(d))
            examples.append(
                f"{la.name}: {d[q]:.4f} mm into the material beside {plan.cuts[near[q]].id} at "
                f"A{math.degrees(th[q]):.3f} X{zz[q]:.4f} r{r[q]:.4f}"
            )
    return over_max, gouges, examples


def _undercut(grid: Grid, plan: CutPlan, pl: Placements, sim: list, ref: list, per: dict) -> float:
    """Reference surface points the program leaves in material: the largest distance (mm) to the
    machined surface, exact near the tool placements; each cut's into ``per``."""
    under_max = 0.0
    for la in ref:
        k, r, _ = _endpoints(la)
        if not len(k):
            continue
        d = _covered_distance(sim, k, r)
        open_ = d > 0
        if np.any(open_ & (d > 1e-3)):
            sel = np.flatnonzero(open_ & (d > 1e-3))
            exact = placement_distance(
                pl, plan.stock, r[sel], grid.theta(k[sel] // grid.n_z), grid.z(k[sel] % grid.n_z)
            )
            d[sel] = np.minimum(d[sel], exact)
        worst = float(np.max(np.where(open_, d, 0.0)))
        per.setdefault(la.name, {})["undercut_mm"] = worst
        under_max = max(under_max, worst)
    return under_max


__all__ = [
    "Grid",
    "Layer",
    "Placements",
    "Verification",
    "placements",
    "reference_layer",
    "scallop",
    "stamp",
    "union_volume",
    "verify",
]
