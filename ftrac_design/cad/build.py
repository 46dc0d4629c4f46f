"""``ftrac-design build``: design → body, parts, exports, features, manifest and render.

Everything is written into a temporary sibling of the output directory that replaces it
only when the whole build succeeded (:func:`ftrac_design.fileio.atomic_directory`).
"""

from __future__ import annotations

import platform
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .. import __version__
from ..design.schema import Design
from ..features import Features, compute_features, write_features
from ..fileio import atomic_directory, check_output_dir, json_format_is, sha256_file, write_json_atomic
from ..manufacture.drawings import DRAWING_FILES
from ..manufacture.fdm import FDM_FILES
from ..manufacture.plan import STL_VOLUME_TOLERANCE, BodyPlan, plan_body, stl_tolerances
from ..manufacture.profiles import CutSizes, Profile, cut_sizes
from .occ import occ_errors, require_cad_packages

MANIFEST_FORMAT = "ftrac-build-manifest"
MANIFEST_VERSION = 1

#: files every build writes (manifest.json last, it lists the others' hashes)
#: (body.ngc: the 4-axis program, cnc profile only; the fanuc post names it body.nc)
OUTPUT_FILES = (
    "features.json",
    "fiducial.step",
    "fiducial.stl",
    "mount.step",
    "mount.stl",
    "connector.step",
    "connector.stl",
    "grooves.csv",
    "grooves.dxf",
    "body.ngc",
    "assembly.step",
    "render.png",
    *DRAWING_FILES,
    "manifest.json",
)
#: what an fdm build writes besides (the 3MF of the printed parts, the slicer settings)
FDM_OUTPUT_FILES = FDM_FILES


def output_files(profile: Profile) -> tuple[str, ...]:
    """Every file a build under ``profile`` may write (manifest.json last; the program only under
    cnc, as body.ngc or, with the fanuc post, body.nc)."""
    extra = FDM_OUTPUT_FILES if profile == "fdm" else ("body.nc",)
    return (*OUTPUT_FILES[:-1], *extra, OUTPUT_FILES[-1])


@dataclass
class BuildResult:
    """What a build wrote and how long each stage took."""

    out_dir: Path
    manifest: dict[str, Any]
    timings: dict[str, float] = field(default_factory=dict)


def default_output_dir(design: Design) -> Path:
    """``outputs/<design name>/`` under the current directory."""
    return Path("outputs") / design.name


def _check_output_dir(out_dir: Path) -> None:
    """Refuse to replace anything but an empty directory or an earlier build's output."""
    check_output_dir(
        out_dir, "an earlier build's output", lambda d: json_format_is(d / "manifest.json", MANIFEST_FORMAT)
    )


class _Clock:
    def __init__(self) -> None:
        self.t0 = time.perf_counter()
        self.last = self.t0
        self.laps: dict[str, float] = {}

    def lap(self, name: str) -> None:
        now = time.perf_counter()
        self.laps[name] = round(now - self.last, 3)
        self.last = now

    @property
    def total(self) -> float:
        return time.perf_counter() - self.t0


