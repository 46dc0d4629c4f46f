"""Image path accuracy: rendered workspace radiographs → track → errors.

For each preset: N workspace poses (SPEC §1) rendered by the xray simulator at the default
imaging model, with and without the anatomy-like background; each image tracked with no
initial guess. Reports

- identification failures: a converged pose > 1° or > 5 mm off (a *wrong* confident
  answer — target 0), with the image indices; and converged poses whose error is
  improbable under their own covariance (χ²₆ > 25.7, p < 1e-4): overconfident;
- images not converged (with reasons);
- segmentation residuals per feature type in mm at the detector (beads: centre error per
  axis; lines, ellipses: distance of each contour point to the true projected curve)
  beside the paper's Table V (0.43 / 0.19 / 0.13 mm; target ≤ 0.1 mm), and how many
  ellipses the converged poses used;
- the pose error per camera axis (RMS, mean ± its standard error: the depth bias) beside
  the solver's own 1σ (RMS over images; ratio empirical / solver per axis) and the
  Cramér–Rao prediction of ``ftrac_design.analysis`` at the same poses with the
  segmentation's measured noise model (median over the images, at the scale each image's
  residuals showed: the variance factor) and contour counts;
- sweeps on ftrac_2005 (where it breaks): dose, detector blur, background strength, a
  needle occluder across the fiducial, truncation (the fiducial partly outside the image);
- the intensity path (``--intensity N``, default 30, 0 = off) on the first N
  images of each preset run whose feature-path pose converged and was right:
  ``refine_intensity`` with its defaults from that pose, as ``track --refine intensity``
  does (full resolution, a 1 px scale first only from a far start), and the efficiency per axis, 1 / mean(z²) with
  its 95 % interval, of the intensity path and of the feature path against the same
  pixel-level Cramér–Rao bound at the true pose (``pixel_information`` with the nuisance
  parameters the refinement fitted: gain and the 12 px spline background, or gain and a
  quadratic where it took the image as cluttered; an anatomy background's attenuation
  included and taken as known), the RMS error in units of the quadratic-background bound,
  and the refinement's CPU time (median, max).

    .venv/bin/python benchmarks/track_accuracy.py --n-2005 1000 --n-mini 300 --n-nine 300
    .venv/bin/python benchmarks/track_accuracy.py --only sweeps --n-sweep 20
    .venv/bin/python benchmarks/track_accuracy.py --only presets --n-2005 60 --n-mini 30 --n-nine 30 --intensity 30
"""

from __future__ import annotations

import argparse
import math
import time
from collections import Counter
from dataclasses import replace

import numpy as np
from intensity_common import Judge, efficiency
from tqdm import tqdm

from ftrac_design.analysis import analyse_poses
from ftrac_design.design import load_design
from ftrac_design.features import compute_features
from ftrac_design.pose import Camera, NoiseModel
from ftrac_design.pose.fitting import conic_matrix
from ftrac_design.pose.simulate import ContourSampling, Workspace, pose_errors
from ftrac_design.segment.pipeline import TrackOptions, track_image
from ftrac_design.xray import ImagingModel, Occluder, anatomy, render

AXES = ("rx", "ry", "rz", "tx", "ty", "tz")


def residuals(obs, truth, pix):
    out = {"point": [], "line": [], "ellipse": [], "ellipse_signed": []}
    for fid, uv in obs.points.items():
        out["point"] += list((uv - np.array(truth["points"][fid])) * pix)
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


def _needle(rng, features):
    """A steel needle (Ø1.27 mm) across the fiducial's middle, in F, random direction ⟂-ish to z."""
    c = features.point_centers().mean(0) + rng.uniform(-5, 5, 3)
    a = rng.uniform(0, 2 * np.pi)
    d = np.array([math.cos(a), math.sin(a), rng.uniform(-0.5, 0.5)])
    d /= np.linalg.norm(d)
    return Occluder(tuple(c - 60 * d), tuple(c + 60 * d))


