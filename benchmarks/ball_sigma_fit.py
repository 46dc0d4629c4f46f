"""Where each ball's σ comes from: the balls of right poses against the truth.

Images of the realism conditions (``track_realism.make_image``: clean, raw, log, display,
shutters, dose, anatomy, blur, seeds and needles, corrected pincushion) are tracked with the
defaults; on each pose that is right (≤ 1° and ≤ 3 mm), every ball the pose used gives its
centre's error against its exact projection (px) beside what its own fit said: the fit's σ
sᵢ, its radius rᵢ, its apparent size mᵢ = √(rᵢ²/5 + blurᵢ²) (the blurred ball's second
moment per axis, px), the median radius r̃ over the pose's balls and the
``point_size_quantile`` m_q of their sizes. The per-axis σ model

    σᵢ² = (a sᵢ)² + (b |rᵢ − r̃|)² + (c |mᵢ − m_q|)² + σ_sys²

is then fitted by maximum likelihood (2-D Gaussian errors; σ_sys held at
``TrackOptions.sys_point_px``) and printed beside the defaults (``point_fit_scale``,
``point_radius_scale``, ``point_size_scale``), with how well each model explains the errors: the per-axis RMS of
the normalised errors (1 when calibrated) and the share beyond χ²₂ = 13.8 (p = 10⁻³; 0.1 %
when Gaussian), for the defaults, the fitted values, the same model with the median size as
the reference (refitted), and one σ for every ball (the median ball's: what the noise model
gave before each ball had its own). The floor and the cap of
:func:`ftrac_design.segment.noise.measured_noise` are left out here.

    .venv/bin/python benchmarks/ball_sigma_fit.py                  # tuning seed 21, 20 per condition
    .venv/bin/python benchmarks/ball_sigma_fit.py --seed 2042 --n 10   # a held-out check
    .venv/bin/python benchmarks/ball_sigma_fit.py --seed 2121 --fitted 1.0 0.23 0.81   # another's fit, held out
"""

from __future__ import annotations

import argparse
import math
from multiprocessing import Pool
from pathlib import Path

import _common  # noqa: F401  (puts the checkout first on sys.path)
import numpy as np
from scipy.optimize import minimize
from tqdm import tqdm
from track_realism import PRESETS, WRONG_DEG, WRONG_MM, make_image, preset_features

from ftrac_design.images.distortion import undistort_image
from ftrac_design.pose.simulate import pose_errors
from ftrac_design.segment import TrackOptions, track_image
from ftrac_design.xray.scenario import CONDITIONS
from ftrac_design.xray.truth import projected_features

CONDS = ("clean",) + CONDITIONS + ("distortion-corrected",)


def balls(task: tuple) -> list[dict]:
    """The balls of one image's pose if it is right: squared error (px²), fit σ, radius's
    departure from the pose's median ball's, size's departure from the pose's balls' size
    quantile and median, and the median fit σ (px); [] otherwise."""
    preset, cond, k, seed, n, cache = task
    features = preset_features(preset)
    img, R, t, cam, model = make_image(preset, cond, k, seed, n, cache)
    opts = TrackOptions()
    if cond == "distortion-corrected":
        img, opts = undistort_image(img, model), TrackOptions(distortion_prior_mm=0.0)
    res = track_image(img, features, cam, opts)
    p = res.pose
    if not p.converged or res.observation is None or res.beads is None:
        return []
    dr, dt = pose_errors(p.rotation, p.translation_mm, R, t)
    if math.degrees(float(np.linalg.norm(dr))) > WRONG_DEG or float(np.linalg.norm(dt)) > WRONG_MM:
        return []
    truth = projected_features(features, R, t, cam)["points"]
    b = res.beads
    which = {}
    for fid, uv in res.observation.points.items():
        d = np.linalg.norm(b.uv - np.asarray(uv), axis=1)
        if d.min() < 1e-6:
            which[fid] = int(np.argmin(d))
    if not which:
        return []
    r_med = float(np.median([b.radius[j] for j in which.values()]))
    size = np.sqrt(b.second_moment_px2)
    sizes = [size[j] for j in which.values()]
    m_ref, m_med = float(np.quantile(sizes, opts.point_size_quantile)), float(np.median(sizes))
    out = []
    for fid, j in which.items():
        e = np.asarray(res.observation.points[fid], float) - np.asarray(truth[fid], float)
        out.append(
            {
                "preset": preset,
                "e2": float(e @ e),
                "s": float(b.sigma_px[j]),
                "dr": abs(float(b.radius[j]) - r_med),
                "dm": abs(float(size[j]) - m_ref),
                "dm_median": abs(float(size[j]) - m_med),
                "median_s": float(np.median([b.sigma_px[i] for i in which.values()])),
            }
        )
    return out


