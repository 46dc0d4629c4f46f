"""Held-out check: the tracker on images from the independent renderer (benchmarks/independent/).

For each of ftrac_2005, ftrac_mini and nine_bead: N workspace poses (SPEC §1), each rendered
by ``render_independent`` without and with the voxel pelvis (the built CAD parts, a
polychromatic beam, scatter, focal-spot and MTF blur, compound-Poisson noise; kVp, scatter
ratio and focal spot drawn per image), saved as 16-bit PNG with a truth JSON under
``outputs/independent/<preset>/<clean|patient>/`` (reused on the next run unless
``--render``), then tracked with the package's defaults through :func:`track` and printed:

- tracked: converged and right (≤ 1° and ≤ 3 mm);
- confident wrong: converged, > 1° or > 3 mm off, and improbable under the pose's own
  covariance (χ²₆ > 25.7, p < 1e-4; target 0); far-but-honest: as far, the covariance saying so;
- not converged, with the reasons;
- RMS pose error per camera axis (° and mm) over the right ones;
- render and track time per image (median);

and the same again with the tracker told the images' polarity (raw counts are dense-dark, as
a DICOM header's photometric interpretation would say), which separates polarity detection
from the rest of the image path.

The tracker is not tuned on these images: they are held out.

    .venv/bin/python benchmarks/independent_check.py                 # N = 30 per preset
    .venv/bin/python benchmarks/independent_check.py --n 5 --presets ftrac_mini
    .venv/bin/python benchmarks/independent_check.py --figure         # docs/img/independent_render.png
"""

from __future__ import annotations

import argparse
import json
import math
import time
from collections import Counter
from pathlib import Path

import _common  # noqa: F401  (puts the checkout first on sys.path)
import cv2
import numpy as np
from _common import view_prior
from independent import render_independent
from independent.fiducial import build_digest, cached_build
from independent.render import renderer_digest
from tqdm import tqdm

from ftrac_design.design import load_design
from ftrac_design.features import compute_features
from ftrac_design.pose import Camera
from ftrac_design.pose.simulate import Workspace, pose_errors

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "outputs" / "independent"
PRESETS = ("ftrac_2005", "ftrac_mini", "nine_bead")
AXES = ("rx", "ry", "rz", "tx", "ty", "tz")
WRONG_DEG, WRONG_MM, CHI2_6 = 1.0, 3.0, 25.7


def track(image: np.ndarray, features, camera: Camera, polarity_hint: str | None = None, view=None):
    """The package's tracker with its default options (``view``: a view known beforehand, else
    none): (converged, R, t, covariance, error message).

    ``polarity_hint`` ("dense_dark" for raw counts) is what a DICOM header's photometric
    interpretation would tell it; None lets the tracker detect the polarity. The one place
    this benchmark calls the tracker, so an API change is mended here.
    """
    from ftrac_design.segment import TrackOptions
    from ftrac_design.segment.pipeline import track_image

    res = track_image(image, features, camera, TrackOptions(view=view), polarity_hint=polarity_hint)
    p = res.pose
    cov = None if p.covariance is None else np.asarray(p.covariance, float)
    return bool(p.converged), np.asarray(p.rotation, float), np.asarray(p.translation_mm, float), cov, p.error


def physics(seed: int) -> dict:
    """The per-image beam and detector settings drawn from ``seed``."""
    rng = np.random.default_rng(seed)
    return {
        "kvp": float(rng.uniform(70, 90)),
        "spr": float(rng.uniform(0.5, 3.0)),
        "focal_spot_mm": float(rng.uniform(0.6, 1.0)),
    }


def reusable(png: Path, js: Path, R: np.ndarray, t: np.ndarray, img_seed: int, dose: float, build: str) -> bool:
    """Whether a saved image was rendered at this pose, seed and dose, by this renderer, from
    the build of digest ``build`` (:func:`independent.fiducial.build_digest`): an image of parts
    the package no longer builds, or drawn by another version of the renderer, is drawn again."""
    if not (png.is_file() and js.is_file()):
        return False
    try:
        tr = json.loads(js.read_text(encoding="utf-8"))
        return (
            tr.get("build_sha256") == build
            and tr.get("renderer_sha256") == renderer_digest()
            and tr["seed"] == img_seed
            and tr["dose_behind_patient"] == dose
            and np.allclose(tr["rotation"], R)
            and np.allclose(tr["translation_mm"], t)
        )
    except (ValueError, KeyError, TypeError):
        return False


