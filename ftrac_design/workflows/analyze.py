"""``analysis.json`` and the run behind ``ftrac-design analyze`` / ``compare``.

``analysis.json`` (format ``ftrac-analysis``, version 1) holds: the design it scores
(name, source, sha256), the settings (workspace, segmentation error, camera, poses, seed),
the thresholds, the score figures and checks with the verdict, per-group figures (points,
lines, ellipses alone), per-feature figures (own rank ratio, fraction of the workspace where
it is blind, smallest view angle, the score without it), the worst workspace poses, the
atlas summary with the worst view directions and the features responsible, the
segmentability block (image clearances between features over the workspace and the sphere,
overlap shares per kind and pair, worst poses; :mod:`ftrac_design.analysis.segmentability`), with ``--imaging`` an
``imaging`` block (pixel-level vs feature-level predicted errors at a smaller pose sample;
:mod:`ftrac_design.intensity.workspace`, computed by the caller), and the PNG files
written beside it. Lengths mm, angles degrees (keys say ``_deg``), errors are predicted 1σ.

Two scores, clearly apart: ``image_score`` — the image-true score (:mod:`ftrac_design.imagescore`:
a seeded sample of workspace poses rendered clean and over a patient and tracked; the share
refused and wrong, the p95 of the right poses' errors with intervals, its imaging model and every
image's record), the default and the one to rank designs by; and ``figures``/``checks``/``groups``/
``features`` — the paper's model (the feature-level Cramér–Rao bound with the paper's uniform
segmentation error), kept for its per-feature and per-direction insight and its thresholds.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from concurrent.futures import Executor
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Protocol

from ..analysis.atlas import Atlas, blind_spot_atlas
from ..analysis.score import AnalysisSettings, DesignScore, Thresholds, score_design
from ..analysis.segmentability import SegmentabilityAtlas, segmentability_atlas
from ..analysis.subject import Subject
from ..features.model import Features
from ..fileio import atomic_directory, check_output_dir, json_format_is, write_json_atomic
from ..imagescore import TrialSettings, run_trial, trial_figures
from ..imagescore.atlas import AtlasSettings, image_atlas, plot_image_atlas

FORMAT = "ftrac-analysis"
VERSION = 1
PLOTS = {
    "score": "score.png",
    "sphere": "atlas_sphere.png",
    "cone": "atlas_cone.png",
    "segmentability": "segmentability.png",
}
IMAGE_SCORE_PLOT = "image_score.png"
IMAGE_ATLAS_PLOT = "image_atlas.png"
#: what the feature-level figures are, in the summary and analysis.json
PAPER_MODEL = (
    "the paper's model: feature-level Cramér–Rao bound, uniform segmentation error per feature (Jain et al. 2005)"
)
#: the segmentability sphere map's grid is no finer than this (~0.1 ms a direction)
SEGMENTABILITY_ATLAS_STEP_DEG = 3.0


class ImagingBlock(Protocol):
    """What ``run_analysis`` needs of a pixel-level analysis (e.g.
    :class:`ftrac_design.intensity.workspace.ImagingAnalysis`): its analysis.json block and
    its picture."""

    def to_dict(self) -> dict[str, Any]: ...

    def plot(self, path: Path) -> Path: ...


def analysis_document(
    subject: Subject,
    score: DesignScore,
    atlas: Atlas | None,
    seconds: float,
    files: list[str],
    seg_atlas: SegmentabilityAtlas | None = None,
) -> dict:
    """The analysis.json object (see module doc)."""
    from .. import __version__

    f = subject.features
    doc = {
        "format": FORMAT,
        "version": VERSION,
        "units": {"length": "mm", "angle": "deg"},
        "design": {"name": f.name, "source": f.source, "sha256": f.sha256, "input": str(subject.path)},
        "settings": score.settings.to_dict(),
        "passed": score.passed,
    }
    doc.update(score.to_dict())
    doc["atlas"] = atlas.to_dict() if atlas is not None else None
    if doc.get("segmentability") is not None:
        doc["segmentability"]["atlas"] = seg_atlas.to_dict() if seg_atlas is not None else None
    doc["files"] = files
    doc["time_s"] = round(seconds, 3)
    doc["package_version"] = __version__
    return doc


def _check_output_dir(out_dir: Path) -> None:
    """Refuse to replace anything but an empty directory or an earlier analysis."""
    check_output_dir(out_dir, "an earlier analysis", lambda d: json_format_is(d / "analysis.json", FORMAT))


def default_output_dir(features: Features) -> Path:
    """``outputs/<design name>/analysis``."""
    return Path("outputs") / features.name / "analysis"


@dataclass(frozen=True)
class ImageScoring:
    """The image-true part of an analysis, resolved once from the command line: the score's sample
    (None: not computed), its atlas' grid (None: not computed) and the processes that render and
    track (None: one per core; 0: this process)."""

    trial: TrialSettings | None = field(default_factory=TrialSettings)
    atlas: AtlasSettings | None = field(default_factory=AtlasSettings)
    workers: int | None = None

    @classmethod
    def from_options(
        cls, score_images: int, score_seed: int = 0, image_atlas_step_deg: float = 0.0, workers: int | None = None
    ) -> "ImageScoring":
        """From the commands' ``--score-images``, ``--score-seed``, ``--image-atlas-step-deg`` and
        ``--workers`` (0 images or a 0° step: that part is not computed)."""
        return cls(
            TrialSettings(images=score_images, seed=score_seed) if score_images else None,
            AtlasSettings(step_deg=image_atlas_step_deg, seed=score_seed) if image_atlas_step_deg else None,
            workers,
        )

    @property
    def any(self) -> bool:
        """Whether any image is rendered."""
        return self.trial is not None or self.atlas is not None

    def images(self) -> int:
        """How many images it renders and tracks (for progress bars)."""
        n = self.trial.images * len(self.trial.conditions) if self.trial is not None else 0
        if self.atlas is not None:
            n += round(360 / self.atlas.step_deg) * round(180 / self.atlas.step_deg) * self.atlas.rolls
        return n


def subject_body(subject: Subject):
    """The body of what is analysed, as rendered and known to the tracker: the design's, or for a
    features file the body of the design its ``source`` names when that file exists (else None)."""
    from ..xray import Body
    from ..xray.render import AUTO, resolve_body

    return Body.from_design(subject.design) if subject.design is not None else resolve_body(subject.features, AUTO)


def image_score_block(trial: TrialSettings, records: list[dict], seconds: float) -> dict[str, Any]:
    """analysis.json's ``image_score`` block: the imaging model, the figures per condition, every
    image's record and the time it took (s)."""
    return {
        "name": "image-true score",
        "model": trial.describe(),
        "figures": trial_figures(records, trial.seed),
        "records": records,
        "time_s": round(seconds, 3),
    }


