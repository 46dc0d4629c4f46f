"""``make demo`` step: a small fiducial's near-mirror tie, settled by the view known beforehand.

The 1 × 1 × 2 cm ``ftrac_mini`` 600 mm from the source is seen in near-affine projection,
where a labelling turned 135–180° puts every ball and wire within a fraction of a pixel of the
right one's. Most such ties the image's own pixels settle (:mod:`ftrac_design.segment.pixelfit`);
:func:`demo_step` writes, under its ``out_dir``, a log-converted frame of it over a patient
where they do not (``image.npy``: the realism benchmark's ``log`` image 12 of tuning seed 21,
where the pixels prefer the right labelling by 2.9 units, short of the 3 that settle a tie),
its ``camera.json``, ``features.json`` and ``truth.json``, and a pose file of the view as a user
might know it beforehand (``expected_view.json``: the true rotation turned 25°), then runs
``ftrac-design track`` on the frame twice, as a user types it: alone (``alone/pose.json``:
refused as ambiguous, both answers in ``segmentation.alternatives``) and with
``--expect-view expected_view.json --view-within-deg 45`` (``with_view/pose.json``). It prints
each command, what it answered against the truth, and for the refusal how far each of its two
answers is from the truth.

Like every demo step it sits above the command line it drives.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from ..fileio import atomic_file, write_json_atomic
from .carm import format_errors, pose_report, truth_object
from .shell import command_line, relative, run_cli

#: where the tie is: the realism benchmark's image (``track_realism.make_image``)
PRESET, CONDITION, SEED, IMAGES, INDEX = "ftrac_mini", "log", 21, 20, 12
#: how far the expected view is turned from the truth, and how far it admits (degrees)
OFF_DEG, WITHIN_DEG = 25.0, 45.0


def write_inputs(out_dir: Path) -> tuple[Path, np.ndarray, np.ndarray]:
    """Write the frame, its camera, the design's features, the truth and the expected view
    into ``out_dir``; returns the features file and the true pose (R, t) (F → X, mm)."""
    from ..design import load_design
    from ..features import compute_features, write_features
    from ..pose import Camera, so3
    from ..pose.simulate import Workspace
    from ..xray.scenario import realistic_image

    features = compute_features(load_design(PRESET))
    R, t = Workspace().sample(IMAGES, features.nominal_beam_direction, np.random.default_rng(SEED))
    R, t = R[INDEX], t[INDEX]
    camera = Camera()
    image, _ = realistic_image(features, R, t, camera, CONDITION, SEED * 100_000 + INDEX)
    with atomic_file(out_dir / "image.npy") as tmp:
        np.save(tmp, image)
    write_json_atomic(out_dir / "camera.json", camera.to_dict())
    write_json_atomic(out_dir / "truth.json", truth_object(R, t))
    axis = np.random.default_rng(0).normal(size=3)
    expected = so3.exp(axis / np.linalg.norm(axis) * math.radians(OFF_DEG)) @ R
    # the translation is not read: only the rotation is the user's word
    write_json_atomic(out_dir / "expected_view.json", truth_object(expected, t))
    return write_features(out_dir / "features.json", features), R, t


def _alternatives_line(pose: dict, R: np.ndarray) -> str:
    """How far each answer of a refused tie is from the true rotation."""
    from ..pose import so3

    alts = (pose.get("segmentation") or {}).get("alternatives") or []
    off = [math.degrees(float(so3.angle(np.asarray(a["rotation"], float), R))) for a in alts]
    return "    its two answers: " + " and ".join(f"{a:.1f}°" for a in off) + " from the true rotation" if off else ""


def demo_step(out_dir: str | Path) -> str:
    """Write the frame and the expected view into ``out_dir``, track the frame alone and with the
    view known beforehand through the command line, and return the text the demo prints (see
    the module); paths relative to the working directory where inside it."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    features, R, t = write_inputs(out_dir)
    base = ["track", "--features", features, out_dir / "image.npy", "--camera", out_dir / "camera.json"]
    lines = [
        f"view known beforehand: {PRESET} (1 × 1 × 2 cm) over a patient, log-converted — "
        f"{relative(out_dir / 'image.npy')}"
    ]
    runs = (
        ("alone", []),
        ("with_view", ["--expect-view", out_dir / "expected_view.json", "--view-within-deg", f"{WITHIN_DEG:g}"]),
    )
    for name, extra in runs:
        args = [*base, "-o", out_dir / name / "pose.json", *extra]
        (out_dir / name).mkdir(exist_ok=True)
        run_cli(args)
        pose = json.loads((out_dir / name / "pose.json").read_text("utf-8"))
        lines += [f"  {command_line(args)}", "    " + format_errors(pose_report(pose, R, t))]
        if not pose.get("converged"):
            lines.append(_alternatives_line(pose, R))
    return "\n".join(line for line in lines if line)
