"""How well the image path's curve σ describes the wires' contour errors, by a curve's degrees
of freedom — and the prior that pools a short curve's scatter with its balls'.

Images of the realism conditions (``track_realism.make_image``: clean and the 10 realistic
conditions) are tracked with the defaults; on every converged pose, each line and ellipse the
pose used gives its contour points' RMS distance from the true curve (the exact projection; the
distance along the normal for a line, the Sampson distance for a conic, px) beside what the
noise model reads: the residual sum of squares and degrees of freedom of the curve's own fit and
the labelling's median ball fit σ s̃. The model's random σ per contour point is

    σ² = (rss + ν₀ (κ s̃)²) / (dof + ν₀)

(``TrackOptions.curve_prior_dof`` ν₀, ``curve_prior_scale`` κ); the printout gives, per bin of
degrees of freedom, the median and 90th percentile of (RMS distance from the truth) / σ without
the prior (ν₀ = 0) and with the defaults — 1 when calibrated; the systematic offsets of the
contours are in the distance and not in σ, so well-measured curves read a little above 1 — and
κ's evidence: a well-measured curve's (dof ≥ 5) scatter over its balls' median σ, by preset and
curve type.

    .venv/bin/python benchmarks/curve_sigma_fit.py --seed 21 --n 10
    .venv/bin/python benchmarks/curve_sigma_fit.py --seed 2095 --n 6      # held out
"""

from __future__ import annotations

import argparse
import os
from concurrent.futures import ProcessPoolExecutor

import _common  # noqa: F401  (puts the checkout first on sys.path)
import numpy as np
from tqdm import tqdm
from track_realism import make_image, preset_features

from ftrac_design.pose.fitting import fit_conic, fit_line
from ftrac_design.segment import TrackOptions, track_image
from ftrac_design.xray.scenario import CONDITIONS
from ftrac_design.xray.truth import projected_features

CONDS = ("clean",) + CONDITIONS
BINS = ((0, 2), (2, 5), (5, 10), (10, 10**6))


def _distance(kind: str, truth: dict, pts: np.ndarray) -> np.ndarray:
    """Each contour point's distance (px) from the true curve ``truth`` (``projected`` entry)."""
    if kind == "line":
        a, b = np.asarray(truth["start"], float), np.asarray(truth["end"], float)
        n = np.array([a[1] - b[1], b[0] - a[0]]) / np.linalg.norm(b - a)
        return (pts - a) @ n
    A, B, C, D, E, F = truth["conic"]
    u, v = pts[:, 0], pts[:, 1]
    val = A * u * u + B * u * v + C * v * v + D * u + E * v + F
    return val / np.hypot(2 * A * u + B * v + D, B * u + 2 * C * v + E)


def curves(task: tuple) -> list[dict]:
    """The curves of one image's converged pose: kind, preset, own fit's rss and dof, RMS
    distance from the truth (px) and the labelling's median ball fit σ (px); [] otherwise."""
    preset, cond, k, seed, n = task
    features = preset_features(preset)
    img, R, t, cam, _ = make_image(preset, cond, k, seed, n)
    res = track_image(img, features, cam, TrackOptions())
    obs, b = res.observation, res.beads
    if not res.pose.converged or obs is None or b is None or not obs.points:
        return []
    idx = [int(np.argmin(np.linalg.norm(b.uv - np.asarray(uv), axis=1))) for uv in obs.points.values()]
    s_ball = float(np.median(b.sigma_px[idx]))
    truth = projected_features(features, R, t, cam)
    out = []
    for kind, store, fitter in (("line", obs.lines, fit_line), ("ellipse", obs.ellipses, fit_conic)):
        for fid, c in store.items():
            pts = np.asarray(c.points, float)
            f = fitter(pts)
            d = _distance(kind, truth[kind + "s"][fid], pts)
            out.append(
                {"preset": preset, "kind": kind, "rss": float(f.rss), "dof": int(f.dof), "s_ball": s_ball}
                | {"true_rms": float(np.sqrt(np.mean(d * d)))}
            )
    return out


def model_sigma(rows: list[dict], nu0: float, kappa: float) -> np.ndarray:
    """The model's random σ per contour point (px) of each curve, with the prior (ν₀, κ)."""
    rss = np.array([r["rss"] for r in rows])
    dof = np.array([r["dof"] for r in rows], float)
    prior = np.array([(kappa * r["s_ball"]) ** 2 for r in rows])
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.sqrt((rss + nu0 * prior) / (dof + nu0))


def report(rows: list[dict], name: str, nu0: float, kappa: float) -> None:
    """One line: (RMS distance from the truth) / σ, median and 90th percentile per dof bin."""
    q = np.array([r["true_rms"] for r in rows]) / model_sigma(rows, nu0, kappa)
    dof = np.array([r["dof"] for r in rows])
    parts = []
    for lo, hi in BINS:
        v = q[(dof >= lo) & (dof < hi) & np.isfinite(q)]
        label = f"dof {lo}–{hi - 1}" if hi < 10**6 else f"dof ≥ {lo}"
        parts.append(
            f"{label} ({len(v)}): {np.median(v):.2f} / {np.percentile(v, 90):.2f}" if len(v) else f"{label}: —"
        )
    print(f"  {name:34s} " + "   ".join(parts))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed", type=int, default=21)
    ap.add_argument("--n", type=int, default=10, help="images per preset and condition")
    ap.add_argument("--presets", nargs="+", default=["ftrac_2005", "ftrac_mini"])
    ap.add_argument("--workers", type=int, default=min(2, os.cpu_count() or 1))
    args = ap.parse_args()
    tasks = [(p, c, k, args.seed, args.n) for p in args.presets for c in CONDS for k in range(args.n)]
    rows: list[dict] = []
    with ProcessPoolExecutor(args.workers) as pool:
        for out in tqdm(pool.map(curves, tasks, chunksize=2), total=len(tasks), desc="track", mininterval=10):
            rows += out
    if not rows:
        raise SystemExit("curve_sigma_fit: no converged pose with a curve")
    opts = TrackOptions()
    print(f"curve_sigma_fit: seed {args.seed}, {args.n} per condition, {len(rows)} curves of converged poses")
    print("  (RMS distance from the true curve) / model σ, median / 90th percentile, by the curve's dof:")
    report(rows, "own scatter (ν₀ = 0)", 0.0, 0.0)
    report(
        rows,
        f"with the prior (ν₀ = {opts.curve_prior_dof:g}, κ = {opts.curve_prior_scale:g})",
        opts.curve_prior_dof,
        opts.curve_prior_scale,
    )
    print("  a well-measured curve's (dof ≥ 5) scatter over its balls' median σ:")
    for preset in args.presets:
        for kind in ("line", "ellipse"):
            sel = [r for r in rows if r["preset"] == preset and r["kind"] == kind and r["dof"] >= 5]
            if sel:
                k = np.array([np.sqrt(r["rss"] / r["dof"]) / r["s_ball"] for r in sel])
                print(
                    f"    {preset:10s} {kind:7s} ({len(sel):3d}): median {np.median(k):.2f}, "
                    f"10th–90th percentile {np.percentile(k, 10):.2f}–{np.percentile(k, 90):.2f}"
                )


if __name__ == "__main__":
    main()
