"""Does the predicted image overlap hurt segmentation?

Rendered workspace radiographs of a preset (xray simulator, default imaging model, no
anatomy background — so that only the geometry differs), each tracked by ``track`` with no
initial guess, binned by the image clearance that :mod:`ftrac_design.analysis.segmentability`
predicts for the pose (smallest counted clearance, px; < 0 = overlap). The poses are drawn
from 20,000 workspace poses so that every bin gets the same number of images (the overlap
bins are 13 % of the workspace: a plain random draw would leave them nearly empty).

Per bin: images that fail — not converged (with the reasons), or converged to a *wrong*
confident pose (> 1° or > 5 mm off, as in ``track_accuracy.py``) — and the translation
error of the good ones; per kind of the worst pair among the overlapping poses; and, among
poses with no counted overlap, with and without a bead on an ellipse wire (not counted).

    .venv/bin/python benchmarks/segmentability_check.py --per-bin 50 [--design ftrac_2005] [--background]
        [--bins=-inf,-4,-2,0,2.5,inf]
"""

from __future__ import annotations

import argparse
import time
from collections import Counter

import numpy as np
from tqdm import tqdm

from ftrac_design.analysis.segmentability import pair_clearances
from ftrac_design.design import load_design
from ftrac_design.features import compute_features
from ftrac_design.pose import Camera
from ftrac_design.pose.simulate import Workspace, pose_errors
from ftrac_design.segment.pipeline import track_image
from ftrac_design.xray import ImagingModel, anatomy, render

BINS = "-inf,-2,0,1,2.5,inf"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--design", default="ftrac_2005")
    ap.add_argument("--per-bin", type=int, default=40)
    ap.add_argument("--seed", type=int, default=3)
    ap.add_argument("--bins", default=BINS, help="clearance bin edges, px [default: %(default)s]")
    ap.add_argument("--background", action="store_true", help="add the anatomy-like background")
    a = ap.parse_args()
    bins = [float(x) for x in a.bins.split(",")]
    design = load_design(a.design)
    features = compute_features(design)
    cam = Camera()
    rng = np.random.default_rng(a.seed)
    R, t = Workspace().sample(20_000, features.nominal_beam_direction, rng)
    pc = pair_clearances(features, cam, R, t)
    m, wp = pc.minimum(), pc.worst_pair()
    be = pc.kind_minimum("bead-ellipse") < 0  # reported, not counted: does it matter?
    print(
        f"segmentability_check: {a.design}, default imaging model ({ImagingModel()}), "
        f"{'anatomy background' if a.background else 'no background'}; machine shared with other jobs"
    )
    print(f"workspace overlap share (20,000 poses, seed {a.seed}): {100 * np.mean(m < 0):.1f} %")
    picks = []
    for lo, hi in zip(bins[:-1], bins[1:]):
        idx = np.flatnonzero((m >= lo) & (m < hi))
        picks.append(rng.choice(idx, size=min(a.per_bin, idx.size), replace=False))
    rows = []
    t0 = time.perf_counter()
    for b, idx in enumerate(picks):
        for k in tqdm(idx, desc=f"bin {b}", leave=False):
            bg = anatomy(seed=int(k)) if a.background else None
            rad = render(features, R[k], t[k], cam, ImagingModel(), rng=np.random.default_rng(int(k)), background=bg)
            status, err = "ok", np.nan
            try:
                p = track_image(rad.raw, features, cam).pose
            except Exception as e:  # noqa: BLE001 — a crash of track is a failure to count, and to report
                status = f"raised {type(e).__name__}: {str(e)[:50]} (pose {k})"
                rows.append((b, float(m[k]), pc.kinds[wp[k]], status, err, bool(be[k])))
                continue
            if not p.converged:
                status = "not converged: " + (p.error or "?").split(":")[0][:50]
            else:
                dr, dt = pose_errors(p.rotation, p.translation_mm, R[k], t[k])
                err = float(np.linalg.norm(dt))
                if np.degrees(np.linalg.norm(dr)) > 1.0 or err > 5.0:
                    status = "wrong"
            rows.append((b, float(m[k]), pc.kinds[wp[k]], status, err, bool(be[k])))
    print(f"{len(rows)} images in {time.perf_counter() - t0:.0f} s")
    print(
        "\n| predicted clearance, px | images | failed | not converged (or raised) | wrong confident "
        "| median |Δt| of the rest, mm |"
    )
    print("| --- | --- | --- | --- | --- | --- |")
    for b, (lo, hi) in enumerate(zip(bins[:-1], bins[1:])):
        r = [x for x in rows if x[0] == b]
        if not r:
            continue
        nc = sum(x[3].startswith(("not", "raised")) for x in r)
        wr = sum(x[3] == "wrong" for x in r)
        ok = [x[4] for x in r if x[3] == "ok"]
        print(
            f"| [{lo:g}, {hi:g}) | {len(r)} | {100 * (nc + wr) / len(r):.0f} % | {nc} | {wr} | "
            f"{np.median(ok) if ok else float('nan'):.3f} |"
        )
    over = [x for x in rows if x[1] < 0]
    print("\noverlapping poses by the kind of their worst pair:")
    for kind, n in Counter(x[2] for x in over).most_common():
        r = [x for x in over if x[2] == kind]
        bad = sum(x[3] != "ok" for x in r)
        print(f"  {kind:<16} {n:3d} images, failed {bad} ({100 * bad / n:.0f} %)")
    clear = [x for x in rows if x[1] >= 0]
    for flag, label in ((True, "with"), (False, "without")):
        r = [x for x in clear if x[5] == flag]
        if r:
            bad = sum(x[3] != "ok" for x in r)
            print(
                f"no counted overlap, {label} a bead on an ellipse wire: {len(r)} images, failed {bad} "
                f"({100 * bad / len(r):.0f} %)"
            )
    print("\nreasons:", dict(Counter(x[3] for x in rows if x[3] != "ok")))


if __name__ == "__main__":
    main()
