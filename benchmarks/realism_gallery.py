"""The realistic test images, one per condition: ``docs/img/realism_gallery.png``.

ftrac_2005 at one workspace pose (sample seed 4), :func:`ftrac_design.xray.scenario.realistic_image`
for each of its ten conditions (seed 3), shown as stored (linear counts and log line integrals
windowed to their 0.5–99.5 percentiles, display frames as they are), each with a zoom of the
fiducial's neighbourhood; the title names the patient view, the polarity and the dose behind
the patient. Prints the time per image (a benchmark of thousands of images needs ≤ ~0.3 s).

Run: ``.venv/bin/python benchmarks/realism_gallery.py``
"""

from __future__ import annotations

import time

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from _common import ROOT, load, machine  # noqa: E402

from ftrac_design.pose.camera import Camera  # noqa: E402
from ftrac_design.pose.simulate import Workspace  # noqa: E402
from ftrac_design.xray.scenario import CONDITIONS, realistic_image  # noqa: E402

OUT = ROOT / "docs" / "img" / "realism_gallery.png"
SEED = 3


def shown(img: np.ndarray, info: dict) -> tuple[np.ndarray, float, float]:
    """The image and the grey range to show it with: display frames as stored, others windowed."""
    if info["formation"] == "display":
        top = 255 if img.dtype == np.uint8 else 65535
        return img, 0, top
    vals = img[info["field_mask"]] if info["field_mask"].any() else img
    lo, hi = np.percentile(vals[::7], (0.5, 99.5))
    return img, float(lo), float(hi)


def main() -> None:
    features = load("ftrac_2005")
    R, t = Workspace().sample(1, features.nominal_beam_direction, np.random.default_rng(4))
    cam = Camera()
    fig, axes = plt.subplots(2, 5, figsize=(25, 11.4))
    times = []
    for ax, cond in zip(axes.flat, CONDITIONS):
        t0 = time.perf_counter()
        img, info = realistic_image(features, R[0], t[0], cam, cond, seed=SEED)
        times.append(time.perf_counter() - t0)
        im, lo, hi = shown(img, info)
        ax.imshow(im, cmap="gray", vmin=lo, vmax=hi, interpolation="lanczos")
        u0, v0, u1, v1 = info["fiducial_box"]
        pad = 25
        box = (max(u0 - pad, 0), max(v0 - pad, 0), min(u1 + pad, img.shape[1]), min(v1 + pad, img.shape[0]))
        ax.add_patch(
            plt.Rectangle((box[0], box[1]), box[2] - box[0], box[3] - box[1], fill=False, ec="#f5a623", lw=1.0)
        )
        inset = ax.inset_axes([0.60, 0.0, 0.40, 0.40])
        inset.imshow(im[box[1] : box[3], box[0] : box[2]], cmap="gray", vmin=lo, vmax=hi, interpolation="nearest")
        inset.set_xticks([])
        inset.set_yticks([])
        for sp in inset.spines.values():
            sp.set_edgecolor("#f5a623")
        p = info["patient"]
        ax.set_title(
            f"{cond}: {info['formation']} {img.dtype}, {info['polarity']}\n{p['kind']}, "
            f"{p['thickness_mm']:.0f} mm, {info['counts_behind_patient']:.0f} quanta/px behind, "
            f"σ {info['blur_sigma_px']:.1f} px",
            fontsize=10,
        )
        ax.set_xticks([])
        ax.set_yticks([])
        print(
            f"{cond:15s} {1e3 * times[-1]:6.0f} ms  {info['formation']:8s} {info['polarity']:12s} "
            f"{p['kind']:8s} line integral {p['line_integral'][0]:.2f}–{p['line_integral'][2]:.2f}"
        )
    fig.suptitle(
        "ftrac_2005 at one workspace pose, realistic_image for each condition (seed 3); "
        "inset: the fiducial's neighbourhood",
        fontsize=13,
    )
    fig.tight_layout(rect=(0, 0, 1, 0.96))
    OUT.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(OUT, dpi=72)
    print(f"{machine()}\nmedian {1e3 * np.median(times):.0f} ms per 1024² image; wrote {OUT.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