def run_analysis(
    subject: Subject,
    settings: AnalysisSettings,
    thresholds: Thresholds,
    out_dir: Path | None,
    atlas_step_deg: float = 2.0,
    plots: bool = True,
    progress: Callable[[int], None] | None = None,
    imaging: Callable[[Callable[[int], None] | None], ImagingBlock] | None = None,
    trial: TrialSettings | None = None,
    executor: Executor | None = None,
    image_atlas_settings: AtlasSettings | None = None,
) -> tuple[dict, Path]:
    """Score and map ``subject``, write analysis.json (+ PNGs) into ``out_dir`` atomically.

    Parameters
    ----------
    subject, settings, thresholds
        What is analysed, and how (the paper's model's workspace, noise and thresholds).
    out_dir : pathlib.Path or None
        Output directory (default :func:`default_output_dir`); replaced only if it holds an
        earlier analysis.
    atlas_step_deg : float
        Grid step of the whole-sphere atlas, degrees.
    plots : bool
        Write the PNGs.
    progress : callable or None
        Called with the number of poses, directions or images done.
    imaging : callable or None
        A function of the progress callback returning a pixel-level analysis to put beside the
        feature-level one (the ``imaging`` block and imaging.png), such as
        :func:`ftrac_design.intensity.workspace.imaging_analysis` with its arguments bound.
    trial : TrialSettings or None
        The image-true score's sample (None: not computed); its workspace and camera are those
        of ``settings``.
    executor : concurrent.futures.Executor or None
        Where the trial's and the image atlas' images are rendered and tracked (None: here).
    image_atlas_settings : AtlasSettings or None
        The image-true blind-spot atlas' grid (None: not computed); depth and camera from
        ``settings``.

    Returns
    -------
    (dict, pathlib.Path)
        The analysis.json object and the directory written.
    """
    out_dir = Path(out_dir) if out_dir is not None else default_output_dir(subject.features)
    _check_output_dir(out_dir)
    t0 = time.perf_counter()
    records = None
    body = subject_body(subject) if trial is not None or image_atlas_settings is not None else None
    if trial is not None:
        trial = replace(trial, workspace=settings.workspace, camera=settings.camera)
        records = run_trial(subject.features, body, trial, executor, progress)
        trial_seconds = time.perf_counter() - t0
    img_atlas = None
    if image_atlas_settings is not None:
        image_atlas_settings = replace(
            image_atlas_settings, depth_mm=settings.workspace.depth_mm, camera=settings.camera
        )
        img_atlas = image_atlas(subject.features, body, image_atlas_settings, executor, progress)
    score = score_design(subject.features, settings, thresholds, progress=progress)
    atlas = blind_spot_atlas(subject.features, settings, step_deg=atlas_step_deg, progress=progress)
    seg_atlas = segmentability_atlas(
        subject.features,
        settings.camera,
        settings.workspace.depth_mm,
        settings.workspace.cone_deg,
        max(atlas_step_deg, SEGMENTABILITY_ATLAS_STEP_DEG),
        settings.clearance,
    )
    ia = None
    if imaging is not None:
        ia = imaging(progress)
    seconds = time.perf_counter() - t0
    with atomic_directory(out_dir) as tmp:
        files = []
        if plots:
            from ..analysis.plots import plot_atlas_cone, plot_atlas_sphere, plot_score, plot_segmentability

            plot_score(score, tmp / PLOTS["score"])
            plot_atlas_sphere(atlas, tmp / PLOTS["sphere"])
            plot_atlas_cone(atlas, tmp / PLOTS["cone"])
            plot_segmentability(score.segmentability, seg_atlas, tmp / PLOTS["segmentability"], thresholds)
            files = list(PLOTS.values())
            if ia is not None:
                ia.plot(tmp / "imaging.png")
                files.append("imaging.png")
            if records is not None:
                from ..imagescore.plots import plot_image_score

                plot_image_score(records, tmp / IMAGE_SCORE_PLOT, f"{subject.features.name}: image-true score")
                files.append(IMAGE_SCORE_PLOT)
            if img_atlas is not None:
                plot_image_atlas(img_atlas, tmp / IMAGE_ATLAS_PLOT, f"{subject.features.name}: image-true atlas")
                files.append(IMAGE_ATLAS_PLOT)
        doc = analysis_document(subject, score, atlas, seconds, files, seg_atlas)
        doc["paper_model"] = PAPER_MODEL
        doc["image_score"] = image_score_block(trial, records, trial_seconds) if records is not None else None
        doc["image_atlas"] = img_atlas
        if ia is not None:
            doc["imaging"] = ia.to_dict()
        write_json_atomic(tmp / "analysis.json", doc)
    return doc, out_dir


