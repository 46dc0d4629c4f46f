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
:mod:`ftrac_design.intensity.workspace`), and the PNG files
written beside it. Lengths mm, angles degrees (keys say ``_deg``), errors are predicted 1σ.

Two scores, clearly apart: ``image_score`` — the image-true score (:mod:`ftrac_design.imagescore`:
a seeded sample of workspace poses rendered clean and over a patient and tracked; the share
refused and wrong, the p95 of the right poses' errors with intervals, its imaging model and every
image's record), the default and the one to rank designs by; and ``figures``/``checks``/``groups``/
``features`` — the paper's model (the feature-level Cramér–Rao bound with the paper's uniform
segmentation error), kept for its per-feature and per-direction insight and its thresholds.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable
from concurrent.futures import Executor
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from ..analysis.atlas import Atlas, blind_spot_atlas
from ..analysis.score import AnalysisSettings, DesignScore, Thresholds, score_design
from ..analysis.segmentability import SegmentabilityAtlas, segmentability_atlas
from ..analysis.subject import Subject
from ..features.model import Features
from ..fileio import atomic_directory, check_output_dir, json_format_is, write_json_atomic
from ..imagescore import TrialSettings, run_trial, trial_figures
from ..imagescore.atlas import AtlasSettings, image_atlas, plot_image_atlas
from ..xray.model import ImagingModel

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


@dataclass(frozen=True)
class PixelBound:
    """``analyze --imaging``: the pixel-level Cramér–Rao bound of the pose from rendered
    radiographs beside the feature-level one, at its own sample of workspace poses."""

    model: ImagingModel
    poses: int = 60

    @classmethod
    def from_options(
        cls,
        settings: AnalysisSettings,
        poses: int = 60,
        dose: float = 1.0e4,
        energy_kev: float = 60.0,
        detector_blur_px: float = 0.7,
        focal_spot_mm: float = 0.6,
    ) -> "PixelBound":
        """From the command's ``--imaging-poses``, ``--dose``, ``--energy-kev``,
        ``--detector-blur-px`` and ``--focal-spot-mm``; the image as large as the camera's
        (twice its principal point).

        Parameters
        ----------
        settings : AnalysisSettings
            The analysis' settings (its camera).
        poses, dose, energy_kev, detector_blur_px, focal_spot_mm
            The options' values (dose: unattenuated quanta per pixel; keV; px; mm).

        Returns
        -------
        PixelBound
            The imaging model and the poses.
        """
        pp = settings.camera.principal_point_px
        model = ImagingModel(
            energy_kev=energy_kev,
            image_shape=(round(2 * pp[1]), round(2 * pp[0])),
            focal_spot_mm=focal_spot_mm,
            detector_blur_px=detector_blur_px,
            photons_per_px=dose,
        )
        return cls(model, poses)


@dataclass(frozen=True)
class AnalysisPlan:
    """Everything an analysis does, resolved once (from the command line, the report, the demo):
    the paper's model's settings and thresholds, where it writes, the atlas' grid, the image-true
    score and atlas, and the pixel-level bound.

    Attributes
    ----------
    settings, thresholds : AnalysisSettings, Thresholds
        The workspace, noise, camera and sampling, and the pass/fail limits.
    out_dir : pathlib.Path or None
        Output directory (default :func:`default_output_dir`); replaced only if it holds an
        earlier analysis.
    atlas_step_deg : float
        Grid step of the whole-sphere atlas, degrees.
    plots : bool
        Write the PNGs.
    scoring : ImageScoring
        The image-true score's sample and atlas (each None: not computed) and its processes.
    pixel_bound : PixelBound or None
        The pixel-level bound (None: not computed).
    """

    settings: AnalysisSettings
    thresholds: Thresholds
    out_dir: Path | None = None
    atlas_step_deg: float = 2.0
    plots: bool = True
    scoring: ImageScoring = field(default_factory=lambda: ImageScoring(None, None))
    pixel_bound: PixelBound | None = None

    def steps(self) -> int:
        """How many poses, directions and images the analysis works through (for a progress bar)."""
        n = self.settings.poses + atlas_directions(self.atlas_step_deg, self.settings.workspace.cone_deg)
        if self.pixel_bound is not None:
            n += self.pixel_bound.poses
        return n + self.scoring.images()

    def trial(self) -> TrialSettings | None:
        """The image-true score's sample in this analysis' workspace and camera (None: none)."""
        if self.scoring.trial is None:
            return None
        return replace(self.scoring.trial, workspace=self.settings.workspace, camera=self.settings.camera)

    def image_atlas(self) -> AtlasSettings | None:
        """The image-true atlas' grid at this analysis' depth and camera (None: none)."""
        if self.scoring.atlas is None:
            return None
        return replace(self.scoring.atlas, depth_mm=self.settings.workspace.depth_mm, camera=self.settings.camera)


