"""Design rules: can this design be made, and mounted, under a manufacturing profile?

``ftrac-design check`` and ``build`` run :func:`check_design`. Every rule measures one
value on the design — the worst case over all the places it applies — and compares it with
a limit taken from the profile (:func:`ftrac_design.manufacture.profiles.rule_limits`, sources in
``docs/reference/manufacturing.md``). A rule *fails* (a violation: ``check`` exits 1,
``build`` refuses without ``--force``) when the limit is broken, and *warns* when the value
is within the limit but short of the recommended one (CNC walls between 1.0 and 1.5 mm, FDM
walls between 0.8 and 1.2 mm, clearances below the process tolerance); a warning never
changes the exit code. A rule with nothing to measure (no grooves on a bead-only design)
is ``n/a``.

Pure numpy on the design, its features (:mod:`ftrac_design.features`) and the mount and
connector layout (:mod:`ftrac_design.features.mounting`) — no CadQuery, so ``check`` is fast.
Cut sizes come from the profile (:func:`~ftrac_design.manufacture.profiles.cut_sizes`); the cut
geometry follows the body's cut plan: a groove floor lies one wire radius below the
seated centre-line, a bead pocket is a flat-bottomed radial hole whose floor lies one
ball radius below the bead centre, groove and pocket walls run radially from the floor
through the surface.

| rule | measures | limit |
| --- | --- | --- |
| ``body.bore_wall`` | wall between the bore and the deepest groove or pocket floor | ≥ min wall (warn < recommended) |
| ``groove.tool`` | groove width vs the smallest tool | ≥ end-mill Ø (CNC) / nozzle (FDM) |
| ``groove.depth`` | deepest groove floor / end-mill Ø (CNC) | ≤ 4 (warn > 3) |
| ``wires.crossing_clearance`` | radial gap between a line wire and the ellipse wire over it | > 0 (warn < tolerance) |
| ``pockets.spacing`` | wall between a bead pocket and another pocket or another feature's groove | ≥ min wall |
| ``grooves.spacing`` | wall between grooves that do not cross | ≥ min wall |
| ``pockets.retention`` | pocket depth at its lowest rim point vs ball radius | > ball radius |
| ``body.envelope`` | material between any groove or pocket and the body's end faces | ≥ min wall |
| ``mount.coverage`` | gap between the socket rim and the nearest wire, bead or cut | > 0 |
| ``mount.hole_edge`` | mount hole wall to block face | ≥ 1 × hole Ø |
| ``mount.hole_clearance`` | walls between holes, counterbores, socket and faces in the mount | ≥ min wall |
| ``connector.hole_edge`` | pin and tapped hole wall to plate edge | ≥ 1 × hole Ø |
| ``connector.walls`` | pocket wall, pocket floor, pin hole to pocket | ≥ min wall |
| ``connector.template_clearance`` | mount above the template's top edge | > 0 |
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any, Callable, Literal

import numpy as np

from ..design.schema import Design
from ..features import Features, compute_features
from ..features.mounting import ConnectorLayout, Hole, MountLayout, connector_layout, mount_layout
from .profiles import CutSizes, Profile, RuleLimits, cut_sizes, rule_limits

Verdict = Literal["ok", "warn", "fail", "n/a"]

CHECK_FORMAT = "ftrac-check"
CHECK_VERSION = 1

#: samples per ellipse centre-line for distances (0.1°: 26 µm of arc at r = 15 mm; the
#: minimum-distance error of that sampling is far below the 0.001 mm the table prints)
ELLIPSE_SAMPLES = 3600
#: bolted-joint practice: a hole's wall at least one hole diameter from an edge (centre at
#: 1.5 d; EN 1993-1-8 asks 1.2 d0 for steel plates, plastics need more)
HOLE_EDGE_FACTOR = 1.0


@dataclass(frozen=True)
class RuleResult:
    """One rule's verdict: the worst measured value, where it occurs, and the limit."""

    rule: str
    title: str
    measured: float | None
    limit: float
    comparison: str
    unit: str
    verdict: Verdict
    where: str
    recommended: float | None = None
    source: str = ""

    @property
    def message(self) -> str:
        """One line naming the rule, the value and the limit."""
        if self.measured is None:
            return f"{self.rule}: not applicable ({self.where})"
        u = f" {self.unit}" if self.unit else ""
        val = f"{self.measured:.3f}{u}"
        lim = f"{self.comparison} {self.limit:g}{u}"
        if self.verdict == "fail":
            return f"{self.rule}: {self.title} is {val} ({self.where}); the limit is {lim}"
        if self.verdict == "warn":
            return (
                f"{self.rule}: {self.title} is {val} ({self.where}); within the limit {lim} "
                f"but {'above' if self.comparison in ('<=', '<') else 'below'} "
                f"the recommended {self.recommended:g}{u}"
            )
        return f"{self.rule}: {self.title} is {val} ({self.where}); limit {lim}"

    def cells(self, missing: str = "-") -> tuple[str, str]:
        """The measured value and the limit as a table shows them, with the unit (and the
        recommended value beside the limit).

        Parameters
        ----------
        missing : str
            What stands for both when the rule does not apply.

        Returns
        -------
        tuple of str
            (measured, limit).
        """
        if self.measured is None:
            return missing, missing
        u = f" {self.unit}" if self.unit else ""
        lim = f"{self.comparison} {self.limit:g}{u}"
        if self.recommended is not None:
            lim += f" (rec. {self.recommended:g})"
        return f"{self.measured:.3f}{u}", lim

    def as_dict(self) -> dict[str, Any]:
        """The result as plain JSON, with its one-line message."""
        d = asdict(self)
        d["message"] = self.message
        return d