def image_set(preset: str, n: int, seed: int, patient: bool, dose: float, render: bool, camera: Camera):
    """Paths of N rendered images (PNG, JSON) of ``preset``, rendering those missing; render seconds."""
    design = load_design(preset)
    feats = compute_features(design)
    R, t = Workspace().sample(n, feats.nominal_beam_direction, np.random.default_rng(seed))
    folder = OUT / preset / ("patient" if patient else "clean")
    build = build_digest(cached_build(preset))
    folder.mkdir(parents=True, exist_ok=True)
    out, times = [], []
    for k in tqdm(range(n), desc=f"render {preset} {'patient' if patient else 'clean'}", leave=False):
        png, js = folder / f"img_{k:03d}.png", folder / f"img_{k:03d}.json"
        img_seed = seed * 100003 + k
        if render or not reusable(png, js, R[k], t[k], img_seed, dose, build):
            t0 = time.perf_counter()
            counts, truth = render_independent(
                preset,
                R[k],
                t[k],
                camera,
                dose_behind_patient=dose,
                patient=patient,
                seed=img_seed,
                **physics(img_seed),
            )
            times.append(time.perf_counter() - t0)
            if not cv2.imwrite(str(png), counts):
                raise OSError(f"could not write {png}")
            js.write_text(json.dumps(truth, indent=1), encoding="utf-8")
        out.append((png, js))
    return feats, out, times


def evaluate(feats, items, camera: Camera, polarity_hint: str | None = None, view_deg=None, seed: int = 0) -> dict:
    """Track every image and tally right, confident-wrong and not-converged answers; with
    ``view_deg`` (off, within), each with its true view known beforehand (:func:`_common.view_prior`)."""
    errs, wrong, far, reasons, times = [], [], [], Counter(), []
    for k, (png, js) in enumerate(tqdm(items, desc="track", leave=False)):
        img = cv2.imread(str(png), cv2.IMREAD_UNCHANGED)
        truth = json.loads(js.read_text(encoding="utf-8"))
        view = None if view_deg is None else view_prior(np.array(truth["rotation"]), *view_deg, seed, k)
        t0 = time.perf_counter()
        ok, R, t, cov, err = track(img, feats, camera, polarity_hint, view)
        times.append(time.perf_counter() - t0)
        if not ok:
            reasons[(err or "?").split(":")[0][:60]] += 1
            continue
        dr, dt = pose_errors(R, t, np.array(truth["rotation"]), np.array(truth["translation_mm"]))
        if math.degrees(np.linalg.norm(dr)) > WRONG_DEG or np.linalg.norm(dt) > WRONG_MM:
            e = np.r_[dr, dt]
            honest = cov is not None and float(e @ np.linalg.solve(cov, e)) <= CHI2_6
            (far if honest else wrong).append(k)
            continue
        errs.append(np.r_[np.degrees(dr), dt])
    errs = np.array(errs).reshape(-1, 6)
    return {
        "n": len(items),
        "right": len(errs),
        "wrong": wrong,
        "far": far,
        "not_converged": sum(reasons.values()),
        "reasons": dict(reasons),
        "rms": np.sqrt(np.mean(errs**2, 0)) if len(errs) else np.full(6, np.nan),
        "track_s": float(np.median(times)) if times else math.nan,
    }


def show(label: str, r: dict, render_times: list[float]) -> None:
    n = r["n"]
    print(
        f"\n{label}: {n} images — tracked (≤ {WRONG_DEG:g}°, ≤ {WRONG_MM:g} mm) {r['right']} "
        f"({100 * r['right'] / max(n, 1):.0f} %); CONFIDENT WRONG {len(r['wrong'])}"
        f"{' ' + str(r['wrong'][:20]) if r['wrong'] else ''}; far-but-honest {len(r['far'])}"
        f"{' ' + str(r['far'][:20]) if r['far'] else ''}; "
        f"not converged {r['not_converged']} {r['reasons'] or ''}"
    )
    print("                        " + "  ".join(f"{a:>8s}" for a in AXES) + "   (° and mm, camera axes)")
    print("  RMS error (tracked) : " + "  ".join(f"{x:8.4f}" for x in r["rms"]))
    rt = f"{np.median(render_times):.2f} s" if render_times else "none (reused)"
    print(f"  median time per image: render {rt}, track {r['track_s']:.2f} s")


