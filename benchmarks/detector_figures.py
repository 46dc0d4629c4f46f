"""The learned detector's own figures beside the classical detectors', on held-out images of every condition.

For each preset and condition, N images (the realism benchmark's images: :func:`track_realism.make_image`,
a seed never used in training) and their exact truth:

- **balls**: recall (a true ball, in the image and clear of the other balls by 2 radii, with a
  candidate within 1.5 px among the candidates the tracker keeps: 3 × balls + 6), precision (the
  share of those candidates within 1.5 px of a true ball), and the RMS distance of the matched ones
  (px) — for the learned candidates and for the classical blob detector's, each after the
  blurred-sphere fit the tracker runs on them: the network's ``TrackOptions.detector_candidates``
  most probable peaks fitted in turn, the first 3 × balls + 6 that look like a ball kept, as
  :func:`ftrac_design.segment.learned.detections` and :func:`~ftrac_design.segment.detection.detect`
  give them to the tracker; the classical ones on the image conditioned in its true polarity, over
  the whole image (their best case). The JSON's ``learned_raw_balls`` are the network's 3 × balls
  + 6 most probable peaks before any fit;
- **wires**: recall (the share of centre-line samples, clear of the balls, where the learned wire
  probability is ≥ ½ / where a classical ridge point lies within 1.5 px) and precision (the share
  of wire cells ≥ ½ / ridge points within 1.5 px of a centre-line);
- the fitted balls' localisation on clean images beside the pixel-level Cramér–Rao bound
  (:func:`ftrac_design.xray.localization.bead_sigma_mm`) at each image's depth.

    .venv/bin/python benchmarks/detector_figures.py --n 40 --seed 2026
"""

from __future__ import annotations

import argparse
import json
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import _common
import numpy as np
import track_realism as tr

from ftrac_design.pose import Camera
from ftrac_design.segment import learned
from ftrac_design.segment.conditioning import condition
from ftrac_design.segment.detection import detect, scales
from ftrac_design.segment.identify import curve_samples, project
from ftrac_design.segment.image import NoiseField
from ftrac_design.segment.options import TrackOptions
from ftrac_design.xray.localization import bead_sigma_mm

ROOT = Path(__file__).resolve().parents[1]
TOL_PX = 1.5


def _truth(features, R, t, cam, shape):
    uv = project(cam, R, t, features.point_centers())[0]
    H, W = shape
    inside = (uv >= 3).all(1) & (uv[:, 0] < W - 3) & (uv[:, 1] < H - 3)
    rb = scales(features, cam, TrackOptions().finding).bead_radius_px
    dd = np.linalg.norm(uv[:, None] - uv[None], axis=-1) + 1e9 * np.eye(len(uv))
    clear = inside & (dd.min(1) > 4 * rb)
    curves = [p for _, p in curve_samples(features, cam, R, t).values()]
    pts = np.concatenate(curves) if curves else np.zeros((0, 2))
    if len(pts) and len(uv):
        pts = pts[np.linalg.norm(pts[:, None] - uv[None], axis=-1).min(1) > 2.5 * rb]
    return uv[clear], pts, rb


def _ball_figures(found: np.ndarray, truth: np.ndarray) -> tuple[int, int, int, int, list[float]]:
    if len(found) == 0 or len(truth) == 0:
        return len(truth), 0, len(found), 0, []
    d = np.linalg.norm(found[:, None] - truth[None], axis=-1)
    hit_t = d.min(0) <= TOL_PX
    return len(truth), int(hit_t.sum()), len(found), int((d.min(1) <= TOL_PX).sum()), d.min(0)[hit_t].tolist()


