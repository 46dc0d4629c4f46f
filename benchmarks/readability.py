"""How many of the fiducial's balls an image shows: the realism images sorted by it, the tracker's share of each.

`track_realism.py` counts the images the tracker gives a pose on. Where it refuses, either the
tracker missed what the image shows or the image shows little: under 2 px of blur, a dark
display window or a dense bone, a 2 mm steel ball sinks into the patient's texture. This
script sorts the images with the truth. For every ball of every image (the same images as
`track_realism.py` draws for a seed, condition and image count) it reads the image through a
**matched filter** — the ball's own projected chord profile at its true radius in pixels,
blurred by the image's true blur σ, made zero-mean over its window (ball minus its local
background) — and divides the response at the ball's true place (the largest within ±1 px,
for the sub-pixel phase) by the spread of the same filter's responses over the fiducial's
neighbourhood with every ball masked out (a robust σ, 1.4826 × MAD): a **signal-to-clutter
ratio** z. The clutter is the noise, the patient's texture, the fiducial's wires and body,
and everything else a detector must tell a ball from; the field's edge and what a shutter
hides are left out.

It is a measure of difficulty, **not a bound**: a ball read alone at z ≈ 3 is one of many
places of its neighbourhood that look as much like a ball, but the tracker finds balls in
context (the learned detector sees the wire through a ball; once three balls give a pose,
the others are looked for where it puts them) and tracks images whose balls all read below 4
(tuning seed 2142, blur: 32 of 61 such images tracked). Nor does it see everything that
hides a ball: crowded balls (a view that lays two on one another) read high here and are left
out by the tracker, and the robust σ leaves out sparse look-alikes — among brachytherapy seeds
`ftrac_mini`'s 1 mm balls read high and are one blob among many as strong.

Per preset and condition it prints how many images show ≤ 3, 4 and ≥ 5 balls at z ≥ 3 and at
z ≥ 4 (fewer than 4: no P3P start with a check; fewer than 5: below what the tracker's
acceptance takes with wires) and — given `track_realism.py --json` runs of the same images —
the share of each bin tracked: what the tracker makes of images that show their balls, apart
from images that do not.

    .venv/bin/python benchmarks/readability.py --n 200 --seed 2142 --presets ftrac_2005 \\
        --track /tmp/run.json                      # the run's outcomes by bin
    .venv/bin/python benchmarks/readability.py --n 20 --conditions blur-2px --json out.json
    .venv/bin/python benchmarks/readability.py --plot out.json --track /tmp/run.json   # the figure
"""

from __future__ import annotations

import argparse
import json
import math
from collections import defaultdict
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import _common
import cv2
import numpy as np
import track_realism as tr
from tqdm import tqdm

from ftrac_design.pose import Camera
from ftrac_design.xray.scenario import CONDITIONS

#: the images' bins by balls readable: too few for a P3P start and one check, too few for the
#: tracker's acceptance with wires (5), enough
BINS = (("≤3", 0, 3), ("4", 4, 4), ("≥5", 5, 10**6))
ROOT = Path(__file__).resolve().parents[1]
#: the neighbourhood the clutter is measured over: the balls' bounding box grown by this (px)
MARGIN_PX = 48


def ball_template(radius_px: float, blur_px: float) -> np.ndarray:
    """The matched filter of a ball: its projected chord profile ``2·√(r² − ρ²)`` (``radius_px``,
    px) blurred by a Gaussian of σ ``blur_px`` (px), sampled 8× per pixel and averaged over each
    pixel, made zero-mean over its square window and of unit L2 norm (so white noise of σ
    reads σ through it)."""
    half = int(math.ceil(radius_px + 3.0 * blur_px + 2.0))
    sub = 8
    x = (np.arange((2 * half + 1) * sub) + 0.5) / sub - (half + 0.5)
    rho2 = x[:, None] ** 2 + x[None, :] ** 2
    chord = 2.0 * np.sqrt(np.clip(radius_px**2 - rho2, 0.0, None))
    if blur_px > 0:
        chord = cv2.GaussianBlur(chord, (0, 0), blur_px * sub, borderType=cv2.BORDER_CONSTANT)
    t = chord.reshape(2 * half + 1, sub, 2 * half + 1, sub).mean(axis=(1, 3))
    t = t - t.mean()
    return t / np.linalg.norm(t)


def density(image: np.ndarray, formation: str, polarity: str) -> np.ndarray:
    """The image as density (dense = larger), float64: ``−log`` of linear counts (dense dark),
    the negated pixels of a dense-dark display frame, the pixels otherwise."""
    a = np.asarray(image, float)
    if formation == "linear":
        return -np.log(np.maximum(a, 1.0))
    return -a if polarity == "dense-dark" else a