@dataclass(frozen=True)
class CheckReport:
    """Every rule's result for one design under one profile."""

    design: str
    source: str | None
    profile: Profile
    results: tuple[RuleResult, ...]
    cut_sizes: dict[str, Any] = field(default_factory=dict)

    @property
    def violations(self) -> list[RuleResult]:
        """The rules that fail."""
        return [r for r in self.results if r.verdict == "fail"]

    @property
    def warnings(self) -> list[RuleResult]:
        """The rules within their limit but short of the recommended value."""
        return [r for r in self.results if r.verdict == "warn"]

    @property
    def ok(self) -> bool:
        """Whether no rule fails."""
        return not self.violations

    def result(self, rule: str) -> RuleResult:
        """The result of the rule named ``rule`` (KeyError if there is none)."""
        for r in self.results:
            if r.rule == rule:
                return r
        raise KeyError(rule)

    @property
    def summary(self) -> str:
        """One line: the design, the profile, the counts of rules, violations and warnings."""
        n, w = len(self.violations), len(self.warnings)
        return (
            f"{self.design} ({self.profile}): {len(self.results)} rules, "
            f"{n} violation{'s' * (n != 1)}, {w} warning{'s' * (w != 1)}"
        )

    def as_dict(self) -> dict[str, Any]:
        """The report as ``check --json`` prints it (format ``ftrac-check``)."""
        return {
            "format": CHECK_FORMAT,
            "version": CHECK_VERSION,
            "design": {"name": self.design, "source": self.source},
            "profile": self.profile,
            "ok": self.ok,
            "violations": len(self.violations),
            "warnings": len(self.warnings),
            "cut_sizes": self.cut_sizes,
            "rules": [r.as_dict() for r in self.results],
        }

    def table(self) -> str:
        """The report as a plain-text table (one row per rule)."""
        rows = [("rule", "measured", "limit", "verdict", "where")]
        for r in self.results:
            meas, lim = r.cells()
            rows.append((r.rule, meas, lim, r.verdict.upper() if r.verdict == "fail" else r.verdict, r.where))
        widths = [max(len(row[i]) for row in rows) for i in range(4)]
        lines = ["  ".join(c.ljust(w) for c, w in zip(row[:4], widths)) + "  " + row[4] for row in rows]
        lines.insert(1, "  ".join("-" * w for w in widths) + "  " + "-" * 5)
        return "\n".join(lines)


# ---- the cuts in the body, from the features -------------------------------------------------


