"""``--refine intensity`` on images as C-arms hand them over: what the refinement does to the
feature path's poses, and what a fit that walks away costs.

Each image of ``track_realism.py`` (same seeds, same images) is tracked with the default options;
each converged pose is refined twice by :func:`ftrac_design.intensity.refine_track_result`,
interleaved in one process: with the fit free to walk wherever its objective leads
(``within=None``: the baseline) and with the default, which stops a fit at the first step that
leaves the feature pose's own covariance (a pose there would not be taken). Per condition it
prints the poses right (≤ 1° and ≤ 3 mm) inside their covariance, right but with the truth
beyond χ²₆ 25.7 under it ("loose"), far but honest, and confidently wrong (far, and χ²₆ > 25.7)
before refining and after each refinement, how many
refinements were taken, and the refinement's time per image (median, largest, sum) with the
ratio of the sums.

    .venv/bin/python benchmarks/refine_realism.py --seed 2135 --conditions blur-2px
    .venv/bin/python benchmarks/refine_realism.py --presets ftrac_2005 --n 20 --seed 7 --cache outputs/realism_cache
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import _common
import numpy as np
from track_realism import ALL, CHI2_6, WRONG_DEG, WRONG_MM, make_image, preset_features

from ftrac_design.images.distortion import undistort_image
from ftrac_design.intensity import refine_track_result
from ftrac_design.pose.simulate import pose_errors
from ftrac_design.segment import TrackOptions, track_image

WAYS = ("before", "free", "held")


def outcome(pose, R: np.ndarray, t: np.ndarray) -> str:
    """Right inside its covariance ("right"), right with the truth beyond χ²₆ 25.7 under it
    ("loose"), far but inside it ("far") or confidently wrong ("wrong")."""
    dr, dt = pose_errors(pose.rotation, pose.translation_mm, R, t)
    e = np.r_[dr, dt]
    chi2 = float(e @ np.linalg.solve(pose.covariance, e)) if pose.covariance is not None else math.inf
    if math.degrees(float(np.linalg.norm(dr))) <= WRONG_DEG and float(np.linalg.norm(dt)) <= WRONG_MM:
        return "loose" if chi2 > CHI2_6 else "right"
    return "wrong" if chi2 > CHI2_6 else "far"


def one(preset: str, condition: str, k: int, seed: int, n: int, cache: Path | None) -> dict | None:
    """The outcomes and refinement times of one image, or None where the feature path gave no pose."""
    features = preset_features(preset)
    img, R, t, cam, model = make_image(preset, condition, k, seed, n, cache)
    opts = TrackOptions()
    if model is not None:
        # corrected with its model, as `track --distortion` does
        img, opts = undistort_image(img, model), TrackOptions(distortion_prior_mm=0.0)
    res = track_image(img, features, cam, opts)
    if not res.pose.converged:
        return None
    row = {"before": outcome(res.pose, R, t)}
    for way, extra in (("free", {"within": None}), ("held", {})):
        t0 = time.perf_counter()
        out = refine_track_result(img, features, cam, res, **extra)
        row[way + "_s"] = time.perf_counter() - t0
        row[way] = outcome(out.pose, R, t)
        row[way + "_taken"] = bool(out.diagnostics.intensity.taken)
    return row


def summary(condition: str, rows: list[dict]) -> str:
    """One table row: outcomes before and after each way, refinements taken, times."""
    cells = [condition, str(len(rows))]
    for way in WAYS:
        c = {o: sum(r[way] == o for r in rows) for o in ("right", "loose", "far", "wrong")}
        cells.append(f"{c['right']} / {c['loose']} / {c['far']} / {c['wrong']}")
    for way in ("free", "held"):
        cells.append(str(sum(r[way + "_taken"] for r in rows)))
    for way in ("free", "held"):
        s = np.array([r[way + "_s"] for r in rows]) if rows else np.zeros(1)
        cells.append(f"{1000 * np.median(s):.0f} / {1000 * s.max():.0f} / {s.sum():.1f} s")
    free = sum(r["free_s"] for r in rows)
    cells.append(f"×{sum(r['held_s'] for r in rows) / free:.2f}" if free > 0 else "–")
    return "| " + " | ".join(cells) + " |"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--presets", nargs="+", default=["ftrac_2005"])
    ap.add_argument("--conditions", nargs="+", default=[c for c in ALL if c != "distortion"], choices=ALL)
    ap.add_argument("--n", type=int, default=20, help="images per condition")
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--cache", type=Path, default=None, help="folder keeping the images between runs")
    a = ap.parse_args()
    print(f"machine: {_common.machine()}; seed {a.seed}, {a.n} per condition")
    head = (
        "| condition | poses | before: right / loose / far / wrong | free: right / loose / far / wrong "
        "| held: right / loose / far / wrong "
        "| taken free | taken held | free: median ms / max ms / sum | held: median ms / max ms / sum | held / free |"
    )
    for preset in a.presets:
        print(f"\n{preset}\n\n{head}\n" + "|---" * head.count(" | ") + "|---|")
        for condition in a.conditions:
            rows = [one(preset, condition, k, a.seed, a.n, a.cache) for k in range(a.n)]
            print(summary(condition, [r for r in rows if r is not None]), flush=True)


if __name__ == "__main__":
    main()