def clutter_z(
    dens: np.ndarray,
    uv: np.ndarray,
    radius_px: np.ndarray,
    blur_px: float,
    valid: np.ndarray | None = None,
) -> np.ndarray:
    """Each ball's signal-to-clutter ratio: the matched filter's (:func:`ball_template`, the
    median radius of ``radius_px``) response at the ball's true place ``uv`` (N, 2) px — the
    largest within ±1 px, for the sub-pixel phase — over the robust σ (1.4826 × MAD about
    the median) of its responses in the balls' bounding box grown by :data:`MARGIN_PX`, less
    discs around every ball, pixels outside ``valid`` and within the window of its edge."""
    t = ball_template(float(np.median(radius_px)), blur_px)
    half = t.shape[0] // 2
    resp = cv2.filter2D(dens.astype(np.float64), -1, t[::-1, ::-1], borderType=cv2.BORDER_REFLECT)
    H, W = dens.shape
    keep = np.ones((H, W), bool) if valid is None else valid.astype(bool).copy()
    keep = cv2.erode(keep.astype(np.uint8), np.ones((2 * half + 1, 2 * half + 1), np.uint8)).astype(bool)
    keep[:half] = keep[-half:] = False
    keep[:, :half] = keep[:, -half:] = False
    u0, v0 = np.floor(uv.min(0)).astype(int) - MARGIN_PX
    u1, v1 = np.ceil(uv.max(0)).astype(int) + MARGIN_PX
    box = np.zeros((H, W), bool)
    box[max(v0, 0) : min(v1 + 1, H), max(u0, 0) : min(u1 + 1, W)] = True
    vv, uu = np.mgrid[0:H, 0:W]
    near = np.zeros((H, W), bool)
    for (u, v), r in zip(uv, radius_px):
        rr = r + 3.0 * blur_px + 2.0
        sl = (slice(max(int(v - rr), 0), int(v + rr) + 2), slice(max(int(u - rr), 0), int(u + rr) + 2))
        near[sl] |= (uu[sl] - u) ** 2 + (vv[sl] - v) ** 2 <= rr * rr
    sample = resp[box & keep & ~near]
    if sample.size < 100:
        return np.full(len(uv), np.nan)
    med = float(np.median(sample))
    sigma = 1.4826 * float(np.median(np.abs(sample - med)))
    out = np.empty(len(uv))
    for i, (u, v) in enumerate(uv):
        iu, iv = int(round(u)), int(round(v))
        if not (1 <= iu < W - 1 and 1 <= iv < H - 1):
            out[i] = np.nan
            continue
        out[i] = (float(resp[iv - 1 : iv + 2, iu - 1 : iu + 2].max()) - med) / sigma
    return out


def one(task: tuple) -> dict:
    """Image ``k`` of a preset and condition as `track_realism.py` draws it: each ball's z,
    read with the formation and polarity its chain drew (not as the tracker reads them, so the
    count does not depend on the tracker)."""
    preset, condition, k, seed, n = task
    f = tr.preset_features(preset)
    img, info, R, t = tr.realism_image(preset, condition, k, seed, n)
    cam = Camera()
    X = f.point_centers() @ R.T + t
    uv = cam.project(X)
    pix = float(np.mean(cam.pixel_size_mm))
    radius = np.array([p.diameter / 2 for p in f.points]) * cam.focal_length_mm / X[:, 2] / pix
    dens = density(img, info["formation"], info["polarity"])
    z = clutter_z(dens, uv, radius, float(info["blur_sigma_px"]), info.get("field_mask"))
    return {
        "preset": preset,
        "condition": condition,
        "k": k,
        "z": [None if not np.isfinite(x) else float(x) for x in z],
    }


def readable(z: list, level: float) -> int:
    """Balls read at ``level`` or above (an unreadable place, None, is not read)."""
    return sum(1 for x in z if x is not None and x >= level)


def tracked(row: dict) -> bool:
    """A `track_realism.py` row tracked right (converged and not far)."""
    return bool(row.get("converged")) and not row.get("far")