@dataclass(frozen=True)
class _BodyCut:
    """A groove or pocket: centre-line samples on the seat (F), floor depth, width."""

    id: str
    kind: str  # "ellipse", "line", "pocket"
    line: str | None
    points: np.ndarray  # (n, 3) centre-line samples at the seat, or the bead centre (1, 3)
    floor_depth: float  # below the outer surface, mm
    width: float  # groove width or pocket diameter (cut size), mm
    reach: float  # half-extent of the seated part across the cut (wire or ball radius), mm

    @property
    def label(self) -> str:
        return f"pocket {self.id}" if self.kind == "pocket" else f"groove {self.id}"

    def at_radius(self, r: float) -> np.ndarray:
        """The centre-line moved radially onto the cylinder of radius ``r``."""
        p = self.points.copy()
        rho = np.hypot(p[:, 0], p[:, 1])
        p[:, :2] *= (r / rho)[:, None]
        return p


def body_cuts(design: Design, features: Features, cuts: CutSizes) -> list[_BodyCut]:
    """Every groove and pocket of the body under one profile's cut sizes."""
    R = design.outer_radius
    out: list[_BodyCut] = []
    s = np.linspace(0.0, 2 * math.pi, ELLIPSE_SAMPLES, endpoint=False)
    for e in features.ellipses:
        pts = e.sample(s)
        rs = float(np.mean(np.hypot(pts[:, 0], pts[:, 1])))
        out.append(
            _BodyCut(e.id, "ellipse", None, pts, R - rs + e.wire_diameter / 2, cuts.groove_width, e.wire_diameter / 2)
        )
    for ln in features.lines:
        n = max(2, int(math.ceil(ln.length / 0.05)) + 1)
        pts = ln.sample(np.linspace(0.0, 1.0, n))
        rs = float(math.hypot(ln.start[0], ln.start[1]))
        out.append(
            _BodyCut(ln.id, "line", ln.id, pts, R - rs + ln.wire_diameter / 2, cuts.groove_width, ln.wire_diameter / 2)
        )
    for p in features.points:
        rs = float(math.hypot(p.center[0], p.center[1]))
        out.append(
            _BodyCut(
                p.id,
                "pocket",
                p.line,
                p.center[None, :].copy(),
                R - rs + p.diameter / 2,
                cuts.pocket_diameter,
                p.diameter / 2,
            )
        )
    return out


