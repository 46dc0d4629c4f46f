"""Optimised designs judged on rendered radiographs: image → segmentation → pose, end to end.

The optimiser scores designs by the Cramér–Rao bound of a feature-level noise model (the
design's segmentation error, times its parts' error factors for stock sizes other than the
start's: ``ftrac_design/xray/localization.py``) and checks the winner by solving simulated
feature observations drawn from that same model. This script asks the question neither
can: do the designs keep their ranking when the xray simulator renders them and
``track`` segments, identifies and solves the images with no initial guess?

For each design (the first is the reference): the same N workspace poses of SPEC §1 and the
same noise draws (common random numbers, ``track_accuracy.run``), with or without the
anatomy-like background. Printed: converged / wrong confident (> 1° or > 5 mm) images, the
segmentation's RMS residual per feature type (mm at the detector), the median, p95 and RMS of
the 3-D pose error (translation mm, rotation °) of the right converged images, and the p95's
ratio to the reference's (the optimiser's objective is a p95) — again over the poses both
designs got right, with a bootstrap 95 % interval (poses resampled in pairs): a p95 over a
few hundred images is uncertain by about ±10 %.

    .venv/bin/python benchmarks/optimize_images.py --n 300 \\
        ftrac_mini ftrac_mini_opt ftrac_mini_stock
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from track_accuracy import run

from ftrac_design.design.presets import preset_path, resolve_design
from ftrac_design.optimize.imagecheck import paired_p95_ratio


def paired_ratio(ref: dict, r: dict) -> tuple[np.ndarray, np.ndarray]:
    """p95 ratio (design / reference) of the 3-D translation and rotation errors over the poses
    both got right, and its bootstrap 95 % interval (:func:`paired_p95_ratio`): (2,), (2, 2);
    NaN where fewer than 20 poses are shared."""

    def per_image(x: dict) -> dict:
        e = x["pose_errors"]
        return {
            "per_image": {
                "index": list(x["right_index"]),
                "translation_mm": np.linalg.norm(e[:, 3:], axis=1),
                "rotation_deg": np.linalg.norm(e[:, :3], axis=1),
            }
        }

    p = paired_p95_ratio(per_image(ref), per_image(r))
    if p is None:  # fewer than 20 poses in common
        return np.full(2, np.nan), np.full((2, 2), np.nan)
    return (
        np.array([p["translation_p95_ratio"], p["rotation_p95_ratio"]]),
        np.array([p["translation_p95_ratio_95ci"], p["rotation_p95_ratio_95ci"]]),
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "designs",
        nargs="*",
        type=resolve_design,
        help="design files or presets; the first is the "
        "reference [default: ftrac_mini, ftrac_mini_opt, ftrac_mini_stock]",
        default=[preset_path(n) for n in ("ftrac_mini", "ftrac_mini_opt", "ftrac_mini_stock")],
    )
    ap.add_argument("--n", type=int, default=100, help="images per design and background")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--background", choices=("both", "none", "anatomy"), default="both")
    args = ap.parse_args()
    bgs = {"both": (False, True), "none": (False,), "anatomy": (True,)}[args.background]
    for bg in bgs:
        print(f"\n{'anatomy background' if bg else 'clean'}: {args.n} workspace poses, seed {args.seed}")
        print(f"{'':<20}{'':>16}{'segmentation':>19}  {'3-D translation error, mm':>28}  {'3-D rotation error, °':>28}")
        print(
            f"{'design':<20}{'conv / wrong':>16}{'pt/ln/el mm':>19}  {'median':>8}{'p95':>8}{'RMS':>8}{'ratio':>6}"
            f"  {'median':>8}{'p95':>8}{'RMS':>8}{'ratio':>6}{'s/img':>7}"
        )
        ref, ref_run, paired = None, None, []
        for path in args.designs:
            t0 = time.perf_counter()
            r = run(str(path), args.n, args.seed, bg, intensity=0, label=path.stem)
            sec = (time.perf_counter() - t0) / args.n
            e = r["pose_errors"]
            et, er = np.linalg.norm(e[:, 3:], axis=1), np.linalg.norm(e[:, :3], axis=1)
            st = [float(np.median(et)), float(np.percentile(et, 95)), float(np.sqrt(np.mean(et**2)))]
            sr = [float(np.median(er)), float(np.percentile(er, 95)), float(np.sqrt(np.mean(er**2)))]
            ref = ref or (st[1], sr[1])
            if ref_run is None:
                ref_run = r
            else:
                paired.append((path.stem, *paired_ratio(ref_run, r)))
            # the Cramér–Rao RMS with the noise the segmentation showed on these images
            bt, br = float(np.linalg.norm(r["cr"][3:])), float(np.linalg.norm(r["cr"][:3]))
            seg = "/".join(f"{r['rms_mm'][k]:.3f}" for k in ("point", "line", "ellipse"))
            conv = f"{r['converged']} / {len(r['wrong'])}"
            print(
                f"{path.stem:<20}{conv:>16}{seg:>19}  "
                + "".join(f"{v:>8.3f}" for v in st)
                + f"{st[1] / ref[0]:>6.2f}  "
                + "".join(f"{v:>8.4f}" for v in sr)
                + f"{sr[1] / ref[1]:>6.2f}{sec:>7.2f}"
                + f"   bound at the measured noise: RMS {bt:.3f} mm, {br:.4f}°"
            )
        for name, ratio, ci in paired:
            print(
                f"  {name}: p95 ratio over the poses both got right, translation {ratio[0]:.2f} "
                f"(95 % bootstrap {ci[0, 0]:.2f}–{ci[0, 1]:.2f}), rotation {ratio[1]:.2f} "
                f"({ci[1, 0]:.2f}–{ci[1, 1]:.2f})"
            )


if __name__ == "__main__":
    main()
