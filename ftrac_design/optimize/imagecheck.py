"""The start and the winner on rendered radiographs: render → track → pose errors.

The search scores designs by the Cramér–Rao bound of a feature-level noise model, and the
solver check draws its observations from that same model, so neither can say whether the
gain survives a real image: rendering (:func:`ftrac_design.xray.render`), segmentation,
identification and the solve with no initial guess (:func:`ftrac_design.segment.track_image`)
err in ways the model does not describe (overlapping features, segmentation bias, wrong
labellings). :func:`image_check` renders both designs at the same workspace poses with the
same noise draws (common random numbers) and reports robust statistics of the 3-D errors —
the p95 is what the objective promised.
"""

from __future__ import annotations

import numpy as np

#: a converged pose further off than this is a wrong answer (as ``benchmarks/track_accuracy.py``)
WRONG_DEG, WRONG_MM = 1.0, 5.0


def image_check(data: dict, settings, images: int, seed: int, progress: bool = False) -> dict:
    """Render ``images`` radiographs of design ``data`` at workspace poses of ``settings``
    (an :class:`~ftrac_design.analysis.score.AnalysisSettings`; pose seed ``seed``, noise seed
    ``seed + 1``) with the default imaging model and the design's body, track each with no
    initial guess, and summarise the errors of the converged, right poses: median, p95 and
    RMS of the 3-D translation (mm) and rotation (°) errors; ``converged`` and ``wrong``
    (converged but > 1° or > 5 mm off) counts."""
    from tqdm import tqdm

    from ..analysis.sampling import workspace_poses
    from ..design.loader import parse_design
    from ..features import compute_features
    from ..pose.simulate import pose_errors
    from ..segment.pipeline import track_image
    from ..xray import ImagingModel, render

    design = parse_design(data)
    f = compute_features(design)
    R, t = workspace_poses(settings.workspace, f.nominal_beam_direction, images, seed)
    cam, imaging = settings.camera, ImagingModel()
    et, er, idx, converged, wrong = [], [], [], 0, 0
    for k in tqdm(range(images), desc=f"images: {f.name}", unit="image", leave=False, disable=not progress):
        rad = render(f, R[k], t[k], cam, imaging, rng=np.random.default_rng([seed + 1, k]))
        p = track_image(rad.raw, f, cam).pose
        if not p.converged:
            continue
        converged += 1
        dr, dt = pose_errors(p.rotation, p.translation_mm, R[k], t[k])
        a, d = float(np.degrees(np.linalg.norm(dr))), float(np.linalg.norm(dt))
        if a > WRONG_DEG or d > WRONG_MM:
            wrong += 1
            continue
        et.append(d)
        er.append(a)
        idx.append(k)
    out: dict = {"images": images, "pose_seed": seed, "converged": converged, "wrong": wrong, "right": len(et)}
    for name, v, unit in (("translation", np.array(et), "mm"), ("rotation", np.array(er), "deg")):
        for stat, fn in (
            ("median", np.median),
            ("p95", lambda a: np.percentile(a, 95)),
            ("rms", lambda a: np.sqrt(np.mean(a**2))),
        ):
            out[f"{name}_{stat}_{unit}"] = float(fn(v)) if len(v) else None
    out["per_image"] = {"index": idx, "translation_mm": et, "rotation_deg": er}
    return out


def paired_p95_ratio(start: dict, best: dict, boot: int = 2000, seed: int = 0) -> dict | None:
    """p95 of best over p95 of start, translation and rotation, over the poses both got right
    (two :func:`image_check` results at the same poses), with a bootstrap 95 % interval (the
    poses resampled in pairs): a p95 over a few hundred images is uncertain by about ±10 %.
    None when fewer than 20 poses are shared."""
    a, b = start["per_image"], best["per_image"]
    common, ia, ib = np.intersect1d(a["index"], b["index"], return_indices=True)
    if len(common) < 20:
        return None
    out: dict = {"poses": int(len(common))}
    rng = np.random.default_rng(seed)
    k = rng.integers(0, len(common), (boot, len(common)))
    for name, key in (("translation", "translation_mm"), ("rotation", "rotation_deg")):
        x, y = np.asarray(a[key])[ia], np.asarray(b[key])[ib]
        bs = np.percentile(y[k], 95, axis=1) / np.percentile(x[k], 95, axis=1)
        out[f"{name}_p95_ratio"] = float(np.percentile(y, 95) / np.percentile(x, 95))
        out[f"{name}_p95_ratio_95ci"] = [float(v) for v in np.percentile(bs, [2.5, 97.5])]
    return out


def image_true_check(start_data: dict, best_data: dict, trial, executor=None, progress: bool = False) -> dict:
    """The winner of an image-scored search against its start on a fresh image-true trial: both
    designs rendered at the same ``trial`` (an :class:`~ftrac_design.imagescore.TrialSettings`
    whose seed the search never used; clean and over a patient, common random numbers) and
    tracked with the default options.

    Parameters
    ----------
    start_data, best_data : dict
        The two designs' TOML data.
    trial : ftrac_design.imagescore.TrialSettings
        The fresh sample.
    executor : concurrent.futures.Executor or None
        Where the images are made and tracked (None: here).
    progress : bool
        Show a progress bar.

    Returns
    -------
    dict
        ``settings`` (the trial's imaging model), ``start`` and ``best`` (per-condition figures,
        :func:`ftrac_design.imagescore.trial_figures`), ``paired`` (best over start per condition
        and ``pooled`` over every condition, :func:`ftrac_design.imagescore.paired_ratios`; None
        where fewer than 20 images were right for both).
    """
    from tqdm import tqdm

    from ..design.loader import parse_design
    from ..features import compute_features
    from ..imagescore import paired_ratios, run_trial, trial_figures

    records = {}
    total = 2 * trial.images * len(trial.conditions)
    with tqdm(total=total, desc="image-true check", unit="image", leave=False, disable=not progress) as bar:
        for name, data in (("start", start_data), ("best", best_data)):
            design = parse_design(data)
            records[name] = run_trial(compute_features(design), trial, executor, bar.update)
    paired = {c: paired_ratios(records["start"], records["best"], c, trial.seed) for c in trial.conditions}
    paired["pooled"] = paired_ratios(records["start"], records["best"], None, trial.seed)
    return {
        "settings": trial.describe(),
        "start": trial_figures(records["start"], trial.seed),
        "best": trial_figures(records["best"], trial.seed),
        "paired": paired,
    }
