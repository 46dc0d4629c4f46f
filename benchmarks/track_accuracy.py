"""Image path accuracy: rendered workspace radiographs → track → errors.

For each preset: N workspace poses (SPEC §1) rendered by the xray simulator at the default
imaging model, with and without the anatomy-like background; each image tracked with no
initial guess. Reports identification failures (a converged pose > 1° or > 5 mm off: a
*wrong* confident answer — target 0), images not converged (with reasons), segmentation
residuals per feature type in mm at the detector (beads: centre error; lines, ellipses:
distance of each contour point to the true projected curve) beside the paper's Table V
(0.43 / 0.19 / 0.13 mm; target ≤ 0.1 mm), the ellipse shrinkage (mean signed distance of
the ellipse points, + = inside) with and without the modelled-body subtraction, and the
pose error per camera axis beside the solver's own covariance.

    .venv/bin/python benchmarks/track_accuracy.py --n-2005 1000 --n-mini 300 --n-nine 300
"""

from __future__ import annotations

import argparse
import time
from collections import Counter
from pathlib import Path

import numpy as np
from tqdm import tqdm

from ftrac_design.design import load_design
from ftrac_design.features import compute_features
from ftrac_design.pose import Camera
from ftrac_design.pose.fitting import conic_matrix
from ftrac_design.pose.simulate import Workspace, pose_errors
from ftrac_design.segment.pipeline import track_image
from ftrac_design.xray import Body, ImagingModel, anatomy, render

ROOT = Path(__file__).resolve().parents[1]


def residuals(obs, truth, pix):
    out = {"point": [], "line": [], "ellipse": [], "ellipse_signed": []}
    for fid, uv in obs.points.items():
        out["point"].append(np.linalg.norm(uv - np.array(truth["points"][fid])) / np.sqrt(2) * pix)
    for fid, c in obs.lines.items():
        a, b = np.array(truth["lines"][fid]["start"]), np.array(truth["lines"][fid]["end"])
        d = (b - a) / np.linalg.norm(b - a)
        out["line"] += list(((c.points - a) @ np.array([-d[1], d[0]])) * pix)
    for fid, c in obs.ellipses.items():
        C = conic_matrix(np.array(truth["ellipses"][fid]["conic"]))
        x = np.c_[c.points, np.ones(len(c.points))]
        Q = np.einsum("ni,ij,nj->n", x, C, x)
        d = Q / np.linalg.norm(2 * (x @ C)[:, :2], axis=1)
        cen = np.array([*truth["ellipses"][fid]["center"], 1.0])
        d *= np.sign(cen @ C @ cen)
        out["ellipse"] += list(d * pix)
        out["ellipse_signed"].append(float(np.mean(d)))
    return out


