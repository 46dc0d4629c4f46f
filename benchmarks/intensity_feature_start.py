"""The intensity path from the feature path's poses, on the images of ``track_accuracy.py``
(same seed, same workspace sample): a quicker A/B than ``track_accuracy.py --intensity``.

The first run tracks the images and caches (image, feature pose, true pose) in
``/tmp/ftrac_intensity_feature_start`` (or ``--cache``); later runs refine from the cache.
Prints per axis the efficiency against the pixel bound (as ``track_accuracy.py``), the
start's distance in bound-σ (Mahalanobis), the background model chosen, renders/iterations,
CPU per refinement; ``--detail`` one line per image. Options of ``refine_intensity`` as
``key=value`` (Python literals), e.g. ``scales=(1.0,0.0)`` (a fixed two-pass schedule, 1 px then
unsmoothed, instead of "auto").

    .venv/bin/python benchmarks/intensity_feature_start.py ftrac_mini 30
    .venv/bin/python benchmarks/intensity_feature_start.py ftrac_2005 30 --detail
"""

from __future__ import annotations

import argparse
import ast
import pickle
from pathlib import Path

import numpy as np
from intensity_common import Judge, efficiency
from intensity_common import pose_errors as pose_error6
from tqdm import tqdm

from ftrac_design.design import load_design
from ftrac_design.features import compute_features
from ftrac_design.pose import Camera
from ftrac_design.pose.simulate import Workspace, pose_errors
from ftrac_design.segment.pipeline import track_image
from ftrac_design.xray import ImagingModel, anatomy, render


def cases(name, n, seed, background, cache: Path):
    """(raw image, feature R, feature t, true R, true t, anatomy or None) for the right
    feature-path poses among ``track_accuracy.run``'s n images (same sample; cached)."""
    f = cache / f"{name}_{n}_{seed}_{int(background)}.pkl"
    if f.exists():
        return pickle.loads(f.read_bytes())
    design = load_design(name)
    features = compute_features(design)
    cam, imaging = Camera(), ImagingModel()
    out, k = [], 0
    N = n
    R, t = Workspace().sample(N, features.nominal_beam_direction, np.random.default_rng(seed))
    with tqdm(total=n, desc=f"tracking {name}", leave=False) as bar:
        while k < N:
            rng = np.random.default_rng(seed * 1000 + k)
            bg = anatomy(seed=seed * 1000 + k) if background else None
            rad = render(features, R[k], t[k], cam, imaging, rng=rng, background=bg)
            p = track_image(rad.raw, features, cam).pose
            k += 1
            bar.update()
            if not p.converged:
                continue
            dr, dt = pose_errors(p.rotation, p.translation_mm, R[k - 1], t[k - 1])
            if np.degrees(np.linalg.norm(dr)) > 1.0 or np.linalg.norm(dt) > 5.0:
                continue
            out.append((rad.raw, p.rotation, p.translation_mm, R[k - 1], t[k - 1], bg))
    cache.mkdir(parents=True, exist_ok=True)
    f.write_bytes(pickle.dumps(out))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("name")
    ap.add_argument("n", type=int)
    ap.add_argument("options", nargs="*", help="refine_intensity options key=value")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--anatomy", action="store_true")
    ap.add_argument("--detail", action="store_true")
    ap.add_argument(
        "--start",
        choices=("features", "truth"),
        default="features",
        help="refine from the feature path's pose (default) or from the true pose (a check)",
    )
    ap.add_argument("--cache", type=Path, default=Path("/tmp/ftrac_intensity_feature_start"))
    a = ap.parse_args()
    opts = {"coarse_scales": (1.0,)}  # as track --refine intensity
    for o in a.options:
        k, v = o.split("=", 1)
        opts[k] = ast.literal_eval(v)
    design = load_design(a.name)
    features = compute_features(design)
    cam, imaging = Camera(), ImagingModel()
    data = cases(a.name, a.n, a.seed, a.anatomy, a.cache)
    z_i, z_f, cpu, its, worse, models, dist = [], [], [], [], 0, {}, []
    for j, (raw, Rf, tf, Rt, tt, bg) in enumerate(tqdm(data, desc="refining", leave=False)):
        judge = Judge(features, cam, imaging, Rt, tt, background=bg)
        R0, t0 = (Rf, tf) if a.start == "features" else (Rt, tt)
        res, zi, _, (_, c) = judge.refine(raw, R0, t0, **opts)
        e0 = pose_error6(Rf, tf, Rt, tt)
        b = judge.spline if res.background_model == "spline" else judge.quad
        d0 = float(np.sqrt(e0 @ b.information @ e0)) if hasattr(b, "information") else float(np.linalg.norm(e0 / b.std))
        zf = judge.z(Rf, tf, res.background_model)
        z_i.append(zi), z_f.append(zf), cpu.append(c), its.append(res.iterations), dist.append(d0)
        worse += res.cost_end > res.cost_start
        models[res.background_model] = models.get(res.background_model, 0) + 1
        if a.detail:
            dof = max(res.roi[2] * res.roi[3] - 6 - res.n_nuisance, 1)
            zq0 = np.sqrt(np.mean(judge.z_quad(Rf, tf) ** 2))
            zq1 = np.sqrt(np.mean(judge.z_quad(res.rotation, res.translation_mm) ** 2))
            print(
                f"{j:3d} χ²/dof {res.cost_end / dof:5.2f} RMS z_quad start {zq0:6.1f} end {zq1:6.1f}  "
                f"start {d0:7.1f}σ |z_start|max {np.abs(zf).max():7.1f}  end z "
                + " ".join(f"{x:+6.2f}" for x in zi)
                + f"  {res.background_model:8s} it {res.iterations:2d} "
                f"{1e3 * c:5.0f} ms {res.message}"
            )
    e, lo, hi = efficiency(z_i)
    print(
        f"{a.name}{' + anatomy' if a.anatomy else ''}, {len(data)} feature-path starts, options {opts}; models {models}"
    )
    print(
        "  efficiency, intensity: "
        + " ".join(f"{x:5.2f}" for x in e)
        + "  (95 %: "
        + " ".join(f"{x:.2f}–{y:.2f}" for x, y in zip(lo, hi))
        + ")"
    )
    print("  RMS z, intensity     : " + " ".join(f"{x:5.2f}" for x in np.sqrt(np.mean(np.square(z_i), 0))))
    zi = np.array(z_i)
    print(
        "  mean z ± s.e.        : "
        + " ".join(f"{m:+.2f}±{s:.2f}" for m, s in zip(zi.mean(0), zi.std(0, ddof=1) / np.sqrt(len(zi))))
    )
    print("  efficiency, features : " + " ".join(f"{x:.3f}" for x in efficiency(z_f)[0]))
    print(
        f"  start distance (bound σ, Mahalanobis): median {np.median(dist):.1f}, max {np.max(dist):.1f}; "
        f"iterations median {np.median(its):.0f} max {np.max(its)}; CPU median {1e3 * np.median(cpu):.0f} ms "
        f"max {1e3 * np.max(cpu):.0f} ms; ended above start: {worse}"
    )


if __name__ == "__main__":
    main()