def build_fiducial(
    design: Design,
    out_dir: str | Path | None = None,
    profile: Profile = "cnc",
    force: bool = False,
    render: bool = True,
    post: str = "linuxcnc",
) -> BuildResult:
    """Build ``design`` into ``out_dir`` (default :func:`default_output_dir`).

    ``render=False`` skips ``render.png`` (benchmarks only; the command always renders).
    Under the cnc profile the body's 4-axis program is written too, for ``post`` (a key of
    :data:`ftrac_design.machining.post.POSTS`); ``ftrac-design gcode`` verifies it.
    The design rules of ``profile`` are checked first: a violation raises
    :class:`~ftrac_design.errors.GoalError` (exit 1) before anything is written, unless
    ``force``. Raises :class:`~ftrac_design.errors.InputError` for a bad output directory and
    :class:`~ftrac_design.cad.body.CadError` (exit 1) when OCC cannot build a part.
    """
    require_cad_packages(render)
    from ..manufacture.fdm import write_fdm_files
    from ..manufacture.manifest import enforce_rules, manufacturing_manifest
    from .drawings import write_drawings
    from .export import BODY_COLOR, build_assembly, export_assembly, write_manufacturing_files
    from .fixture import CONNECTOR_COLOR, MOUNT_COLOR, add_to_assembly, fixture_parts
    from .parts import bead_parts, wire_parts

    out_dir = Path(out_dir) if out_dir is not None else default_output_dir(design)
    _check_output_dir(out_dir)
    clock = _Clock()
    features = compute_features(design)
    cuts = cut_sizes(design, profile)
    plan = plan_body(design, features, cuts)
    report = enforce_rules(design, features, profile, force)
    clock.lap("features")
    with atomic_directory(out_dir) as tmp, occ_errors(design.name):
        write_features(tmp / "features.json", features)
        body = _body_solid(design, plan, profile)
        clock.lap("body")
        parts = wire_parts(features, design.half_length + design.outer_radius) + bead_parts(features)
        clock.lap("parts")
        stl = _export_body(body, design, cuts, tmp)
        clock.lap("export_body")
        fixture = fixture_parts(design, features, profile)
        made = write_manufacturing_files(design, features, profile, tmp, parts=fixture)
        gcode = _write_program(design, profile, post, tmp)
        clock.lap("mount_connector")
        export_assembly(add_to_assembly(build_assembly(design.name, body, parts), fixture), tmp / "assembly.step")
        clock.lap("export_assembly")
        write_drawings(design, features, plan, body, fixture, profile, tmp)
        clock.lap("drawings")
        if profile == "fdm":
            write_fdm_files(design, tmp, {"body": BODY_COLOR, "mount": MOUNT_COLOR, "connector": CONNECTOR_COLOR})
            clock.lap("fdm_files")
        if render:
            _render(body, parts, design, profile, tmp)
        clock.lap("render")
        manifest = _manifest(design, features, cuts, plan, parts, stl, tmp, force, profile)
        manifest["manufacturing"] = manufacturing_manifest(design, features, profile, report, made)
        if gcode is not None:
            manifest["manufacturing"]["gcode"] = gcode
        manifest["bom"] = manifest["manufacturing"].pop("bom")
        manifest["build_time_s"] = round(clock.total, 3)
        manifest["timings_s"] = dict(clock.laps)
        write_json_atomic(tmp / "manifest.json", manifest)
    clock.lap("finish")
    return BuildResult(out_dir, manifest, dict(clock.laps))


def _body_solid(design: Design, plan: BodyPlan, profile: Profile):
    """The body cut to its plan, with the slot across the z = -L/2 end face that the mount's key engages."""
    from .body import build_body, single_solid
    from .mount import key_slot_tool

    body = build_body(plan)
    slot = key_slot_tool(design, profile)
    if slot is not None:
        body = single_solid(body.cut(slot), f"{design.name} key slot")
    return body


@dataclass(frozen=True)
class _BodyStl:
    """The body's STL as written and checked: its report, tolerances and the B-rep's volume."""

    report: Any
    tolerances: tuple[float, float]
    body_volume: float
    volume_vs_brep: float


def _export_body(body, design: Design, cuts: CutSizes, tmp: Path) -> _BodyStl:
    """fiducial.step and fiducial.stl; the STL must be closed and hold the B-rep's volume."""
    from .body import CadError, volume
    from .export import export_step, export_stl

    export_step(body, tmp / "fiducial.step")
    stl_tol, stl_ang = stl_tolerances(cuts, design)
    stl = export_stl(body, tmp / "fiducial.stl", stl_tol, stl_ang)
    body_volume = volume(body)
    stl_rel = stl.volume / body_volume - 1.0
    if not stl.watertight or abs(stl_rel) > STL_VOLUME_TOLERANCE:
        raise CadError(f"fiducial.stl: watertight={stl.watertight}, volume off by {stl_rel:+.3%} from the B-rep")
    return _BodyStl(stl, (stl_tol, stl_ang), body_volume, stl_rel)


def _render(body, parts: list, design: Design, profile: Profile, tmp: Path) -> None:
    """render.png: the body with its wires and beads."""
    from .render import render_png

    sizes = [x.diameter for x in (design.wire, design.bead) if x is not None]
    render_png(
        body,
        parts,
        tmp / "render.png",
        title=f"{design.name}  ({profile})",
        part_size=min(sizes) if sizes else None,
    )


