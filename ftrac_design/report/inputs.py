"""What one design report shows, gathered from a build directory, a design and an analysis.

A :class:`ReportInputs` holds everything the page needs; :func:`collect` fills it from what
exists — a build directory (``manifest.json``, ``features.json``, ``render.png`` and the
output files, whose sha256 are re-computed and compared with the manifest), the design (from
the manifest's parameters or a design file), the design rules of *both* profiles (computed
here, numpy only) and an analysis directory (``analysis.json`` and its PNGs). Missing parts
are ``None`` and the page says what would produce them. No CadQuery here: building is the
caller's business (``ftrac-design report DESIGN.toml`` builds in a temporary directory).
"""

from __future__ import annotations

import json
import platform
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..errors import InputError
from ..fileio import sha256_file

#: pictures of an analysis directory, in page order (file names as ``ftrac-design analyze`` writes them)
ANALYSIS_PICTURES = ("image_score.png", "score.png", "image_atlas.png", "atlas_sphere.png", "atlas_cone.png")


@dataclass(frozen=True)
class OutputFile:
    """One file of a build: its size and sha256 from the manifest, and whether the file on
    disk still has that hash (``"ok"``, ``"changed"``, ``"missing"``, or ``"not kept"`` for a
    build made in a temporary directory)."""

    name: str
    bytes: int
    sha256: str
    status: str


@dataclass(frozen=True)
class ReportInputs:
    """Everything the page shows; ``None`` where that part is not available."""

    name: str
    design: Any | None  # ftrac_design.design.Design
    design_source: str | None
    design_sha256: str | None
    features: Any  # ftrac_design.features.Features
    manifest: dict | None = None
    build_dir: Path | None = None
    build_kept: bool = True
    render_png: bytes | None = None
    rules: dict[str, Any] = field(default_factory=dict)  # profile → CheckReport
    analysis: dict | None = None
    analysis_dir: Path | None = None
    analysis_pictures: dict[str, bytes] = field(default_factory=dict)
    files: tuple[OutputFile, ...] = ()
    versions: dict[str, str] = field(default_factory=dict)


def _read_json(path: Path, what: str) -> dict:
    try:
        d = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError(path, None, f"{what} (file not found)") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(path, None, f"{what} as readable JSON ({exc})") from None
    if not isinstance(d, dict):
        raise InputError(path, None, f"{what}: a JSON object")
    return d


def read_manifest(build_dir: Path) -> dict:
    """``manifest.json`` of a build directory, checked for the keys the page uses."""
    path = build_dir / "manifest.json"
    m = _read_json(path, "the manifest of an `ftrac-design build` directory")
    if m.get("format") != "ftrac-build-manifest":
        raise InputError(path, "format", '"ftrac-build-manifest"')
    for key, kind in (("design", dict), ("files", dict), ("bom", dict), ("versions", dict)):
        if not isinstance(m.get(key), kind):
            raise InputError(path, key, f"a JSON {'object' if kind is dict else 'value'} (written by build)")
    return m


def read_analysis(analysis_dir: Path) -> tuple[dict, dict[str, bytes]]:
    """``analysis.json`` and the PNGs beside it."""
    path = analysis_dir / "analysis.json"
    doc = _read_json(path, "an `ftrac-design analyze` result")
    if doc.get("format") != "ftrac-analysis":
        raise InputError(path, "format", '"ftrac-analysis"')
    pics = {n: (analysis_dir / n).read_bytes() for n in ANALYSIS_PICTURES if (analysis_dir / n).is_file()}
    return doc, pics


def output_files(build_dir: Path, manifest: dict, kept: bool = True) -> tuple[OutputFile, ...]:
    """The manifest's files with their hashes, each re-hashed on disk."""
    out = []
    for name, info in sorted(manifest["files"].items()):
        if not isinstance(info, dict):
            continue
        sha, size = str(info.get("sha256", "")), int(info.get("bytes", 0) or 0)
        p = build_dir / name
        if not kept:
            status = "not kept"
        elif not p.is_file():
            status = "missing"
        else:
            status = "ok" if sha256_file(p) == sha else "changed"
        out.append(OutputFile(name, size, sha, status))
    return tuple(out)


def _versions(manifest: dict | None, analysis: dict | None) -> dict[str, str]:
    import numpy
    import scipy

    from .. import __version__

    v: dict[str, str] = {}
    if manifest:
        v.update({f"build: {k}": str(x) for k, x in manifest.get("versions", {}).items()})
    if analysis and analysis.get("package_version"):
        v["analysis: ftrac_design"] = str(analysis["package_version"])
    v.update(
        {
            "report: ftrac_design": __version__,
            "report: python": platform.python_version(),
            "report: numpy": numpy.__version__,
            "report: scipy": scipy.__version__,
        }
    )
    try:
        import matplotlib

        v["report: matplotlib"] = matplotlib.__version__
    except ImportError:  # pragma: no cover - a dependency
        pass
    return v


def collect(
    build_dir: str | Path | None = None,
    design: Any | None = None,
    analysis_dir: str | Path | None = None,
    build_kept: bool = True,
    features: Any | None = None,
) -> ReportInputs:
    """Gather a report's inputs from a build directory, a design or bare features, and an
    analysis directory (``build_dir/analysis`` if it holds one and ``analysis_dir`` is not given).

    With a build directory the design comes from its manifest (the parameters it was built
    from) unless ``design`` is given; without one, only the design's own parts are shown.
    Raises :class:`InputError` for an unreadable build or analysis.
    """
    from ..design.loader import parse_design
    from ..features import compute_features, load_features
    from ..manufacture.rules import check_design

    manifest = render = None
    files: tuple[OutputFile, ...] = ()
    source = sha = None
    if build_dir is not None:
        build_dir = Path(build_dir)
        if not build_dir.is_dir():
            raise InputError(build_dir, None, "a build directory (written by `ftrac-design build`)")
        manifest = read_manifest(build_dir)
        mdesign = manifest["design"]
        source, sha = mdesign.get("source"), mdesign.get("sha256")
        if design is None:
            design = parse_design(mdesign.get("parameters"), build_dir / "manifest.json")
        features = load_features(build_dir / "features.json")
        rp = build_dir / "render.png"
        render = rp.read_bytes() if rp.is_file() else None
        try:
            files = output_files(build_dir, manifest, build_kept)
        except (TypeError, ValueError, OverflowError) as exc:
            raise InputError(
                build_dir / "manifest.json", "files", f"name → {{sha256, bytes}} as `build` writes ({exc})"
            ) from None
        if analysis_dir is None and (build_dir / "analysis" / "analysis.json").is_file():
            analysis_dir = build_dir / "analysis"
    elif design is not None:
        features = compute_features(design)
    elif features is None:
        raise ValueError("collect() needs a build directory, a design or features")
    if design is not None and source is None:
        source, sha = design.source, design.sha256
    analysis, pics = (None, {})
    if analysis_dir is not None:
        analysis_dir = Path(analysis_dir)
        analysis, pics = read_analysis(analysis_dir)
    rules = {p: check_design(design, p, features) for p in ("cnc", "fdm")} if design is not None else {}
    return ReportInputs(
        name=features.name,
        design=design,
        design_source=source,
        design_sha256=sha,
        features=features,
        manifest=manifest,
        build_dir=build_dir,
        build_kept=build_kept,
        render_png=render,
        rules=rules,
        analysis=analysis,
        analysis_dir=analysis_dir,
        analysis_pictures=pics,
        files=files,
        versions=_versions(manifest, analysis),
    )