def _min_distance(a: np.ndarray, b: np.ndarray) -> float:
    if len(a) * len(b) <= 200_000:
        return float(np.min(np.linalg.norm(a[:, None, :] - b[None, :, :], axis=2)))
    # Coarse to fine, exact on these samples: every s-th sample stands for its neighbours,
    # each within da (db) of it, so the closest pair's representatives are within
    # dmin + da + db ≤ coarse_min + da + db; only those neighbourhoods are searched finely.
    # (A k-d tree is slow here: two parallel curves put every point near the same distance.)
    s = int(math.ceil(math.sqrt(len(a) * len(b) / 200_000)))
    ra = np.minimum(np.round(np.arange(len(a)) / s).astype(int), (len(a) - 1) // s)
    rb = np.minimum(np.round(np.arange(len(b)) / s).astype(int), (len(b) - 1) // s)
    da = float(np.max(np.linalg.norm(a - a[ra * s], axis=1)))
    db = float(np.max(np.linalg.norm(b - b[rb * s], axis=1)))
    ca, cb = a[::s], b[::s]
    # |p − q|² by one matrix product (rounding ~1e-12 mm², covered by the 1e-9 slack)
    sq = np.maximum((ca * ca).sum(1)[:, None] + (cb * cb).sum(1)[None, :] - 2.0 * ca @ cb.T, 0.0)
    coarse = np.sqrt(sq)
    ci, cj = np.nonzero(coarse <= coarse.min() + da + db + 1e-9)
    if len(ci) <= 20_000:
        off = np.arange(-s, s + 1)  # covers every sample represented by a coarse one
        wa = np.clip(ci[:, None] * s + off, 0, len(a) - 1)
        wb = np.clip(cj[:, None] * s + off, 0, len(b) - 1)
        best = np.inf
        for k in range(0, len(ci), 1000):
            d = np.linalg.norm(a[wa[k : k + 1000]][:, :, None, :] - b[wb[k : k + 1000]][:, None, :, :], axis=3)
            best = min(best, float(d.min()))
        return best
    from scipy.spatial import cKDTree

    d, _ = cKDTree(b).query(a)
    return float(np.min(d))


def _ligament(a: _BodyCut, b: _BodyCut, R: float) -> float:
    """Wall between two cuts, at the shallower floor (where radial walls are closest)."""
    r = R - min(a.floor_depth, b.floor_depth)
    return _min_distance(a.at_radius(r), b.at_radius(r)) - a.width / 2 - b.width / 2


# ---- the mount's and connector's cuts: axis-aligned capped cylinders and boxes --------------


@dataclass(frozen=True)
class _Cyl:
    """An axis-aligned solid cylinder ``{|p_uv − c_uv| ≤ r, lo ≤ p_axis ≤ hi}``."""

    name: str
    axis: int
    center: tuple[float, float, float]
    r: float
    lo: float
    hi: float

    def project(self, p: list[float]) -> list[float]:
        q = list(p)
        a = self.axis
        q[a] = min(max(p[a], self.lo), self.hi)
        u, v = (a + 1) % 3, (a + 2) % 3
        du, dv = p[u] - self.center[u], p[v] - self.center[v]
        n = math.hypot(du, dv)
        if n > self.r:
            q[u] = self.center[u] + du * self.r / n
            q[v] = self.center[v] + dv * self.r / n
        return q

    def bbox(self) -> tuple[list[float], list[float]]:
        lo, hi = [0.0] * 3, [0.0] * 3
        for k in range(3):
            if k == self.axis:
                lo[k], hi[k] = self.lo, self.hi
            else:
                lo[k], hi[k] = self.center[k] - self.r, self.center[k] + self.r
        return lo, hi


def _convex_distance(a: _Cyl, b: _Cyl, iters: int = 2000) -> float:
    """Distance between two convex solids by alternating projections (0 if they meet)."""
    p = list(a.center)
    q = b.project(p)
    for _ in range(iters):
        p2 = a.project(q)
        q2 = b.project(p2)
        moved = max(abs(p2[k] - p[k]) + abs(q2[k] - q[k]) for k in range(3))
        p, q = p2, q2
        if moved < 1e-10:
            break
    return math.dist(p, q)


def _bbox_distance(a: _Cyl, b: _Cyl) -> float:
    (alo, ahi), (blo, bhi) = a.bbox(), b.bbox()
    gaps = [max(0.0, blo[k] - ahi[k], alo[k] - bhi[k]) for k in range(3)]
    return math.sqrt(sum(g * g for g in gaps))


def _hole_pieces(h: Hole, cuts: CutSizes) -> list[_Cyl]:
    """A mount hole as its through cylinder and (if any) its counterbore, at cut size."""
    c = tuple(float(x) for x in h.center)
    out = [_Cyl(f"hole {h.name}", h.axis, c, cuts.hole(h.diameter) / 2, h.lo, h.hi)]
    if h.counterbore_diameter:
        out.append(
            _Cyl(
                f"counterbore {h.name}",
                h.axis,
                c,
                cuts.hole(h.counterbore_diameter) / 2,
                h.hi - h.counterbore_depth,
                h.hi,
            )
        )
    return out


def _face_ligament(piece: _Cyl, lo: np.ndarray, hi: np.ndarray) -> float:
    """Wall between a cylinder and the faces of a box it runs along (not through)."""
    u, v = (piece.axis + 1) % 3, (piece.axis + 2) % 3
    return min(min(piece.center[k] - lo[k], hi[k] - piece.center[k]) for k in (u, v)) - piece.r


# ---- rules -------------------------------------------------------------------------------------


@dataclass
class _Ctx:
    design: Design
    profile: Profile
    features: Features
    cuts: CutSizes
    limits: RuleLimits
    body: list[_BodyCut]
    mount: MountLayout
    connector: ConnectorLayout


@dataclass(frozen=True)
class Limit:
    """A rule's limit: the value the measure is compared with, the recommended value (a
    warning short of it) and where the limit comes from."""

    value: float
    recommended: float | None = None
    source: str = ""


@dataclass(frozen=True)
class Place:
    """One place a rule measures: the value there and where it is. ``limit``: the place's own
    limit, where it depends on the place (a hole's diameter, a ball's radius); ``rank``: what
    picks the worst place, where it is not the value itself."""

    value: float
    where: str
    limit: float | None = None
    rank: float | None = None

    @property
    def order(self) -> float:
        """What the worst place has least of."""
        return self.value if self.rank is None else self.rank


@dataclass(frozen=True)
class NotApplicable:
    """Nothing to measure: why, and the limit the report shows then (the rule's own when None)."""

    why: str
    limit: Limit | None = None


def _wall(c: _Ctx) -> Limit:
    return Limit(c.limits.min_wall, c.limits.recommended_wall, c.limits.sources["wall"])


def _fixed(value: float, source: str = "") -> Callable[[_Ctx], Limit]:
    return lambda c: Limit(value, source=source)


@dataclass(frozen=True)
class Rule:
    """One design rule: what it measures over the design (every place it applies) and the
    limit the worst place is held to.

    Attributes
    ----------
    name, title : str
        The rule's name (``body.bore_wall``) and what it measures, in words.
    comparison : {">=", ">", "<="}
        How the worst value must compare with the limit.
    measure : callable
        ``measure(context)``: the places measured, or :class:`NotApplicable`.
    limit : callable
        ``limit(context)``: the profile's :class:`Limit`.
    nothing : str
        What an empty list of places means (the report's ``where`` for ``n/a``).
    unit : str
        The measure's unit (``mm``, ``x``).
    """

    name: str
    title: str
    comparison: Literal[">=", ">", "<="]
    measure: Callable[[_Ctx], list[Place] | NotApplicable]
    limit: Callable[[_Ctx], Limit]
    nothing: str = ""
    unit: str = "mm"

    @property
    def __name__(self) -> str:
        """The rule's name, as a function's would be."""
        return self.name

    def evaluate(self, c: _Ctx) -> RuleResult:
        """The rule's verdict on the design in ``c``: the worst place against the limit."""
        found = self.measure(c)
        if isinstance(found, NotApplicable) or not found:
            why = found.why if isinstance(found, NotApplicable) else self.nothing
            lim = found.limit if isinstance(found, NotApplicable) and found.limit is not None else self.limit(c)
            return RuleResult(
                self.name,
                self.title,
                None,
                lim.value,
                self.comparison,
                self.unit,
                "n/a",
                why,
                lim.recommended,
                lim.source,
            )
        lim = self.limit(c)
        worst = min(found, key=lambda p: p.order)
        limit = lim.value if worst.limit is None else worst.limit
        return RuleResult(
            self.name,
            self.title,
            round(float(worst.value), 6) + 0.0,
            limit,
            self.comparison,
            self.unit,
            self.verdict(worst.value, limit, lim.recommended),
            worst.where,
            lim.recommended,
            lim.source,
        )

    def verdict(self, value: float, limit: float, recommended: float | None) -> Verdict:
        """``fail`` when the limit is broken, ``warn`` when within it but short of ``recommended``."""
        ok = {">=": value >= limit - 1e-12, ">": value > limit + 1e-12, "<=": value <= limit + 1e-12}[self.comparison]
        if not ok:
            return "fail"
        if recommended is not None:
            if self.comparison in (">=", ">"):
                short = value < recommended - 1e-12
            else:
                short = value > recommended + 1e-12
            if short:
                return "warn"
        return "ok"


def bore_wall(c: _Ctx) -> list[Place]:
    """Wall between the bore and the deepest groove or pocket floor (the thinnest wall of the
    body). Limits: CNC ≥ 1.0 mm feasible / 1.5 mm recommended (zekes3d, Neptune Labs);
    FDM ≥ 0.8 mm = 2 perimeters / 1.2 mm recommended (printparams, layer-one)."""
    R, rb = c.design.outer_radius, c.design.bore_radius
    return [Place(R - b.floor_depth - rb, f"bore to {b.label} floor") for b in c.body]


def groove_tool(c: _Ctx) -> list[Place] | NotApplicable:
    """Groove width vs the smallest tool: a CNC end mill cannot cut a slot narrower than its
    diameter (``manufacturing.cnc.tool_diameter``); an FDM printer cannot leave a gap
    narrower than its extrusion width (``manufacturing.fdm.nozzle_diameter``)."""
    if not any(b.kind != "pocket" for b in c.body):
        return NotApplicable("no grooves", Limit(c.limits.tool))
    return [Place(c.cuts.groove_width, f"vs {c.limits.tool:g} mm {c.limits.tool_name}")]


def groove_depth(c: _Ctx) -> list[Place] | NotApplicable:
    """Deepest groove floor over the end-mill diameter (CNC only): ≤ 4 (violation above),
    ≤ 3 recommended (common CNC guides: pocket depth ≤ 3–4 × tool diameter)."""
    grooves = [b for b in c.body if b.kind != "pocket"]
    if c.limits.max_depth_ratio is None or not grooves:
        why = "no grooves" if not grooves else f"no depth limit for {c.profile}"
        return NotApplicable(why, Limit(0.0))
    g = max(grooves, key=lambda b: b.floor_depth)
    where = f"{g.label}: {g.floor_depth:.3f} mm deep, {c.limits.tool:g} mm end mill"
    return [Place(g.floor_depth / c.limits.tool, where)]


def crossing_clearance(c: _Ctx) -> list[Place]:
    """Radial clearance between a line wire and the ellipse wire that crosses over it
    (``|r_line − r_ellipse| − r_wire,line − r_wire,ellipse``): must be > 0 so the wires do
    not touch; below the process tolerance (CNC ±0.05 mm, FDM ±0.2 mm) it is a warning."""
    out = []
    for e in c.features.ellipses:
        s = np.linspace(0.0, 2 * math.pi, ELLIPSE_SAMPLES, endpoint=False)
        pts = e.sample(s)
        phi = np.arctan2(pts[:, 1], pts[:, 0])
        re = np.hypot(pts[:, 0], pts[:, 1])
        for ln in c.features.lines:
            az = math.atan2(ln.start[1], ln.start[0])
            k = int(np.argmin(np.abs(np.angle(np.exp(1j * (phi - az))))))
            z = pts[k, 2]
            z0, z1 = sorted((ln.start[2], ln.end[2]))
            if not (z0 - ln.wire_diameter <= z <= z1 + ln.wire_diameter):
                continue
            rl = math.hypot(ln.start[0], ln.start[1])
            gap = abs(rl - re[k]) - ln.wire_diameter / 2 - e.wire_diameter / 2
            out.append(Place(gap, f"{ln.id} under {e.id} at z = {z:.2f}"))
    return out


def pocket_spacing(c: _Ctx) -> list[Place]:
    """Wall between a bead pocket and every other pocket and every groove other than its own
    line's, at the shallower of the two floors. Limits: the profile's walls."""
    R = c.design.outer_radius
    pockets = [b for b in c.body if b.kind == "pocket"]
    out = []
    for i, p in enumerate(pockets):
        for q in pockets[i + 1 :]:
            out.append(Place(_ligament(p, q, R), f"{p.label} to {q.label}"))
        for g in c.body:
            if g.kind == "pocket" or (g.kind == "line" and g.id == p.line):
                continue
            out.append(Place(_ligament(p, g, R), f"{p.label} to {g.label}"))
    return out


def groove_spacing(c: _Ctx) -> list[Place]:
    """Wall between grooves that do not cross (ellipse–ellipse, line–line), at the shallower
    floor. Limits: the profile's walls."""
    R = c.design.outer_radius
    grooves = [b for b in c.body if b.kind != "pocket"]
    out = []
    for i, a in enumerate(grooves):
        for b in grooves[i + 1 :]:
            if a.kind != b.kind:
                continue  # a line and an ellipse cross by design (wires.crossing_clearance)
            out.append(Place(_ligament(a, b, R), f"{a.label} to {b.label}"))
    return out


def retention(c: _Ctx) -> list[Place] | NotApplicable:
    """Pocket depth at its lowest rim point (the surface curves away across the pocket by
    ``R − √(R² − ρ²)``) vs the ball radius: it must be deeper than the radius so that the
    ball's centre is below the rim and the walls hold the ball (a press fit, or glue)."""
    R = c.design.outer_radius
    out = []
    for b in c.body:
        if b.kind != "pocket":
            continue
        rho = min(b.width / 2, R)
        depth = b.floor_depth - (R - math.sqrt(R * R - rho * rho))
        out.append(Place(depth, f"{b.label}, ball radius {b.reach:g} mm", limit=b.reach, rank=depth - b.reach))
    return out or NotApplicable("no beads", Limit(0.0))


def envelope(c: _Ctx) -> list[Place]:
    """Material between every groove or pocket (as the tool cuts it: half a groove width
    beyond the centre-line, including a line groove's rounded ends) and the body's end faces.
    Limits: the profile's walls."""
    L2 = c.design.half_length
    out = []
    for b in c.body:
        zmax = float(np.max(np.abs(b.points[:, 2]))) + b.width / 2
        out.append(Place(L2 - zmax, f"{b.label} to the end face"))
    return out


def coverage(c: _Ctx) -> list[Place]:
    """Gap between the mount's socket rim (``z = −L/2 + socket_depth`` in F) and the lowest
    point of any wire, bead, groove or pocket: the mount must not cover any feature (> 0)."""
    rim = -c.design.half_length + c.design.mount.socket_depth
    out = []
    for b in c.body:
        k = int(np.argmin(b.points[:, 2]))
        low = float(b.points[k, 2]) - max(b.width / 2, b.reach)
        out.append(Place(low - rim, f"{b.id} reaches z = {low:.3f}, socket rim at z = {rim:.3f}"))
    return out


def mount_hole_edge(c: _Ctx) -> list[Place] | NotApplicable:
    """Wall between each mount hole (at cut size) and the block faces it runs along:
    ≥ 1 × the hole's nominal diameter (hole centre ≥ 1.5 d from an edge; bolted-joint
    practice, stricter than EN 1993-1-8's 1.2 d0 for steel because acetal is weaker and creeps)."""
    m = c.mount
    out = []
    for h in m.holes:
        lig = _face_ligament(_hole_pieces(h, c.cuts)[0], m.lo, m.hi)
        where = f"hole {h.name} (Ø{h.diameter:g}) in a {m.width:g} x {m.width:g} x {m.height:g} mm block"
        out.append(Place(lig, where, limit=HOLE_EDGE_FACTOR * h.diameter, rank=lig / h.diameter))
    return out or NotApplicable("no holes", Limit(0.0))


def mount_clearance(c: _Ctx) -> list[Place]:
    """Walls in the mount between any two cuts of different holes (through hole or
    counterbore), between a hole and the socket, and between a counterbore or the socket and
    the block's faces. Sets that run into each other or into the socket give 0. Limits: the
    profile's walls."""
    m = c.mount
    socket = _Cyl("socket", 2, (0.0, 0.0, 0.0), c.cuts.socket_diameter / 2, 0.0, m.socket_depth)
    groups = [[socket]] + [_hole_pieces(h, c.cuts) for h in m.holes]
    out: list[Place] = []
    for i, ga in enumerate(groups):
        for gb in groups[i + 1 :]:
            for a in ga:
                for b in gb:
                    bound = _bbox_distance(a, b)
                    if out and bound >= min(p.value for p in out) and bound > c.limits.recommended_wall:
                        continue
                    out.append(Place(_convex_distance(a, b), f"{a.name} to {b.name}"))
    for g in groups:
        for piece in g:
            if piece.name.startswith("hole"):
                continue  # hole_edge rule
            out.append(Place(_face_ligament(piece, m.lo, m.hi), f"{piece.name} to the block face"))
    return out


def connector_hole_edge(c: _Ctx) -> list[Place]:
    """Wall between each connector hole (dowel-pin holes, tapped holes for the mount screws)
    and the plate's edges: ≥ 1 × the hole's nominal diameter, as for the mount."""
    k = c.connector
    out = []
    for h in k.holes:
        d = c.cuts.pin_hole_diameter if h.kind == "pin" else c.cuts.hole(h.diameter)
        piece = _Cyl(h.name, h.axis, tuple(float(x) for x in h.center), d / 2, h.lo, h.hi)
        lig = _face_ligament(piece, k.lo, k.hi)
        out.append(
            Place(lig, f"hole {h.name} (Ø{h.diameter:g})", limit=HOLE_EDGE_FACTOR * h.diameter, rank=lig / h.diameter)
        )
    return out


def connector_walls(c: _Ctx) -> list[Place]:
    """Walls of the connector: the plate around the pocket (at cut size), the pocket floor
    (plate thickness minus pocket depth) and each dowel-pin hole to the pocket. Limits: the
    profile's walls."""
    k = c.connector
    size = c.cuts.slide(k.pocket_size)
    plo = k.pocket_center[:2] - size / 2
    phi = k.pocket_center[:2] + size / 2
    edge = float(min(plo[0] - k.lo[0], plo[1] - k.lo[1], k.hi[0] - phi[0], k.hi[1] - phi[1]))
    out = [Place(edge, "pocket to the plate edge"), Place(float(k.size[2] - k.pocket_depth), "pocket floor")]
    for h in k.holes:
        if h.kind != "pin":
            continue
        r = c.cuts.pin_hole_diameter / 2
        dx = max(plo[0] - h.center[0], 0.0, h.center[0] - phi[0])
        dy = max(plo[1] - h.center[1], 0.0, h.center[1] - phi[1])
        out.append(Place(math.hypot(dx, dy) - r, f"hole {h.name} to the pocket"))
    return out


def template_clearance(c: _Ctx) -> list[Place]:
    """Gap between the mount's lower side (``axis_height − width/2`` in T) and the template's
    top edge (``template_edge``): the mount and the cylinder reach over the template along
    ``+z`` and must clear it (> 0)."""
    con = c.design.connector
    low = con.axis_height - c.mount.width / 2
    return [Place(low - con.template_edge, f"mount from y = {low:g}, template edge at y = {con.template_edge:g}")]


_HOLE_EDGE = "edge distance >= 1 x hole diameter (centre at 1.5 d)"

#: every design rule, in the report's order
RULES: tuple[Rule, ...] = (
    Rule("body.bore_wall", "wall under the deepest cut", ">=", bore_wall, _wall, "no cuts"),
    Rule(
        "groove.tool",
        "groove width",
        ">=",
        groove_tool,
        lambda c: Limit(c.limits.tool, source=c.limits.sources["tool"]),
    ),
    Rule(
        "groove.depth",
        "groove depth / tool",
        "<=",
        groove_depth,
        lambda c: Limit(c.limits.max_depth_ratio, c.limits.recommended_depth_ratio, c.limits.sources["depth"]),
        unit="x",
    ),
    Rule(
        "wires.crossing_clearance",
        "clearance between crossing wires",
        ">",
        crossing_clearance,
        lambda c: Limit(0.0, c.limits.tolerance, c.limits.sources["tolerance"]),
        "no crossings",
    ),
    Rule(
        "pockets.spacing",
        "wall between a pocket and its neighbours",
        ">=",
        pocket_spacing,
        _wall,
        "fewer than two cuts",
    ),
    Rule("grooves.spacing", "wall between grooves", ">=", groove_spacing, _wall, "fewer than two parallel grooves"),
    Rule(
        "pockets.retention",
        "pocket depth at its rim",
        ">",
        retention,
        _fixed(0.0, "a ball is held by its pocket only if its centre is below the rim"),
    ),
    Rule("body.envelope", "material to the end faces", ">=", envelope, _wall, "no cuts"),
    Rule(
        "mount.coverage",
        "gap between the socket rim and the nearest feature",
        ">",
        coverage,
        _fixed(0.0, "the mount must not cover a wire or bead (paper §II.A.3)"),
        "no features",
    ),
    Rule("mount.hole_edge", "hole wall to block edge", ">=", mount_hole_edge, _fixed(0.0, _HOLE_EDGE)),
    Rule("mount.hole_clearance", "wall between mount cuts", ">=", mount_clearance, _wall),
    Rule("connector.hole_edge", "hole wall to plate edge", ">=", connector_hole_edge, _fixed(0.0, _HOLE_EDGE)),
    Rule("connector.walls", "connector wall", ">=", connector_walls, _wall),
    Rule(
        "connector.template_clearance",
        "gap between the mount and the template's top edge",
        ">",
        template_clearance,
        _fixed(0.0, "the mount reaches over the template's top edge"),
    ),
)


def check_design(design: Design, profile: Profile = "cnc", features: Features | None = None) -> CheckReport:
    """Run every rule on ``design`` under ``profile``.

    Parameters
    ----------
    design : Design
        The design.
    profile : {"cnc", "fdm"}
        The manufacturing profile whose cut sizes and limits apply.
    features : Features or None
        The design's features, when already computed.

    Returns
    -------
    CheckReport
        Every rule's result, in :data:`RULES` order.
    """
    features = features if features is not None else compute_features(design)
    cuts = cut_sizes(design, profile)
    mount = mount_layout(design)
    ctx = _Ctx(
        design,
        profile,
        features,
        cuts,
        rule_limits(design, profile),
        body_cuts(design, features, cuts),
        mount,
        connector_layout(design, mount),
    )
    return CheckReport(design.name, design.source, profile, tuple(rule.evaluate(ctx) for rule in RULES), cuts.as_dict())