def run(
    name,
    n,
    seed,
    background,
    use_body=True,
    imaging=ImagingModel(),
    bg_strength=1.0,
    needle=False,
    truncate_px=None,
    label="",
    intensity=0,
):
    design = load_design(name)  # a design file, or a preset by name
    features = compute_features(design)
    # what the tracker is told: the fiducial with its body, or without (the body is rendered either way)
    known = features if use_body else replace(features, body=None)
    R, t = Workspace().sample(n, features.nominal_beam_direction, np.random.default_rng(seed))
    cam = Camera()
    pix = float(np.mean(cam.pixel_size_mm))
    if truncate_px is not None:
        # the fiducial origin projected ``truncate_px`` from the left edge (negative: outside)
        t = t.copy()
        t[:, 0] = (truncate_px - cam.principal_point_px[0]) * pix / cam.focal_length_mm * t[:, 2]
    res_all = {"point": [], "line": [], "ellipse": [], "ellipse_signed": []}
    wrong, overconf, notconv, reasons = [], [], 0, Counter()
    perr, psd, noise, counts, n_ell, times, conv_idx = [], [], [], [], Counter(), [], []
    inten = {"z_int": [], "z_feat": [], "zq_int": [], "zq_feat": [], "cpu": [], "worse": 0, "models": Counter()}
    for k in tqdm(range(n), desc=label or name, leave=False, mininterval=5):
        rng = np.random.default_rng(seed * 1000 + k)
        bg = anatomy(seed=seed * 1000 + k, strength=bg_strength) if background else None
        occ = (_needle(rng, features),) if needle else ()
        rad = render(features, R[k], t[k], cam, imaging, rng=rng, background=bg, occluders=occ)
        t0 = time.perf_counter()
        # the simulator's camera is a pinhole: no distortion term in the covariance
        tr = track_image(rad.raw, known, cam, TrackOptions(distortion_prior_mm=0.0))
        times.append(time.perf_counter() - t0)
        p = tr.pose
        if tr.observation is not None:
            truth = rad.truth["projected"]
            obs = tr.observation
            ok = (
                all(f in truth["points"] for f in obs.points)
                and all(f in truth["lines"] for f in obs.lines)
                and all(f in truth["ellipses"] for f in obs.ellipses)
            )
            if ok:
                for key, v in residuals(obs, truth, pix).items():
                    res_all[key] += v
        if not p.converged:
            notconv += 1
            reasons[(p.error or "?").split(":")[0][:60]] += 1
            continue
        dr, dt = pose_errors(p.rotation, p.translation_mm, R[k], t[k])
        if np.degrees(np.linalg.norm(dr)) > 1.0 or np.linalg.norm(dt) > 5.0:
            wrong.append(k)
            continue
        e = np.r_[dr, dt]
        if p.covariance is not None and e @ np.linalg.solve(p.covariance, e) > 25.7:
            overconf.append(k)
        perr.append(np.r_[np.degrees(dr), dt])
        psd.append(np.r_[np.degrees(np.sqrt(np.diag(p.covariance)[:3])), p.std_mm])
        # the noise model at the scale the residuals showed (the covariance's variance factor)
        vf = tr.diagnostics.variance_factor
        vf = math.sqrt(vf if vf and math.isfinite(vf) else 1.0)
        noise.append([vf * tr.noise.point_mm, vf * tr.noise.line_mm, vf * tr.noise.ellipse_mm])
        obs = tr.observation
        counts.append(
            [
                np.median([len(c.points) for c in obs.lines.values()]) if obs.lines else np.nan,
                np.median([len(c.points) for c in obs.ellipses.values()]) if obs.ellipses else np.nan,
            ]
        )
        n_ell[len(obs.ellipses)] += 1
        conv_idx.append(k)
        if len(inten["cpu"]) < intensity:
            # the intensity path on the same image, from this pose (as track --refine intensity)
            judge = Judge(known, cam, imaging, R[k], t[k], background=bg)
            ri, zi, zqi, (_, cpu) = judge.refine(rad.raw, p.rotation, p.translation_mm, coarse_scales=(1.0,))
            inten["z_int"].append(zi)
            inten["zq_int"].append(zqi)
            inten["z_feat"].append(judge.z(p.rotation, p.translation_mm, ri.background_model))
            inten["zq_feat"].append(judge.z_quad(p.rotation, p.translation_mm))
            inten["cpu"].append(cpu)
            inten["worse"] += ri.cost_end > ri.cost_start
            inten["models"][ri.background_model] += 1
    perr, psd = np.array(perr).reshape(-1, 6), np.array(psd).reshape(-1, 6)
    cr = np.full(6, np.nan)
    if len(conv_idx) and features.points:
        nm = np.nanmedian(np.array(noise), 0)
        cnt = np.nanmedian(np.array(counts), 0)
        cs = ContourSampling(
            ellipse=int(cnt[1]) if np.isfinite(cnt[1]) else 24, line=int(cnt[0]) if np.isfinite(cnt[0]) else 12
        )
        an = analyse_poses(features, R[conv_idx], t[conv_idx], cam, NoiseModel(*nm), cs, detail=False)
        sd = np.c_[np.degrees(an.overall.rotation_std_rad), an.overall.translation_std_mm]
        cr = np.sqrt(np.mean(sd**2, 0))

    def rms(v):
        return float(np.sqrt(np.mean(np.square(v)))) if len(v) else float("nan")

    m = len(perr)
    return {
        "n": n,
        "wrong": wrong,
        "overconfident": overconf,
        "not_converged": notconv,
        "reasons": dict(reasons),
        "rms_mm": {k: rms(res_all[k]) for k in ("point", "line", "ellipse")},
        "ellipse_shrink_px": float(np.mean(res_all["ellipse_signed"])) if res_all["ellipse_signed"] else math.nan,
        "ellipses_used": dict(sorted(n_ell.items())),
        "pose_errors": perr,
        "right_index": np.array(conv_idx, int),
        "pose_rms": np.sqrt(np.mean(perr**2, 0)) if m else np.full(6, np.nan),
        "pose_bias": np.mean(perr, 0) if m else np.full(6, np.nan),
        "pose_bias_se": np.std(perr, 0, ddof=1) / math.sqrt(m) if m > 1 else np.full(6, np.nan),
        "pose_sd_pred": np.sqrt(np.mean(psd**2, 0)) if m else np.full(6, np.nan),
        "cr": cr,
        "noise_mm": np.nanmedian(np.array(noise), 0) if noise else np.full(3, np.nan),
        "median_ms": 1000 * float(np.median(times)),
        "converged": m + len(wrong),
        "intensity": inten if inten["cpu"] else None,
    }