def figure(path: Path, preset: str = "ftrac_2005", seed: int = 11) -> None:
    """Our simulator vs the independent renderer at one pose: full images and a zoom."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ftrac_design.xray import ImagingModel, anatomy, render

    feats = compute_features(load_design(preset))
    R, t = Workspace().sample(1, feats.nominal_beam_direction, np.random.default_rng(seed))
    cam = Camera()
    ours = render(
        feats, R[0], t[0], cam, ImagingModel(), rng=np.random.default_rng(seed), background=anatomy(seed=seed)
    ).raw.astype(float)
    theirs, truth = render_independent(preset, R[0], t[0], cam, dose_behind_patient=1000, patient=True, seed=seed)
    theirs = theirs.astype(float) - truth["detector"]["offset_adu"]
    u, v = cam.project(t[0])
    half = 130
    r0, c0 = int(v) - half, int(u) - half
    fig, ax = plt.subplots(2, 2, figsize=(11, 11))
    for j, (img, name) in enumerate(
        (
            (ours, "ftrac_design.xray (ours): one energy, 2-D anatomy"),
            (theirs, "benchmarks/independent: CAD parts, voxel pelvis, 80 kVp"),
        )
    ):
        dens = -np.log(np.maximum(img, 1.0))
        ax[0, j].imshow(dens, cmap="gray", vmin=np.percentile(dens, 0.5), vmax=np.percentile(dens, 99.8))
        ax[0, j].add_patch(plt.Rectangle((c0, r0), 2 * half, 2 * half, fill=False, color="orange", lw=1))
        ax[0, j].set_title(name, fontsize=9)
        z = dens[max(r0, 0) : r0 + 2 * half, max(c0, 0) : c0 + 2 * half]
        ax[1, j].imshow(z, cmap="gray", vmin=np.percentile(z, 0.5), vmax=np.percentile(z, 99.9))
        ax[1, j].set_title("zoom on the fiducial (−log counts)", fontsize=9)
        for a in ax[:, j]:
            a.set_xticks([])
            a.set_yticks([])
    fig.suptitle(f"{preset}, the same pose (seed {seed}): our simulator vs the held-out renderer", fontsize=11)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    print(f"wrote {path}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=30, help="workspace poses per preset")
    ap.add_argument("--presets", nargs="+", default=list(PRESETS))
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument(
        "--dose",
        type=float,
        default=1000.0,
        help="quanta per pixel behind the patient at the fiducial (patient images)",
    )
    ap.add_argument("--dose-clean", type=float, default=3000.0, help="quanta per pixel in the open field (no patient)")
    ap.add_argument("--render", action="store_true", help="render again even where images exist")
    ap.add_argument("--figure", action="store_true", help="write docs/img/independent_render.png and stop")
    _common.add_view_prior_argument(ap, also=True)
    a = ap.parse_args()
    if a.figure:
        figure(ROOT / "docs" / "img" / "independent_render.png")
        return
    cam = Camera()
    print(
        f"independent_check: {a.n} workspace poses per preset, seed {a.seed}; kVp 70–90, SPR 0.5–3, "
        f"focal spot 0.6–1.0 mm per image; dose {a.dose:g} quanta/px behind the patient, {a.dose_clean:g} "
        f"in the open field without; tracker defaults"
    )
    for preset in a.presets:
        for patient in (False, True):
            feats, items, rt = image_set(
                preset, a.n, a.seed, patient, a.dose if patient else a.dose_clean, a.render, cam
            )
            label = f"{preset} {'over the voxel pelvis' if patient else 'no patient'}"
            show(label, evaluate(feats, items, cam), rt)
            show(f"{label}, told the polarity (raw counts: dense-dark)", evaluate(feats, items, cam, "dense_dark"), [])
            if a.view_prior_deg is not None:
                off, within = a.view_prior_deg
                r = evaluate(feats, items, cam, None, a.view_prior_deg, a.seed)
                show(f"{label}, its view known to {within:g}° ({off:g}° off)", r, [])


if __name__ == "__main__":
    main()