def _write_program(design: Design, profile: Profile, post: str, out_dir: Path) -> dict[str, Any] | None:
    """Write the body's program (cnc only); its manifest entry, or why there is none."""
    from ..fileio import write_text_atomic
    from ..manufacture.gcode import body_program

    if profile != "cnc":
        return None
    try:
        bp = body_program(design, profile, post, check=False)
    except ValueError as exc:  # a forced build whose grooves are narrower than the end mill
        return {"skipped": str(exc)}
    write_text_atomic(out_dir / bp.filename, bp.text)
    return bp.summary()


def _ocp_version() -> str:
    try:
        from OCP import __version__ as v
    except ImportError:  # pragma: no cover
        return "unknown"
    return str(v)


def _manifest(
    design: Design,
    features: Features,
    cuts: CutSizes,
    plan: BodyPlan,
    parts: list,
    stl: _BodyStl,
    tmp: Path,
    force: bool,
    profile: Profile,
) -> dict[str, Any]:
    """manifest.json's object, but for the manufacturing entry and the timings the build adds."""
    import cadquery as cq

    return {
        "format": MANIFEST_FORMAT,
        "version": MANIFEST_VERSION,
        "design": {
            "name": design.name,
            "source": design.source,
            "sha256": design.sha256,
            "parameters": design.model_dump(mode="json"),
        },
        "profile": profile,
        "cut_sizes": cuts.as_dict(),
        "force": force,
        "files": _file_hashes(tmp, profile),
        "features": {"points": len(features.points), "lines": len(features.lines), "ellipses": len(features.ellipses)},
        "wires": _wires_entry(design, features),
        "beads": {
            "count": len(features.points),
            "diameter_mm": design.bead.diameter if design.bead else None,
            "material": design.bead.material if design.bead else None,
        },
        "volumes_mm3": _volumes_entry(plan, parts, stl.body_volume),
        "stl": {
            "chord_tolerance_mm": stl.tolerances[0],
            "angular_tolerance_rad": stl.tolerances[1],
            "triangles": stl.report.triangles,
            "watertight": stl.report.watertight,
            "repaired": stl.report.repaired,
            "volume_mm3": round(stl.report.volume, 4),
            "volume_vs_brep": stl.volume_vs_brep,
        },
        "versions": {
            "ftrac_design": __version__,
            "cadquery": cq.__version__,
            "ocp": _ocp_version(),
            "python": platform.python_version(),
        },
    }


def _file_hashes(tmp: Path, profile: Profile) -> dict[str, dict[str, Any]]:
    """sha256 and size of every file the build wrote (the manifest itself excepted)."""
    files = {}
    for name in output_files(profile):
        p = tmp / name
        if p.exists() and name != "manifest.json":
            files[name] = {"sha256": sha256_file(p), "bytes": p.stat().st_size}
    return files


def _wires_entry(design: Design, features: Features) -> dict[str, Any]:
    """The wires' diameter, material, each feature's length and each straight piece to cut."""
    lengths = {f.id: round(features.wire_length(f.id), 4) for f in (*features.ellipses, *features.lines)}
    pieces = []
    for ln in features.lines:
        for k, (a, b) in enumerate(features.wire_segments(ln.id), start=1):
            pieces.append(
                {
                    "name": f"wire_{ln.id}_{k}",
                    "feature": ln.id,
                    "length_mm": round(float(((b - a) ** 2).sum() ** 0.5), 4),
                }
            )
    return {
        "diameter_mm": design.wire.diameter if design.wire else None,
        "material": design.wire.material if design.wire else None,
        "length_mm": lengths,
        "total_length_mm": round(sum(lengths.values()), 4),
        "line_pieces": pieces,
    }


def _volumes_entry(plan: BodyPlan, parts: list, body_volume: float) -> dict[str, float]:
    """The body's, the blank's and the removed volume, and the wires' and beads' (mm³)."""
    import math

    blank = math.pi * (plan.outer_radius**2 - plan.bore_radius**2) * 2 * plan.half_length
    return {
        "body": round(body_volume, 4),
        "blank": round(blank, 4),
        "removed": round(blank - body_volume, 4),
        "wires": round(sum(p.volume for p in parts if p.kind == "wire"), 4),
        "beads": round(sum(p.volume for p in parts if p.kind == "bead"), 4),
    }
