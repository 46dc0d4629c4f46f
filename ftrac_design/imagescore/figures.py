"""The image-true score's figures from a trial's records: per condition, the share of images
refused and wrong, and the median and 95th percentile of the 3-D translation (mm) and rotation
(degrees) errors of the right poses, each p95 with a bootstrap 95 % interval (images resampled);
and two designs' paired ratios over the images both got right (common random numbers).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

#: bootstrap resamples of the intervals
BOOT = 2000
#: fewest right images for a p95 and its interval
MIN_RIGHT = 20


def _p95_interval(v: np.ndarray, rng: np.random.Generator) -> list[float]:
    k = rng.integers(0, len(v), (BOOT, len(v)))
    return [float(x) for x in np.percentile(np.percentile(v[k], 95, axis=1), [2.5, 97.5])]


def condition_figures(records: Sequence[dict[str, Any]], seed: int = 0) -> dict[str, Any]:
    """Figures of one condition's records (see the module).

    Parameters
    ----------
    records : sequence of dict
        :func:`ftrac_design.imagescore.trial.run_images` records of one condition.
    seed : int
        Seed of the bootstrap.

    Returns
    -------
    dict
        ``images``, ``right``, ``wrong``, ``refused`` (counts), ``refused_pct``, ``wrong_pct``,
        ``translation_median_mm``, ``translation_p95_mm``, ``translation_p95_95ci_mm``,
        ``rotation_median_deg``, ``rotation_p95_deg``, ``rotation_p95_95ci_deg`` (None with fewer
        than :data:`MIN_RIGHT` right images).
    """
    n = len(records)
    right = [r for r in records if r["outcome"] == "right"]
    counts = {o: sum(r["outcome"] == o for r in records) for o in ("right", "wrong", "refused")}
    out: dict[str, Any] = {
        "images": n,
        **counts,
        "refused_pct": 100.0 * counts["refused"] / n if n else None,
        "wrong_pct": 100.0 * counts["wrong"] / n if n else None,
    }
    rng = np.random.default_rng(seed)
    for name, key, unit in (("translation", "translation_mm", "mm"), ("rotation", "rotation_deg", "deg")):
        v = np.array([r[key] for r in right], float)
        ok = len(v) >= MIN_RIGHT
        out[f"{name}_median_{unit}"] = float(np.median(v)) if ok else None
        out[f"{name}_p95_{unit}"] = float(np.percentile(v, 95)) if ok else None
        out[f"{name}_p95_95ci_{unit}"] = _p95_interval(v, rng) if ok else None
    return out


def trial_figures(records: Sequence[dict[str, Any]], seed: int = 0) -> dict[str, dict[str, Any]]:
    """:func:`condition_figures` of each condition present in ``records``, by condition name."""
    conditions = list(dict.fromkeys(r["condition"] for r in records))
    return {c: condition_figures([r for r in records if r["condition"] == c], seed) for c in conditions}


def paired_ratios(
    reference: Sequence[dict[str, Any]], other: Sequence[dict[str, Any]], condition: str | None, seed: int = 0
) -> dict[str, Any] | None:
    """p95 of ``other`` over p95 of ``reference`` (translation and rotation) over the images of
    ``condition`` (None: of every condition, pooled) both got right, with a paired bootstrap 95 %
    interval; None when fewer than :data:`MIN_RIGHT` images are shared.

    Parameters
    ----------
    reference, other : sequence of dict
        Two trials' records at the same settings (the same poses and draws).
    condition : str or None
        Which condition's images; None pools every condition's.
    seed : int
        Seed of the bootstrap.

    Returns
    -------
    dict or None
        ``images``, ``translation_p95_ratio``, ``translation_p95_ratio_95ci``, ``rotation_…``.
    """

    def right(records: Sequence[dict[str, Any]]) -> dict[tuple[str, int], dict[str, Any]]:
        return {
            (r["condition"], r["k"]): r
            for r in records
            if r["outcome"] == "right" and condition in (None, r["condition"])
        }

    a, b = right(reference), right(other)
    common = sorted(set(a) & set(b))
    if len(common) < MIN_RIGHT:
        return None
    rng = np.random.default_rng(seed)
    k = rng.integers(0, len(common), (BOOT, len(common)))
    out: dict[str, Any] = {"images": len(common)}
    for name, key in (("translation", "translation_mm"), ("rotation", "rotation_deg")):
        x = np.array([a[i][key] for i in common])
        y = np.array([b[i][key] for i in common])
        boot = np.percentile(y[k], 95, axis=1) / np.percentile(x[k], 95, axis=1)
        out[f"{name}_p95_ratio"] = float(np.percentile(y, 95) / np.percentile(x, 95))
        out[f"{name}_p95_ratio_95ci"] = [float(v) for v in np.percentile(boot, [2.5, 97.5])]
    return out
