"""Check an optimised design against its start on fresh poses and by the solver.

For each design: predicted p95 and worst 1σ 3-D errors over ``--poses`` fresh workspace
poses (seed ``--seed``, never used by a search), and a Monte-Carlo run of the robust solver
(no initial guess) on ``--images`` simulated images at 0.25 mm segmentation error, with the
Cramér–Rao bound at the same poses (the solver should attain it: actual / bound ≈ 1).
The same poses and noise seeds for every design (common random numbers).

Run: ``.venv/bin/python benchmarks/optimize_results.py ftrac_mini
ftrac_mini_opt [--poses 20000] [--images 1000] [--seed 4242]``
"""

from __future__ import annotations

import argparse
import tomllib

from _common import machine

from ftrac_design.analysis.subject import Subject, settings_for
from ftrac_design.design import load_design
from ftrac_design.design.presets import resolve_design
from ftrac_design.features import compute_features
from ftrac_design.optimize.verify import verify


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("designs", nargs="+", type=resolve_design, help="design files or presets")
    ap.add_argument("--poses", type=int, default=20_000)
    ap.add_argument("--images", type=int, default=1000)
    ap.add_argument("--seed", type=int, default=4242)
    args = ap.parse_args()
    print(f"machine: {machine()}")
    rows = []
    for path in args.designs:
        d = load_design(path)
        settings, _ = settings_for(Subject(compute_features(d), d.analysis, path))
        v = verify(tomllib.loads(path.read_text()), settings, args.poses, args.images, args.seed)
        rows.append((str(path), v))
    print(
        f"{args.poses} fresh poses (predicted 1σ, 3-D RMS, p95 / worst); solver on {args.images} images "
        f"(RMS of the 3-D error, and the bound at the same poses)"
    )
    print(
        f"{'design':34s} {'t p95 mm':>9s} {'t worst':>8s} {'r p95 °':>8s} {'r worst':>8s} {'solved':>7s} "
        f"{'t RMS mm':>9s} {'bound':>7s} {'r RMS °':>8s} {'bound':>7s}"
    )
    for name, v in rows:
        p, s = v["predicted"], v["solver"]
        print(
            f"{name:34s} {p['translation_p95_mm']:9.4f} {p['translation_worst_mm']:8.4f} "
            f"{p['rotation_p95_deg']:8.4f} {p['rotation_worst_deg']:8.4f} {s['solved']:4d}/{s['images']:<4d}"
            f"{s['translation_rms_mm']:8.4f} {s['predicted_translation_rms_mm']:7.4f} "
            f"{s['rotation_rms_deg']:8.4f} {s['predicted_rotation_rms_deg']:7.4f}"
        )
    if len(rows) > 1:
        p0, s0 = rows[0][1]["predicted"], rows[0][1]["solver"]
        for name, v in rows[1:]:
            p, s = v["predicted"], v["solver"]
            print(
                f"{name} vs {rows[0][0]}: predicted p95 translation "
                f"{p['translation_p95_mm'] / p0['translation_p95_mm'] - 1:+.1%}, rotation "
                f"{p['rotation_p95_deg'] / p0['rotation_p95_deg'] - 1:+.1%}; solver RMS translation "
                f"{s['translation_rms_mm'] / s0['translation_rms_mm'] - 1:+.1%}, rotation "
                f"{s['rotation_rms_deg'] / s0['rotation_rms_deg'] - 1:+.1%}"
            )


if __name__ == "__main__":
    main()