def summarise(rows: list[dict], runs: dict, level: float = 4.0) -> str:
    """Per preset and condition: the images by how many balls they show at ``level`` (:data:`BINS`)
    and, where ``runs`` (preset, condition, k → a `track_realism.py` row) has them, the share
    of each bin tracked."""
    by = defaultdict(list)
    for r in rows:
        by[(r["preset"], r["condition"])].append(r)
    lines = []
    for (preset, cond), rs in by.items():
        got = [runs.get((preset, cond, r["k"])) for r in rs]
        have = all(g is not None for g in got)
        cells = []
        for label, lo, hi in BINS:
            inside = [i for i, r in enumerate(rs) if lo <= readable(r["z"], level) <= hi]
            cell = f"{label}: {len(inside):3d}"
            if have and inside:
                cell += f" ({sum(tracked(got[i]) for i in inside) / len(inside):6.1%} tracked)"
            elif have:
                cell += " (—)"
            cells.append(cell)
        head = f"{preset:11s} {cond:15s} n {len(rs):3d}"
        if have:
            head += f"  tracked {sum(tracked(g) for g in got) / len(rs):6.1%}"
        lines.append(f"{head}  balls at z≥{level:g}  " + "  ".join(cells))
    return "\n".join(lines)


def plot(rows: list[dict], runs: dict, path: Path, level: float = 4.0) -> Path:
    """Per preset and condition, the images by the balls they show at ``level`` (:data:`BINS`)
    as stacked horizontal bars, each bin split into tracked (dark) and not (light) where
    ``runs`` has the images; PNG at ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    presets = list(dict.fromkeys(r["preset"] for r in rows))
    conds = list(dict.fromkeys(r["condition"] for r in rows))
    fig, axes = plt.subplots(1, len(presets), figsize=(4.4 * len(presets), 0.42 * len(conds) + 1.6), sharey=True)
    axes = np.atleast_1d(axes)
    colours = {"≤3": ("#9d0208", "#f4a6a6"), "4": ("#e85d04", "#fcd5b5"), "≥5": ("#2a9d8f", "#b8e0da")}
    for ax, preset in zip(axes, presets):
        for y, cond in enumerate(conds):
            rs = [r for r in rows if r["preset"] == preset and r["condition"] == cond]
            n = max(len(rs), 1)
            left = 0.0
            for label, lo, hi in BINS:
                inside = [r for r in rs if lo <= readable(r["z"], level) <= hi]
                got = [runs.get((preset, cond, r["k"])) for r in inside]
                done = sum(tracked(g) for g in got if g is not None)
                dark, light = colours[label]
                for share, colour, name in ((done / n, dark, "tracked"), ((len(inside) - done) / n, light, "not")):
                    tag = f"{label} balls, {name}" if y == 0 else None
                    ax.barh(y, 100 * share, left=100 * left, color=colour, label=tag)
                    left += share
            seen = [runs[(preset, cond, r["k"])] for r in rs if (preset, cond, r["k"]) in runs]
            if seen:
                ax.text(101, y, f"{100 * sum(tracked(g) for g in seen) / len(seen):.1f} %", va="center", fontsize=7)
        ax.set_title(f"{preset} ({len(rs)} images each)", fontsize=9)
        ax.set_xlim(0, 125)
        ax.set_xlabel("share of images (%)")
    title = f"images by the balls they show (matched filter, z ≥ {level:g} clutter σ) and the share tracked"
    return _common.finish_condition_bars(fig, axes, conds, title, path, ncol=3)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--n", type=int, default=200, help="images per preset and condition (as track_realism.py --n)")
    ap.add_argument("--seed", type=int, default=2142)
    ap.add_argument("--presets", nargs="+", default=["ftrac_2005", "ftrac_mini", "nine_bead"])
    ap.add_argument("--conditions", nargs="+", default=list(CONDITIONS), choices=CONDITIONS)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--track", nargs="*", default=[], help="track_realism.py --json runs of the same images")
    ap.add_argument("--json", type=Path, help="write every ball's z here")
    ap.add_argument(
        "--plot", type=Path, metavar="ZS.json", help="draw docs/img/readability.png from an earlier --json and stop"
    )
    a = ap.parse_args()
    runs = {}
    for path in a.track:
        for r in json.loads(Path(path).read_text()):
            runs[(r["preset"], r["condition"], r["k"])] = r
    if a.plot:
        print(plot(json.loads(a.plot.read_text()), runs, ROOT / "docs" / "img" / "readability.png"))
        return
    tasks = [(p, c, k, a.seed, a.n) for p in a.presets for c in a.conditions for k in range(a.n)]
    with ProcessPoolExecutor(a.workers) as ex:
        rows = list(tqdm(ex.map(one, tasks, chunksize=4), total=len(tasks), desc="readability"))
    print(f"readability: seed {a.seed}, {a.n} images per condition")
    for level in (3.0, 4.0):
        print(summarise(rows, runs, level))
    if a.json:
        a.json.write_text(json.dumps(rows))


if __name__ == "__main__":
    main()