def one(task) -> dict:
    preset, cond, k, seed, n = task
    features = tr.preset_features(preset)
    if cond == "clean":
        img, R, t, cam, _ = tr.make_image(preset, cond, k, seed, n)
        pol, form = "dense-dark", "linear"
    else:
        # drawn with what its chain chose: the polarity and formation
        img, info, R, t = tr.realism_image(preset, cond, k, seed, n)
        cam = Camera()
        pol, form = info["polarity"], info["formation"]
    truth, wire_pts, _ = _truth(features, R, t, cam, img.shape)
    opts = TrackOptions().finding
    sc = scales(features, cam, opts)
    P = len(features.points)
    out = {"preset": preset, "condition": cond, "k": k}
    # the classical detectors, on the image conditioned in its true polarity
    cond_img = condition(np.asarray(img, np.float32), pol, form, sc.disc_px)
    t0 = time.perf_counter()
    scene = detect(
        cond_img.density, features, cam, opts, cond_img.valid, NoiseField(cond_img.density, cond_img.valid, sc.disc_px)
    )
    out["classical_ms"] = (time.perf_counter() - t0) * 1e3
    out["classical_balls"] = _ball_figures(scene.beads.uv[: 3 * P + 6], truth)
    ridges = scene.ridges.uv if scene.ridges is not None else np.zeros((0, 2))
    if len(wire_pts) and len(ridges):
        from scipy.spatial import cKDTree

        dr = cKDTree(ridges).query(wire_pts)[0]
        dw = cKDTree(wire_pts).query(ridges)[0]
        out["classical_wires"] = [len(wire_pts), int((dr <= TOL_PX).sum()), len(ridges), int((dw <= TOL_PX).sum())]
    # the learned detector, on the image as stored, with the candidates the tracker keeps
    t0 = time.perf_counter()
    det = learned.detections(img, sc, opts)
    out["learned_ms"] = (time.perf_counter() - t0) * 1e3
    out["learned_raw_balls"] = _ball_figures(det.beads_uv[: 3 * P + 6], truth)
    fitted = detect(cond_img.density, features, cam, opts, cond_img.valid, None, det).beads
    out["learned_balls"] = _ball_figures(fitted.uv, truth)
    if len(wire_pts):
        p = det.wire_probability(wire_pts)
        cells = np.argwhere(det.wire >= 0.5)
        centres = np.stack([cells[:, 1], cells[:, 0]], -1) * det.cell_px + det.cell_px / 2 - 0.5
        from scipy.spatial import cKDTree

        dw = cKDTree(wire_pts).query(centres)[0] if len(centres) else np.zeros(0)
        out["learned_wires"] = [len(wire_pts), int((p >= 0.5).sum()), len(centres), int((dw <= det.cell_px).sum())]
    if cond == "clean":
        pix = float(np.mean(cam.pixel_size_mm))
        out["crb_px"] = bead_sigma_mm(float(features.points[0].diameter), float(t[2]), cam) / pix
    return out


def summarise(rows: list[dict]) -> str:
    lines = []
    by: dict = {}
    for r in rows:
        by.setdefault((r["preset"], r["condition"]), []).append(r)
    lines.append(
        f"{'preset':10s} {'condition':15s} | balls: recall, precision, RMS px | wires: recall, precision "
        "(each learned / classical) | time learned / classical"
    )
    for (preset, cond), rs in by.items():

        def balls(key):
            nt, ht, nf, hf = (sum(r[key][j] for r in rs) for j in range(4))
            e = np.concatenate([np.asarray(r[key][4], float) for r in rs]) if rs else np.zeros(0)
            return ht / max(nt, 1), hf / max(nf, 1), float(np.sqrt(np.mean(e**2))) if len(e) else float("nan")

        def wires(key):
            have = [r[key] for r in rs if key in r]
            if not have:
                return float("nan"), float("nan")
            return sum(h[1] for h in have) / max(sum(h[0] for h in have), 1), sum(h[3] for h in have) / max(
                sum(h[2] for h in have), 1
            )

        lb, cb = balls("learned_balls"), balls("classical_balls")
        lw, cw = wires("learned_wires"), wires("classical_wires")
        ms = [np.median([r[k] for r in rs]) for k in ("learned_ms", "classical_ms")]
        lines.append(
            f"{preset:10s} {cond:15s} | {lb[0]:5.3f}/{cb[0]:5.3f}  {lb[1]:5.3f}/{cb[1]:5.3f}  "
            f"{lb[2]:4.2f}/{cb[2]:4.2f} | {lw[0]:5.3f}/{cw[0]:5.3f}  {lw[1]:5.3f}/{cw[1]:5.3f} | "
            f"{ms[0]:4.0f} / {ms[1]:4.0f} ms"
        )
    crb = [r["crb_px"] for r in rows if "crb_px" in r]
    if crb:
        lines.append(
            f"pixel-level Cramér–Rao σ of a ball's centre on the clean images: median {np.median(crb):.3f} px per axis"
        )
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=40)
    ap.add_argument("--seed", type=int, default=2026)
    ap.add_argument("--presets", nargs="+", default=list(tr.PRESETS))
    ap.add_argument("--conditions", nargs="+", default=["clean", *tr.CONDITIONS])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--json", type=Path, default=ROOT / "outputs" / "detector_figures.json")
    a = ap.parse_args()
    print(f"detector_figures: {_common.machine()}")
    tasks = [(p, c, k, a.seed, a.n) for p in a.presets for c in a.conditions for k in range(a.n)]
    with ProcessPoolExecutor(a.workers) as ex:
        rows = list(ex.map(one, tasks, chunksize=4))
    a.json.parent.mkdir(parents=True, exist_ok=True)
    a.json.write_text(json.dumps(rows))
    print(summarise(rows))


if __name__ == "__main__":
    main()