def run_analysis(
    subject: Subject,
    plan: AnalysisPlan,
    progress: Callable[[int], None] | None = None,
    executor: Executor | None = None,
) -> tuple[dict, Path]:
    """Score and map ``subject`` as ``plan`` says, write analysis.json (+ PNGs) atomically.

    Parameters
    ----------
    subject : Subject
        What is analysed.
    plan : AnalysisPlan
        What the analysis does.
    progress : callable or None
        Called with the number of poses, directions or images done (:meth:`AnalysisPlan.steps`
        in all).
    executor : concurrent.futures.Executor or None
        Where the image-true score's and atlas' images are rendered and tracked; None: the
        plan's workers (:func:`ftrac_design.optimize.execution.open_executor`; none with 0
        workers, the images then rendered here).

    Returns
    -------
    (dict, pathlib.Path)
        The analysis.json object and the directory written.
    """
    out_dir = Path(plan.out_dir) if plan.out_dir is not None else default_output_dir(subject.features)
    _check_output_dir(out_dir)
    with contextlib.ExitStack() as stack:
        if executor is None and plan.scoring.any and plan.scoring.workers != 0:
            from ..optimize.execution import open_executor

            executor, _ = stack.enter_context(open_executor(None, plan.scoring.workers))
        results = _analyse(subject, plan, progress, executor)
    with atomic_directory(out_dir) as tmp:
        files = _plot(subject, plan, results, tmp) if plan.plots else []
        doc = analysis_document(subject, results.score, results.atlas, results.seconds, files, results.seg_atlas)
        doc["paper_model"] = PAPER_MODEL
        doc["image_score"] = (
            image_score_block(plan.trial(), results.records, results.trial_seconds)
            if results.records is not None
            else None
        )
        doc["image_atlas"] = results.image_atlas
        if results.pixel is not None:
            doc["imaging"] = results.pixel.to_dict()
        write_json_atomic(tmp / "analysis.json", doc)
    return doc, out_dir


@dataclass
class _Results:
    """What an analysis computed, before anything is written."""

    score: DesignScore
    atlas: Atlas
    seg_atlas: SegmentabilityAtlas
    seconds: float
    records: list[dict] | None = None
    trial_seconds: float = 0.0
    image_atlas: dict | None = None
    pixel: Any = None


def _analyse(
    subject: Subject, plan: AnalysisPlan, progress: Callable[[int], None] | None, executor: Executor | None
) -> _Results:
    """Every figure of the analysis, in a fixed order (the image-true score first)."""
    settings, f = plan.settings, subject.features
    t0 = time.perf_counter()
    trial, atlas_settings = plan.trial(), plan.image_atlas()
    records, trial_seconds = None, 0.0
    if trial is not None:
        records = run_trial(f, trial, executor, progress)
        trial_seconds = time.perf_counter() - t0
    img_atlas = image_atlas(f, atlas_settings, executor, progress) if atlas_settings is not None else None
    score = score_design(f, settings, plan.thresholds, progress=progress)
    atlas = blind_spot_atlas(f, settings, step_deg=plan.atlas_step_deg, progress=progress)
    seg_atlas = segmentability_atlas(
        f,
        settings.camera,
        settings.workspace.depth_mm,
        settings.workspace.cone_deg,
        max(plan.atlas_step_deg, SEGMENTABILITY_ATLAS_STEP_DEG),
        settings.clearance,
    )
    pixel = None
    if plan.pixel_bound is not None:
        from ..intensity.workspace import imaging_analysis

        b = plan.pixel_bound
        pixel = imaging_analysis(
            f,
            settings.workspace,
            b.model,
            b.poses,
            settings.seed,
            settings.camera,
            settings.segmentation_error_mm,
            settings.contour,
            progress=progress,
        )
    seconds = time.perf_counter() - t0
    return _Results(score, atlas, seg_atlas, seconds, records, trial_seconds, img_atlas, pixel)


def _plot(subject: Subject, plan: AnalysisPlan, r: _Results, tmp: Path) -> list[str]:
    """Draw the analysis' pictures into ``tmp``; their file names."""
    from ..analysis.plots import plot_atlas_cone, plot_atlas_sphere, plot_score, plot_segmentability

    name = subject.features.name
    plot_score(r.score, tmp / PLOTS["score"])
    plot_atlas_sphere(r.atlas, tmp / PLOTS["sphere"])
    plot_atlas_cone(r.atlas, tmp / PLOTS["cone"])
    plot_segmentability(r.score.segmentability, r.seg_atlas, tmp / PLOTS["segmentability"], plan.thresholds)
    files = list(PLOTS.values())
    if r.pixel is not None:
        r.pixel.plot(tmp / "imaging.png")
        files.append("imaging.png")
    if r.records is not None:
        from ..imagescore.plots import plot_image_score

        plot_image_score(r.records, tmp / IMAGE_SCORE_PLOT, f"{name}: image-true score")
        files.append(IMAGE_SCORE_PLOT)
    if r.image_atlas is not None:
        plot_image_atlas(r.image_atlas, tmp / IMAGE_ATLAS_PLOT, f"{name}: image-true atlas")
        files.append(IMAGE_ATLAS_PLOT)
    return files


def atlas_directions(step_deg: float, cone_deg: float) -> int:
    """How many poses :func:`blind_spot_atlas` analyses (for progress bars)."""
    from ..analysis.sampling import cone_grid, sphere_grid

    return sphere_grid(step_deg)[0].size + cone_grid([0.0, 0.0, 1.0], cone_deg)[0].size


def _fmt(v) -> str:
    return "inf" if v is None else f"{v:.3g}"


def format_summary(doc: dict) -> str:
    """The score, groups, features and worst directions of an analysis.json object as a few
    readable lines (its ``imaging`` block too, where it has one).

    Parameters
    ----------
    doc : dict
        An analysis.json object.

    Returns
    -------
    str
        The summary.
    """
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
    if doc.get("imaging"):
        from ..intensity.workspace import format_imaging

        echo(format_imaging(doc["imaging"]))
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