def atlas_directions(step_deg: float, cone_deg: float) -> int:
    """How many poses :func:`blind_spot_atlas` analyses (for progress bars)."""
    from ..analysis.sampling import cone_grid, sphere_grid

    return sphere_grid(step_deg)[0].size + cone_grid([0.0, 0.0, 1.0], cone_deg)[0].size


def _fmt(v) -> str:
    return "inf" if v is None else f"{v:.3g}"


def format_summary(doc: dict, imaging: Callable[[dict], str] | None = None) -> str:
    """The score, groups, features and worst directions of an analysis.json object as a few
    readable lines; ``imaging`` formats its ``imaging`` block where there is one (e.g.
    :func:`ftrac_design.intensity.workspace.format_imaging`)."""
    lines: list[str] = []
    echo = lines.append
    f = doc["figures"]
    s = doc["settings"]
    if doc.get("image_score"):
        echo(format_image_score(doc["design"]["name"], doc["image_score"]))
    if doc.get("image_atlas"):
        echo(format_image_atlas(doc["image_atlas"]))
    if doc.get("image_score") or doc.get("image_atlas"):
        echo(f"{PAPER_MODEL}:")
    echo(
        f"{doc['design']['name']}: {s['poses']} poses within {s['cone_deg']:g}° of the nominal beam, "
        f"segmentation error {s['segmentation_error_mm']:g} mm"
        + "".join(f", {k} ×{s[k + '_error_factor']:.3g}" for k in ("bead", "wire") if k + "_error_factor" in s)
        + " (predicted 1σ, 3-D RMS)"
    )
    tz = f["translation_p95_per_axis_mm"][2]
    echo(
        f"  translation  p95 {_fmt(f['translation_mm']['p95'])} mm  worst {_fmt(f['translation_mm']['worst'])} mm"
        f"  (depth p95 {_fmt(tz)} mm)"
    )
    echo(f"  rotation     p95 {_fmt(f['rotation_deg']['p95'])}°  worst {_fmt(f['rotation_deg']['worst'])}°")
    echo(f"  condition    median {_fmt(f['condition']['median'])}  worst {_fmt(f['condition']['worst'])}")
    for c in doc["checks"]:
        echo(
            f"  {'ok  ' if c['passed'] else 'FAIL'} {c['figure']:<18} {_fmt(c['value']):>8} {c['unit']:<3} "
            f"limit {c['limit']:g}"
        )
    for g, v in doc["groups"].items():
        echo(
            f"  {g:<9} alone: translation p95 {_fmt(v['translation_mm']['p95'])} mm, condition median "
            f"{_fmt(v['condition']['median'])}"
            + (f", singular at {v['singular_fraction']:.0%} of poses" if v["singular_fraction"] else "")
        )
    worst = max(doc["features"], key=lambda x: x["without"]["translation_loss"] or float("inf"))
    echo(
        f"  most needed feature: {worst['id']} (without it p95 translation x"
        f"{_fmt(worst['without']['translation_loss'])})"
    )
    sg = doc.get("segmentability")
    if sg:
        echo(format_segmentability(sg))
    if doc.get("imaging") and imaging is not None:
        echo(imaging(doc["imaging"]))
    at = doc.get("atlas")
    if at:
        echo(f"  atlas: {at['directions']} directions; worst view directions:")
        for i, w in enumerate(at["worst_directions"][:3]):
            who = (
                ", ".join(f"{r['id']} {r['reason']} ({_fmt(r['view_angle_deg'])}°)" for r in w["responsible"])
                or "no single feature blind"
            )
            echo(
                f"    {i + 1}. lon {w['lon_deg']:.0f}°, lat {w['lat_deg']:.0f}° "
                f"({w['angle_from_nominal_deg']:.0f}° from nominal{', in workspace' if w['in_workspace'] else ''}):"
                f" {_fmt(w['translation_error_mm'])} mm, condition {_fmt(w['condition'])} — {who}"
            )
    return "\n".join(lines)