def show(label, r):
    w = r["wrong"]
    print(
        f"\n{label}: {r['n']} images — WRONG confident poses {len(w)} (target 0){' ' + str(w[:20]) if w else ''}; "
        f"converged {r['converged']}, not converged {r['not_converged']} {r['reasons'] or ''}"
    )
    print(
        f"  overconfident (right but χ²₆ of the error vs its covariance > 25.7): {len(r['overconfident'])}"
        f"{' ' + str(r['overconfident'][:20]) if r['overconfident'] else ''}"
    )
    m = r["rms_mm"]
    print(
        f"  segmentation RMS at the detector, mm: points {m['point']:.3f}  lines {m['line']:.3f}  ellipses "
        f"{m['ellipse']:.3f}   (paper Table V: 0.43 / 0.19 / 0.13; target ≤ 0.1)"
    )
    print(
        f"  ellipses used per converged image {r['ellipses_used']}; mean signed ellipse distance (+ = inside) "
        f"{r['ellipse_shrink_px']:+.3f} px; noise model × √variance factor (median) point/line/ellipse "
        + " ".join(f"{x:.3f}" for x in r["noise_mm"])
        + " mm"
    )
    print("                                 " + "  ".join(f"{a:>8s}" for a in AXES) + "   (° and mm)")
    print("  pose error RMS               : " + "  ".join(f"{x:8.4f}" for x in r["pose_rms"]))
    print("  pose error mean              : " + "  ".join(f"{x:+8.4f}" for x in r["pose_bias"]))
    print("  standard error of the mean   : " + "  ".join(f"{x:8.4f}" for x in r["pose_bias_se"]))
    print("  solver's own 1σ (RMS)        : " + "  ".join(f"{x:8.4f}" for x in r["pose_sd_pred"]))
    print("  ratio error RMS / solver 1σ  : " + "  ".join(f"{x:8.2f}" for x in r["pose_rms"] / r["pose_sd_pred"]))
    print("  Cramér–Rao (analysis), RMS   : " + "  ".join(f"{x:8.4f}" for x in r["cr"]))
    print(f"  median track time {r['median_ms']:.0f} ms per image")
    it = r.get("intensity")
    if it:
        e_i, lo, hi = efficiency(it["z_int"])
        e_f, lo_f, hi_f = efficiency(it["z_feat"])
        m = len(it["cpu"])
        print(
            f"  intensity path on the first {m} right images (refine_intensity defaults from the feature pose; "
            f"background models {dict(it['models'])}), vs the pixel-level bound:"
        )
        print(
            "  efficiency, intensity path   : "
            + "  ".join(f"{x:8.2f}" for x in e_i)
            + f"   (target ≥ 0.9: {'met' if np.all(e_i >= 0.9) else 'missed'})"
        )
        print("    95 % interval              : " + " ".join(f"{a:.2g}–{b:.2g}".rjust(9) for a, b in zip(lo, hi)))
        print("  efficiency, feature path     : " + "  ".join(f"{x:8.4f}" for x in e_f))
        print("    95 % interval              : " + " ".join(f"{a:.2g}–{b:.2g}".rjust(9) for a, b in zip(lo_f, hi_f)))
        zq_i, zq_f = np.array(it["zq_int"]), np.array(it["zq_feat"])
        print(
            "  RMS error / quadratic bound  : intensity "
            + " ".join(f"{x:.2f}" for x in np.sqrt(np.mean(zq_i**2, 0)))
            + "; features "
            + " ".join(f"{x:.1f}" for x in np.sqrt(np.mean(zq_f**2, 0)))
        )
        cpu = 1e3 * np.array(it["cpu"])
        print(
            f"  refinement CPU time per image: median {np.median(cpu):.0f} ms, max {cpu.max():.0f} ms "
            f"(target ≤ 1 s); ended above its start's objective: {it['worse']}"
        )


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n-2005", type=int, default=1000)
    ap.add_argument("--n-mini", type=int, default=300)
    ap.add_argument("--n-nine", type=int, default=300)
    ap.add_argument("--n-sweep", type=int, default=20, help="images per sweep setting (0: no sweeps)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument(
        "--intensity",
        type=int,
        default=30,
        help="refine the first N right poses of each preset run on the intensities and compare both "
        "paths with the pixel-level bound (0: off)",
    )
    ap.add_argument(
        "--background",
        choices=("both", "none", "anatomy"),
        default="both",
        help="the preset runs without / with the anatomy background, or both",
    )
    ap.add_argument(
        "--only",
        choices=("all", "presets", "sweeps", "ftrac_2005", "small"),
        default="all",
        help="presets: the three presets; ftrac_2005 / small: that one / ftrac_mini and nine_bead",
    )
    a = ap.parse_args()
    print(
        "track_accuracy: rendered workspace images, default imaging model "
        f"({ImagingModel()}), machine shared with other jobs"
    )
    todo = {
        "all": ("ftrac_2005", "ftrac_mini", "nine_bead"),
        "presets": ("ftrac_2005", "ftrac_mini", "nine_bead"),
        "ftrac_2005": ("ftrac_2005",),
        "small": ("ftrac_mini", "nine_bead"),
        "sweeps": (),
    }[a.only]
    for name, n in (("ftrac_2005", a.n_2005), ("ftrac_mini", a.n_mini), ("nine_bead", a.n_nine)):
        if n <= 0 or name not in todo:
            continue
        for bg in {"both": (False, True), "none": (False,), "anatomy": (True,)}[a.background]:
            lab = f"{name}{' with anatomy background' if bg else ''}"
            show(lab, run(name, n, a.seed, bg, label=lab, intensity=a.intensity))
    if "ftrac_2005" in todo and a.n_2005 > 0 and a.background != "anatomy":
        show(
            "ftrac_2005 WITHOUT the modelled-body subtraction (blur bias left in)",
            run("ftrac_2005", min(a.n_2005, 100), a.seed, False, use_body=False, label="no body"),
        )
    if a.n_sweep > 0 and a.only in ("all", "sweeps"):
        n = a.n_sweep
        print(f"\nSweeps (ftrac_2005, {n} images each; where it breaks):")
        for dose in (300, 1e3, 3e3, 1e5):
            show(
                f"photons/px {dose:g}",
                run(
                    "ftrac_2005",
                    n,
                    a.seed + 1,
                    False,
                    imaging=ImagingModel(photons_per_px=dose),
                    label=f"dose {dose:g}",
                ),
            )
        for blur in (1.2, 2.0, 3.0):
            show(
                f"detector blur σ {blur} px",
                run(
                    "ftrac_2005",
                    n,
                    a.seed + 2,
                    False,
                    imaging=ImagingModel(detector_blur_px=blur),
                    label=f"blur {blur}",
                ),
            )
        for s in (2.0, 4.0, 8.0):
            show(f"anatomy background × {s:g}", run("ftrac_2005", n, a.seed + 3, True, bg_strength=s, label=f"bg {s}"))
        show(
            "a steel needle (Ø1.27 mm) across the fiducial",
            run("ftrac_2005", n, a.seed + 4, False, needle=True, label="needle"),
        )
        for px in (80, 40, 0):
            show(
                f"truncated: fiducial origin {px} px from the image edge",
                run("ftrac_2005", n, a.seed + 5, False, truncate_px=px, label=f"trunc {px}"),
            )


if __name__ == "__main__":
    main()
