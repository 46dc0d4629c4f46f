"""``ftrac-design report DESIGN.toml|PRESET|BUILD_DIR [-o report.html]`` (SPEC §5): one
self-contained HTML page per design (:mod:`ftrac_design.report`).

A build directory is reported as it is (its files re-hashed against the manifest) with its
``analysis/`` if it has one, else an analysis run at the design's settings and not kept.
A design file (or a preset, by name) is first built, with ``--force`` semantics (a design that breaks a rule is
still reported, its violations in red), into a temporary directory that is not kept — the
page then says so; run ``build`` first to keep the files.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import click

from ..errors import InputError
from .options import OUT_FILE, image_score_options, optional_option, output_option, poses_option, profile_option


@click.command("report")
@click.argument("source", type=click.Path(path_type=Path))
@output_option(
    "HTML file to write [default: BUILD_DIR/report.html; report_<name>.html for a design file]", type=OUT_FILE
)
@optional_option(
    "--analysis",
    "analysis_dir",
    type=click.Path(path_type=Path, file_okay=False),
    help="an `ftrac-design analyze` output directory to show [default: BUILD_DIR/analysis if present, "
    "else the analysis is run]",
)
@poses_option("workspace poses when the analysis is run [default: the design's, else 20000]")
@profile_option("profile of the build made from a design file (the page shows the rules of both)")
@image_score_options(atlas=True)
def command(
    source: Path,
    output: Path | None,
    analysis_dir: Path | None,
    poses: int | None,
    profile: str,
    score_images: int,
    score_seed: int,
    image_atlas_step_deg: float,
    workers: int | None,
) -> int:
    """Write one HTML page for a design: render, parameters, features, design rules (cnc and
    fdm), score and atlas, bill of materials, wire cut list, output files with sha256, versions.

    Images are embedded and the style is inline: the file opens with no network.
    """
    from ..design.presets import known_presets, resolve_design
    from ..workflows.analyze import ImageScoring
    from ..workflows.report import report_for_build

    scoring = ImageScoring.from_options(score_images, score_seed, image_atlas_step_deg, workers)

    if not source.is_dir():  # a build directory is reported as it is; anything else may be a preset
        source = resolve_design(source)
    if analysis_dir is not None and not (analysis_dir / "analysis.json").is_file():
        raise InputError(
            analysis_dir, "--analysis", "a directory written by `ftrac-design analyze` (no analysis.json in it)"
        )
    if source.is_dir():
        if not (source / "manifest.json").is_file():
            raise InputError(
                source,
                None,
                "a build directory with manifest.json (written by `ftrac-design build`) or a design file (.toml)",
            )
        path = report_for_build(
            source,
            output,
            analysis_dir,
            poses=poses,
            scoring=scoring,
        )
    elif source.suffix.lower() == ".toml" or source.is_file():
        path = _report_design(source, output, analysis_dir, poses, profile, scoring)
    else:
        raise InputError(
            source, None, f"a design file (.toml), a build directory or a preset ({known_presets()}) (file not found)"
        )
    click.echo(f"wrote {path} ({path.stat().st_size / 1024:.0f} KB)")
    return 0


def _report_design(
    source: Path,
    output: Path | None,
    analysis_dir: Path | None,
    poses: int | None,
    profile: str,
    scoring,
) -> Path:
    from ..cad.build import build_fiducial
    from ..design import load_design
    from ..workflows.report import report_for_build

    design = load_design(source)  # exit 2 before any CAD
    output = output if output is not None else Path(f"report_{design.name}.html")
    with tempfile.TemporaryDirectory(prefix="ftrac-report-build-") as tmp:
        build = Path(tmp) / design.name
        build_fiducial(design, build, profile=profile, force=True)
        return report_for_build(
            build,
            output,
            analysis_dir,
            poses=poses,
            build_kept=False,
            design=design,
            scoring=scoring,
        )
