"""The tracker's answers on a fixed set of images, recorded in one environment and compared in another.

    python tests/pose_record.py write DIR     # renders the images, tracks them, writes DIR/images.npz, DIR/poses.json
    python tests/pose_record.py compare DIR   # tracks DIR's images here and compares with DIR/poses.json

``make test-latest`` writes the record with the newest releases (OpenCV 5.x) and compares it after
installing OpenCV 4.x into the same environment: the same images must give the same status, the
same bead labelling (each bead on the same blob, within 10⁻³ px) and a pose within 1 % of its own
standard deviation. The images are saved, not rendered again, so only the tracking differs
between the two runs. Exit 1 with one line per image that differs.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from ftrac_design.design import load_design
from ftrac_design.features import compute_features
from ftrac_design.pose import Camera
from ftrac_design.pose.simulate import Workspace
from ftrac_design.segment import track_image
from ftrac_design.xray import render
from ftrac_design.xray.scenario import realistic_image

PRESETS = ("ftrac_2005", "ftrac_mini", "nine_bead")
CONDITIONS = ("clean", "raw", "display-dark", "strong-anatomy")
PER = 3
SEED = 31


def _images() -> dict[str, tuple[str, np.ndarray]]:
    out = {}
    for preset in PRESETS:
        d = load_design(preset)
        features = compute_features(d)
        R, t = Workspace().sample(PER * len(CONDITIONS), features.nominal_beam_direction, np.random.default_rng(SEED))
        for c, cond in enumerate(CONDITIONS):
            for k in range(PER):
                i = c * PER + k
                if cond == "clean":
                    img = render(features, R[i], t[i], Camera(), rng=np.random.default_rng(SEED + i)).raw
                else:
                    img = realistic_image(features, R[i], t[i], Camera(), cond, SEED * 1000 + i)[0]
                out[f"{preset}/{cond}/{k}"] = (preset, img)
    return out


def _track(images: dict[str, tuple[str, np.ndarray]]) -> dict[str, dict]:
    cache: dict[str, object] = {}
    out = {}
    for key, (preset, img) in images.items():
        if preset not in cache:
            cache[preset] = compute_features(load_design(preset))
        features = cache[preset]
        res = track_image(img, features, Camera())
        obs = res.observation
        out[key] = {
            "converged": bool(res.pose.converged),
            "error": res.pose.error,
            "rotation": np.nan_to_num(res.pose.rotation).tolist(),
            "translation_mm": np.nan_to_num(res.pose.translation_mm).tolist(),
            "covariance": None if res.pose.covariance is None else np.asarray(res.pose.covariance).tolist(),
            "beads": {} if obs is None else {k: np.asarray(v).tolist() for k, v in obs.points.items()},
        }
    return out


def _differs(a: dict, b: dict) -> str | None:
    if a["converged"] != b["converged"]:
        return f"converged {a['converged']} → {b['converged']} ({b['error'] or a['error']})"
    if set(a["beads"]) != set(b["beads"]):
        return f"beads used {sorted(a['beads'])} → {sorted(b['beads'])}"
    moved = max((float(np.max(np.abs(np.subtract(a["beads"][k], b["beads"][k])))) for k in a["beads"]), default=0.0)
    if moved > 1e-3:
        return f"a bead's blob moved by {moved:.2e} px"
    if not a["converged"] or a["covariance"] is None:
        return None
    from ftrac_design.pose.simulate import pose_errors

    dr, dt = pose_errors(
        np.array(b["rotation"]), np.array(b["translation_mm"]), np.array(a["rotation"]), np.array(a["translation_mm"])
    )
    sd = np.sqrt(np.diag(np.array(a["covariance"])))
    worst = float(np.max(np.abs(np.r_[dr, dt]) / sd))
    return f"pose moved by {worst:.3f} of its σ" if worst > 0.01 else None


def main(argv: list[str]) -> int:
    if len(argv) != 2 or argv[0] not in ("write", "compare"):
        print(__doc__.splitlines()[2].strip(), file=sys.stderr)
        return 2
    folder = Path(argv[1])
    if argv[0] == "write":
        images = _images()
        folder.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(folder / "images.npz", **{k.replace("/", "|"): v for k, (_, v) in images.items()})
        (folder / "poses.json").write_text(json.dumps(_track(images)))
        print(f"{len(images)} images tracked, record in {folder}")
        return 0
    with np.load(folder / "images.npz") as z:
        images = {k.replace("|", "/"): (k.split("|")[0], z[k]) for k in z.files}
    before = json.loads((folder / "poses.json").read_text())
    now = _track(images)
    bad = {k: why for k in before if (why := _differs(before[k], now[k])) is not None}
    for k, why in bad.items():
        print(f"{k}: {why}")
    conv = sum(v["converged"] for v in before.values())
    print(f"{len(before) - len(bad)} of {len(before)} images tracked the same ({conv} converged in the record)")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