def run(name, n, seed, background, use_body=True, imaging=ImagingModel(), occlude=False):
    design = load_design(ROOT / "models" / f"{name}.toml")
    features = compute_features(design)
    body = Body.from_design(design)
    R, t = Workspace().sample(n, features.nominal_beam_direction, np.random.default_rng(seed))
    cam = Camera()
    pix = float(np.mean(cam.pixel_size_mm))
    res_all = {"point": [], "line": [], "ellipse": [], "ellipse_signed": []}
    wrong, notconv, reasons, perr, psd, times = 0, 0, Counter(), [], [], []
    for k in tqdm(range(n), desc=f"{name}{' +bg' if background else ''}", leave=False):
        bg = anatomy(seed=seed * 1000 + k) if background else None
        rad = render(features, R[k], t[k], cam, imaging, rng=np.random.default_rng(seed * 1000 + k), background=bg,
                     body=body)
        t0 = time.perf_counter()
        tr = track_image(rad.raw, features, cam, body=body if use_body else None)
        times.append(time.perf_counter() - t0)
        p = tr.pose
        if tr.observation is not None:
            for key, v in residuals(tr.observation, rad.truth["projected"], pix).items():
                res_all[key] += v
        if not p.converged:
            notconv += 1
            reasons[(p.error or "?").split(":")[0][:60]] += 1
            continue
        dr, dt = pose_errors(p.rotation, p.translation_mm, R[k], t[k])
        if np.degrees(np.linalg.norm(dr)) > 1.0 or np.linalg.norm(dt) > 5.0:
            wrong += 1
            continue
        perr.append(np.r_[np.degrees(dr), dt])
        psd.append(np.r_[np.degrees(np.sqrt(np.diag(p.covariance)[:3])), p.std_mm])
    perr, psd = np.array(perr).reshape(-1, 6), np.array(psd).reshape(-1, 6)

    def rms(v):
        return float(np.sqrt(np.mean(np.square(v)))) if len(v) else float("nan")
    return {"n": n, "wrong": wrong, "not_converged": notconv, "reasons": dict(reasons),
            "rms_mm": {k: rms(res_all[k]) for k in ("point", "line", "ellipse")},
            "ellipse_shrink_px": float(np.mean(res_all["ellipse_signed"])) if res_all["ellipse_signed"] else float("nan"),
            "pose_rms": np.sqrt(np.mean(perr ** 2, 0)) if len(perr) else np.full(6, np.nan),
            "pose_bias": np.mean(perr, 0) if len(perr) else np.full(6, np.nan),
            "pose_sd_pred": np.sqrt(np.mean(psd ** 2, 0)) if len(psd) else np.full(6, np.nan),
            "median_ms": 1000 * float(np.median(times))}


def show(label, r):
    print(f"\n{label}: {r['n']} images — wrong confident poses {r['wrong']} (target 0), not converged "
          f"{r['not_converged']} {r['reasons'] or ''}")
    m = r["rms_mm"]
    print(f"  segmentation RMS at the detector, mm: points {m['point']:.3f}  lines {m['line']:.3f}  ellipses "
          f"{m['ellipse']:.3f}   (paper Table V: 0.43 / 0.19 / 0.13; target ≤ 0.1)")
    print(f"  ellipse points' mean signed distance (+ = inside, i.e. shrinkage): {r['ellipse_shrink_px']:+.3f} px")
    print("  pose error RMS  rx ry rz (°) tx ty tz (mm): " + " ".join(f"{x:.4f}" for x in r["pose_rms"]))
    print("  pose error mean                            : " + " ".join(f"{x:+.4f}" for x in r["pose_bias"]))
    print("  solver's own 1σ (RMS over images)          : " + " ".join(f"{x:.4f}" for x in r["pose_sd_pred"]))
    print(f"  median track time {r['median_ms']:.0f} ms per image")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n-2005", type=int, default=1000)
    ap.add_argument("--n-mini", type=int, default=300)
    ap.add_argument("--n-nine", type=int, default=300)
    ap.add_argument("--n-sweep", type=int, default=20, help="images per sweep setting (0: no sweeps)")
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args()
    print("track_accuracy: rendered workspace images, default imaging model "
          f"({ImagingModel()}), machine shared with other jobs")
    for name, n in (("ftrac_2005", a.n_2005), ("ftrac_mini", a.n_mini), ("nine_bead", a.n_nine)):
        if n <= 0:
            continue
        for bg in (False, True):
            show(f"{name}{' with anatomy background' if bg else ''}", run(name, n, a.seed, bg))
    if a.n_2005 > 0:
        show("ftrac_2005 WITHOUT the modelled-body subtraction (blur bias left in)",
             run("ftrac_2005", min(a.n_2005, 100), a.seed, False, use_body=False))
    if a.n_sweep > 0:
        print("\nSweeps (ftrac_2005, where it breaks):")
        for dose in (1e3, 3e3, 1e5):
            show(f"photons/px {dose:g}", run("ftrac_2005", a.n_sweep, a.seed + 1, False,
                                             imaging=ImagingModel(photons_per_px=dose)))
        for blur in (1.2, 2.0):
            show(f"detector blur σ {blur} px", run("ftrac_2005", a.n_sweep, a.seed + 2, False,
                                                   imaging=ImagingModel(detector_blur_px=blur)))


if __name__ == "__main__":
    main()
