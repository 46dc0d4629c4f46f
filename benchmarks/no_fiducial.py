"""Images with no fiducial of the design tracked: the tracker must give no pose.

Five kinds, each image tracked as each of the presets (ftrac_2005, ftrac_mini, nine_bead) with
default options and no hints, as a user with a PNG of it would:

- **anatomy**: a patient under the C-arm's image chain in every condition of
  :mod:`ftrac_design.xray.scenario` — the left half of a 1024 × 2048 frame whose right half holds
  the fiducial (the chain's window, noise and shutters computed over the whole frame);
- **grid plate**: a dewarping plate of steel balls (10–20 per side, 4–12 mm apart, 1.5–3 mm
  balls) through an intensifier's distortion and round field
  (:func:`ftrac_design.calibration.gridplate.render_grid`) — another calibration phantom;
- **another fiducial**: a realistic image of one preset tracked as another (nine_bead's helix of
  balls as ftrac_2005, ftrac_2005 as ftrac_mini, …);
- **blank**: constant frames (8-bit, 16-bit, float, black and white);
- **noise**: Gaussian, Poisson counts, uniform 8-bit, salt and pepper.

Prints, per kind and preset, the images tracked and the poses given (target 0), and the time.

    .venv/bin/python benchmarks/no_fiducial.py --seed 909
"""

from __future__ import annotations

import argparse
import json
import math
import time
from collections import Counter
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import _common
import numpy as np
import track_realism as tr

from ftrac_design.calibration.gridplate import grid_plate, plate_pose, render_grid
from ftrac_design.images.distortion import combine, radial, s_distortion
from ftrac_design.pose import Camera, so3
from ftrac_design.pose.simulate import Workspace
from ftrac_design.segment import TrackOptions, ViewPrior, track_image
from ftrac_design.xray import ImagingModel
from ftrac_design.xray.scenario import CONDITIONS, realistic_image

ROOT = Path(__file__).resolve().parents[1]
KINDS = {"anatomy": 200, "grid plate": 100, "another fiducial": 120, "blank": 40, "noise": 60}


