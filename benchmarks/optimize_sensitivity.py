"""What binds an optimised design: a constrained local polish, and each constraint relaxed.

From ``--design`` (an optimised layout, e.g. the preset ``ftrac_mini_opt``), mapped into the
search space of ``--start`` (the preset the search began from) and ``--space``, COBYLA
(``scipy.optimize.minimize``; derivative-free, inequality constraints) minimises the p95
translation ratio t/t₀ on the search's own fixed pose sample, subject to every CNC rule
margin ≥ 0, the ellipse view-angle margin ≥ 0 and r/r₀ ≤ 1 — the ``translation`` objective
of ``ftrac-design optimize`` as a smooth constrained problem. Then each binding constraint
is relaxed by a little (a rule's normalised margin may go to −``--relax``: 0.05 mm for a
1 mm wall or a "> 0" gap; the view angle by 30 %; rotation by 1 %) and the polish is repeated:
what each would buy. If nothing buys much, the design is a local optimum that only a
different layout (another basin) can beat.

Run: ``.venv/bin/python benchmarks/optimize_sensitivity.py [--design ftrac_mini_opt]
[--start ftrac_mini] [--space ftrac_mini_layout] [--seed 1]``
(~2 min on one core).
"""

from __future__ import annotations

import argparse
import time
import tomllib

import numpy as np
from _common import machine
from scipy.optimize import minimize

from ftrac_design.design.loader import parse_design
from ftrac_design.design.presets import resolve_design, resolve_space
from ftrac_design.errors import InputError
from ftrac_design.features import compute_features
from ftrac_design.manufacture.rules import check_design
from ftrac_design.optimize.evaluate import evaluate_candidate, min_ellipse_view_deg, rule_margins, score_figures
from ftrac_design.optimize.setup import prepare
from ftrac_design.optimize.space import _line_geometry

#: "> 0" rules need a hair above 0
STRICT = (
    "cnc:mount.coverage",
    "cnc:wires.crossing_clearance",
    "cnc:pockets.retention",
    "cnc:connector.template_clearance",
)


def unit_point(space, data: dict) -> np.ndarray:
    """Unit-cube point of design ``data`` in ``space`` (azimuths and bead fractions as the space has them)."""
    geo = _line_geometry(data)
    x = []
    for p in space.parameters:
        _, ident, key = p.key.split(".", 2)
        if key.startswith("beads"):
            v = geo[ident]["fractions"][int(key[6:-1])]
        else:
            items = data["ellipses"] if p.key.startswith("ellipses") else data["lines"]
            v = next(it for it in items if it["id"] == ident)[key]
        x.append(p.unit(v))
    return np.array(x)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--design", type=resolve_design, default="ftrac_mini_opt", help="a design file or a preset")
    ap.add_argument("--start", type=resolve_design, default="ftrac_mini", help="a design file or a preset")
    ap.add_argument("--space", type=resolve_space, default="ftrac_mini_layout", help="a space file or a shipped space")
    ap.add_argument("--seed", type=int, default=1, help="the search's seed (its pose sample)")
    ap.add_argument("--relax", type=float, default=0.05, help="how far a rule margin may go below 0")
    ap.add_argument("--maxiter", type=int, default=300)
    args = ap.parse_args()
    print(f"machine: {machine()} (loaded by other jobs)")
    space, settings = prepare(args.start, args.space, seed=args.seed)
    ref = evaluate_candidate(space.base, settings)["figures"]
    cache: dict = {}

    def ev(x: np.ndarray) -> tuple[float, float, dict]:
        key = tuple(np.round(x, 12))
        if key not in cache:
            try:
                d = parse_design(space.candidate(x), "candidate")
            except InputError:  # the schema refuses it: every constraint badly broken
                cache[key] = (2.0, 2.0, None)
                return cache[key]
            f = compute_features(d)
            m, _ = rule_margins(check_design(d, "cnc", f))
            lim = settings.min_ellipse_view_deg
            m["view"] = (min_ellipse_view_deg(f, settings.analysis) - lim) / max(lim, 1.0)
            fig = score_figures(f, settings.analysis)
            cache[key] = (
                fig["translation_p95_mm"] / ref["translation_p95_mm"],
                fig["rotation_p95_deg"] / ref["rotation_p95_deg"],
                m,
            )
        return cache[key]

    x0 = unit_point(space, tomllib.loads(args.design.read_text()))
    t0, r0, m0 = ev(x0)
    names = sorted(m0)
    binding = sorted((v, k) for k, v in m0.items())[:4]
    print(
        f"{args.design.name} on the seed-{args.seed} search sample ({settings.analysis.poses} poses): "
        f"t/t0 {t0:.5f}, r/r0 {r0:.5f}"
    )
    print("closest constraints (normalised margin): " + ", ".join(f"{k} {v:+.4f}" for v, k in binding))

    def polish(relaxed: str | None) -> tuple[float, float, int]:
        n0 = len(cache)
        lims = {k: (1e-6 if k in STRICT else 0.0) for k in names}
        if relaxed in lims:
            lims[relaxed] = -(0.3 if relaxed == "view" else args.relax)
        r_max = 1.01 if relaxed == "rotation" else 1.0
        cons = [{"type": "ineq", "fun": (lambda x, k=k: (ev(x)[2] or {}).get(k, -1.0) - lims[k])} for k in names]
        cons.append({"type": "ineq", "fun": lambda x: r_max - ev(x)[1]})
        res = minimize(
            lambda x: ev(x)[0],
            x0,
            method="COBYLA",
            constraints=cons,
            bounds=[(0.0, 1.0)] * len(x0),
            options={"rhobeg": 0.02, "maxiter": args.maxiter, "tol": 1e-6},
        )
        t, r, _ = ev(res.x)
        return (t, r, len(cache) - n0) if res.maxcv < 1e-6 else (float("nan"), float("nan"), len(cache) - n0)

    print(f"{'relaxed':34s} {'by':>12s} {'t/t0':>9s} {'r/r0':>8s} {'gain, points':>13s} {'evals':>6s}")
    rows = (
        [(None, "")]
        + [(k, f"margin -{args.relax:g}") for _, k in binding if k != "view"]
        + [("view", "30 %"), ("rotation", "to 1.01")]
    )
    for k, by in rows:
        tic = time.perf_counter()
        t, r, n = polish(k)
        print(
            f"{k or 'nothing (polish only)':34s} {by:>12s} {t:9.5f} {r:8.5f} {100 * (t0 - t):13.3f} {n:6d}"
            f"   ({time.perf_counter() - tic:.0f} s)",
            flush=True,
        )


if __name__ == "__main__":
    main()