def _interval(ci) -> str:
    return f" [{ci[0]:.3g}, {ci[1]:.3g}]" if ci else ""


def format_image_score(name: str, block: dict) -> str:
    """A few lines on an analysis.json ``image_score`` block: per condition, the p95 errors of the
    right poses with their 95 % intervals and the shares refused and wrong."""
    m = block["model"]
    out = [
        f"{name}: image-true score — {m['images_per_condition']} rendered images per condition, seed {m['seed']}, "
        f"tracked with the defaults (wrong: beyond {m['wrong_if_beyond']['rotation_deg']:g}° or "
        f"{m['wrong_if_beyond']['translation_mm']:g} mm and {m['wrong_if_beyond'].get('sigma', 0):g}σ "
        "by its own covariance)"
    ]
    for cond, f in block["figures"].items():
        out.append(
            f"  {cond:<8} translation p95 {_fmt(f['translation_p95_mm'])} mm"
            f"{_interval(f['translation_p95_95ci_mm'])}, rotation p95 {_fmt(f['rotation_p95_deg'])}°"
            f"{_interval(f['rotation_p95_95ci_deg'])}; refused {f['refused_pct']:.1f} %, "
            f"wrong {f['wrong_pct']:.1f} %"
        )
    out.append(
        f"  (clean: {m['clean']['photons_per_px']:g} quanta/px, {m['clean']['energy_kev']:g} keV, "
        f"focal spot {m['clean']['focal_spot_mm']:g} mm, blur {m['clean']['detector_blur_px']:g} px; "
        f"anatomy: {m['anatomy']['patient']}, {m['anatomy']['quanta_behind_patient'][0]}–"
        f"{m['anatomy']['quanta_behind_patient'][1]} quanta behind the patient, raw counts)"
    )
    return "\n".join(out)