def anatomy(k: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng([seed, 1, k])
    features = tr.preset_features("ftrac_2005")
    R, t = Workspace().sample(1, features.nominal_beam_direction, rng)
    cam = Camera(principal_point_px=(1536.0, 512.0))
    cond = CONDITIONS[k % len(CONDITIONS)]
    img, _ = realistic_image(features, R[0], t[0], cam, cond, int(rng.integers(2**31)), shape=(1024, 2048))
    return np.ascontiguousarray(img[:, :1024])


def grid(k: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng([seed, 2, k])
    n = int(rng.integers(10, 21))
    plate = grid_plate(float(rng.uniform(4, 12)), n, n, float(rng.uniform(1.5, 3.0)))
    shape = (512, 512)
    dist = combine(
        radial(shape, k_mm_at_r=(rng.uniform(0.5, 3.0), 100.0), pixel_mm=0.44),
        s_distortion(shape, amplitude_px=rng.uniform(0, 3), radius_px=256.0),
    )
    pose = plate_pose(float(rng.uniform(0, 2 * np.pi)), tuple(rng.uniform(-0.2, 0.2, 2)), float(rng.uniform(600, 970)))
    imaging = ImagingModel(image_shape=shape, photons_per_px=float(rng.uniform(500, 5000)))
    return render_grid(plate, dist, pose=pose, imaging=imaging, field_radius_px=240.0, rng=rng).raw


def fiducial(k: int, seed: int) -> tuple[np.ndarray, str]:
    """A realistic image of one preset, and the preset it is to be tracked as (another)."""
    rng = np.random.default_rng([seed, 3, k])
    shown = tr.PRESETS[k % 3]
    features = tr.preset_features(shown)
    R, t = Workspace().sample(1, features.nominal_beam_direction, rng)
    cond = ("clean",) + CONDITIONS
    c = cond[int(rng.integers(len(cond)))]
    if c == "clean":
        from ftrac_design.xray import render

        img = render(features, R[0], t[0], Camera(), rng=rng).raw
    else:
        img, _ = realistic_image(features, R[0], t[0], Camera(), c, int(rng.integers(2**31)))
    return img, shown


def blank(k: int, seed: int) -> np.ndarray:
    kinds = [
        np.zeros((1024, 1024), np.uint8),
        np.full((1024, 1024), 255, np.uint8),
        np.full((1024, 1024), 3000, np.uint16),
        np.full((768, 1024), 0.7, np.float32),
    ]
    return kinds[k % len(kinds)]


def noise(k: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng([seed, 5, k])
    kind = k % 4
    if kind == 0:
        return rng.normal(0, 1, (1024, 1024)).astype(np.float32)
    if kind == 1:
        return rng.poisson(float(rng.uniform(50, 5000)), (1024, 1024)).astype(np.uint16)
    if kind == 2:
        return rng.integers(0, 256, (1024, 1024)).astype(np.uint8)
    img = np.full((1024, 1024), 128, np.uint8)
    m = rng.random((1024, 1024))
    img[m < 0.01] = 0
    img[m > 0.99] = 255
    return img


def one(task) -> list[dict]:
    kind, k, seed, within_deg = task
    shown = None
    if kind == "anatomy":
        img = anatomy(k, seed)
    elif kind == "grid plate":
        img = grid(k, seed)
    elif kind == "another fiducial":
        img, shown = fiducial(k, seed)
    elif kind == "blank":
        img = blank(k, seed)
    else:
        img = noise(k, seed)
    H, W = img.shape
    cam = Camera(principal_point_px=(W / 2, H / 2))
    rows = []
    for i, preset in enumerate(tr.PRESETS):
        if preset == shown:
            continue
        features = tr.preset_features(preset)
        opts = TrackOptions()
        if within_deg is not None:
            # a view a user might expect, at random: a prior only takes answers away
            rng = np.random.default_rng([seed, k, i, list(KINDS).index(kind)])
            opts = TrackOptions(view=ViewPrior(so3.uniform_rotations(1, rng)[0], math.radians(within_deg)))
        t0 = time.perf_counter()
        res = track_image(img, features, cam, opts)
        rows.append(
            {
                "kind": kind,
                "k": k,
                "preset": preset,
                "shown": shown,
                "pose": bool(res.pose.converged),
                "error": res.pose.error,
                "ms": (time.perf_counter() - t0) * 1e3,
            }
        )
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=909)
    ap.add_argument("--scale", type=float, default=1.0, help="multiply every kind's image count")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument(
        "--view-prior-deg",
        type=float,
        default=None,
        metavar="WITHIN",
        help="track with a view known beforehand (`track --expect-view`): a rotation drawn at random per "
        "tracking, admitting WITHIN degrees (default: no prior)",
    )
    ap.add_argument("--json", type=Path, default=ROOT / "outputs" / "no_fiducial.json")
    a = ap.parse_args()
    print(f"no_fiducial: {_common.machine()}")
    tasks = [
        (kind, k, a.seed, a.view_prior_deg) for kind, n in KINDS.items() for k in range(max(1, int(round(n * a.scale))))
    ]
    from tqdm import tqdm

    rows: list[dict] = []
    with ProcessPoolExecutor(a.workers) as ex:
        for part in tqdm(ex.map(one, tasks, chunksize=2), total=len(tasks), desc="images"):
            rows += part
    a.json.parent.mkdir(parents=True, exist_ok=True)
    a.json.write_text(json.dumps(rows))
    images = {(r["kind"], r["k"]) for r in rows}
    print(f"{len(images)} images with no fiducial of the design, {len(rows)} trackings")
    for kind in KINDS:
        for preset in tr.PRESETS:
            rs = [r for r in rows if r["kind"] == kind and r["preset"] == preset]
            if not rs:
                continue
            poses = [r for r in rs if r["pose"]]
            why = Counter((r["error"] or "?").split(":")[0][:40] for r in rs if not r["pose"])
            print(
                f"{kind:17s} as {preset:10s} {len(rs):4d} tracked, poses given {len(poses)}"
                f"{' (' + ', '.join(str(r['k']) for r in poses) + ')' if poses else ''}; "
                f"median {np.median([r['ms'] for r in rs]):4.0f} ms; refused as: "
                + "; ".join(f"{v} {w}" for w, v in why.most_common(2))
            )
    total = sum(r["pose"] for r in rows)
    print(f"poses given on images with no fiducial of the design: {total} of {len(rows)} trackings")


if __name__ == "__main__":
    main()