def model_var(scales: tuple[float, float, float], sys_px: float, get: dict[str, np.ndarray]) -> np.ndarray:
    """Per-axis variance (px²) of the σ model with scales (a, b, c) on the fit's σ, the radius's
    and the size's departures (``get["s"]``, ``["dr"]``, ``["dm"]``) and systematic ``sys_px``."""
    a, b, c = scales
    return (a * get["s"]) ** 2 + (b * get["dr"]) ** 2 + (c * get["dm"]) ** 2 + sys_px**2


def fit(e2: np.ndarray, get: dict[str, np.ndarray], sys_px: float) -> tuple[float, float, float]:
    """Maximum-likelihood (a, b, c) for 2-D Gaussian errors of squared length ``e2``."""

    def nll(p):
        v = model_var(tuple(abs(p)), sys_px, get)
        return float(np.sum(np.log(v) + e2 / (2 * v)))

    r = minimize(nll, [1.0, 0.3, 0.3], method="Nelder-Mead", options={"xatol": 1e-4, "fatol": 1e-6})
    return tuple(abs(float(x)) for x in r.x)


def report(name: str, e2: np.ndarray, v: np.ndarray) -> None:
    """Normalised errors' per-axis RMS and the share beyond p = 10⁻³."""
    z2 = e2 / v
    rms = math.sqrt(float(np.mean(z2)) / 2)
    print(f"  {name:44s} per-axis RMS {rms:5.2f} σ   beyond p = 1e-3: {np.mean(z2 > 13.8):6.2%}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=20, help="images per condition and preset")
    ap.add_argument("--seed", type=int, default=21)
    ap.add_argument("--presets", nargs="+", default=list(PRESETS), choices=PRESETS)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--cache", type=Path, default=None, help="folder of track_realism's cached images")
    ap.add_argument(
        "--fitted",
        type=float,
        nargs=3,
        default=None,
        metavar=("A", "B", "C"),
        help="also report these scales (another seed's fit, judged on this one)",
    )
    args = ap.parse_args()
    tasks = [(p, c, k, args.seed, args.n, args.cache) for p in args.presets for c in CONDS for k in range(args.n)]
    rows: list[dict] = []
    with Pool(args.workers) as pool:
        for out in tqdm(pool.imap_unordered(balls, tasks), total=len(tasks), desc="track"):
            rows += out
    if not rows:
        raise SystemExit("ball_sigma_fit: no right pose to measure")
    get = {k: np.array([r[k] for r in rows]) for k in ("e2", "s", "dr", "dm", "dm_median", "median_s")}
    by_median = {**get, "dm": get["dm_median"]}
    opts = TrackOptions()
    sys_px = opts.sys_point_px
    fitted = fit(get["e2"], get, sys_px)
    fitted_median = fit(get["e2"], by_median, sys_px)
    defaults = (opts.point_fit_scale, opts.point_radius_scale, opts.point_size_scale)
    print(f"ball_sigma_fit: seed {args.seed}, {args.n} per condition, {len(rows)} balls of right poses")
    print("  fitted (σ_sys = {} px held):  a = {:.3f}  b = {:.3f}  c = {:.3f}".format(sys_px, *fitted))
    print("  defaults:                     a = {:.3f}  b = {:.3f}  c = {:.3f}".format(*defaults))
    report("one σ for every ball (median fit σ, σ_sys)", get["e2"], get["median_s"] ** 2 + sys_px**2)
    report("each ball its own, without the size (c = 0)", get["e2"], model_var((*defaults[:2], 0.0), sys_px, get))
    report("each ball its own, defaults", get["e2"], model_var(defaults, sys_px, get))
    report("each ball its own, defaults, median size", get["e2"], model_var(defaults, sys_px, by_median))
    report("each ball its own, fitted here", get["e2"], model_var(fitted, sys_px, get))
    print("  the median size as the reference, fitted: a = {:.3f}  b = {:.3f}  c = {:.3f}".format(*fitted_median))
    report("each ball its own, median size, fitted here", get["e2"], model_var(fitted_median, sys_px, by_median))
    if args.fitted:
        given = tuple(args.fitted)
        report("each ball its own, --fitted {} {} {}".format(*given), get["e2"], model_var(given, sys_px, get))
    for preset in args.presets:
        m = np.array([r["preset"] == preset for r in rows])
        if m.any():
            sub = {k: v[m] for k, v in get.items()}
            report(f"{preset} ({m.sum()} balls), defaults", get["e2"][m], model_var(defaults, sys_px, sub))


if __name__ == "__main__":
    main()