def format_image_atlas(atlas: dict) -> str:
    """Two lines on an analysis.json ``image_atlas`` block: the shares tracked right and the worst
    directions."""
    s = atlas["settings"]
    cone = atlas["right_share_cone"]
    out = [
        f"  image-true atlas ({s['step_deg']:g}° grid, {s['rolls']} rolls, clean): tracked right from "
        f"{100 * atlas['right_share_sphere']:.0f} % of the sphere of view directions"
        + (f", {100 * cone:.0f} % of the workspace cone" if cone is not None else "")
    ]
    worst = "; ".join(
        f"lon {w['lon_deg']:.0f}°, lat {w['lat_deg']:.0f}° ({w['angle_from_nominal_deg']:.0f}° from "
        f"nominal) {100 * w['right_share']:.0f} % right"
        for w in atlas["worst"][:3]
    )
    out.append(f"    worst: {worst}")
    return "\n".join(out)


def _pct(v) -> str:
    return "n/a" if v is None else f"{100 * v:.1f} %"


def format_segmentability(sg: dict) -> str:
    """Two or three lines on image clearances from an analysis.json ``segmentability`` block."""
    c = {k: ("n/a" if v is None else f"{v:.3g}") for k, v in sg["clearance_px"].items()}
    kinds = (
        ", ".join(
            f"{k} {_pct(v['overlap_share'])}" for k, v in sg["kinds"].items() if v["counted"] and v["overlap_share"] > 0
        )
        or "none"
    )
    out = [
        f"  segmentability ({sg['settings']['poses']} poses): features overlap at {_pct(sg['overlap_share'])} "
        f"of poses ({kinds}); smallest clearance p5 {c['p5']} px, min {c['min']} px"
    ]
    if sg["worst_poses"]:
        w = sg["worst_poses"][0]
        out.append(
            f"    worst: {w['pair']} ({w['kind']}) {w['clearance_px']:.2g} px at "
            f"{w['angle_from_nominal_deg']:.0f}° from nominal"
        )
    at = sg.get("atlas")
    if at:
        out.append(
            f"    overlap over {_pct(at['overlap_share_of_sphere'])} of the sphere of view directions, "
            f"{_pct(at['overlap_share_of_cone'])} of the workspace cone (fiducial at the isocentre)"
        )
    return "\n".join(out)
