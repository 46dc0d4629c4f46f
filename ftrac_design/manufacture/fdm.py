"""What a build under the ``fdm`` profile adds for the printer: ``fiducial.3mf`` and
``print_settings.json``.

``fiducial.3mf`` is a 3MF package (3MF Core Specification 1.3: an OPC zip with
``[Content_Types].xml``, ``_rels/.rels`` and ``3D/3dmodel.model``) in millimetres holding the
three printed parts — ``body``, ``mount``, ``connector`` — each a named mesh object with its
colour as a core ``basematerials`` display colour. The meshes are the build's verified STLs
(``fiducial.stl``, ``mount.stl``, ``connector.stl``), vertices merged, so triangle count and
enclosed volume are the STLs'. Each part sits on the plate (lowest point at z = 0) in its
printing orientation — the body axis vertical, the mount's socket and the connector's
pocket facing up — side by side along x with :data:`PLATE_GAP` between them; the build
items carry only translations.

The package is written with the standard library (deterministic bytes, so the manifest's
hash only changes when the geometry does); the tests read it back with trimesh and with
lib3mf, the 3MF Consortium's reference implementation.

``print_settings.json`` holds the slicer settings the fdm cut sizes assume
(:func:`ftrac_design.manufacture.profiles.print_settings`) with their sources, and the cut sizes
already built into the parts, which the slicer must not compensate a second time.
"""

from __future__ import annotations

import io
import zipfile
from dataclasses import dataclass
from pathlib import Path
from xml.sax.saxutils import escape, quoteattr

import numpy as np

from ..design.schema import Design
from ..fileio import write_json_atomic
from .profiles import cut_sizes, print_settings

PRINT_SETTINGS_FORMAT = "ftrac-print-settings"
PRINT_SETTINGS_VERSION = 1
#: files :func:`write_fdm_files` writes
FDM_FILES = ("fiducial.3mf", "print_settings.json")
#: gap between the parts on the plate, mm
PLATE_GAP = 5.0
#: the printed parts: (3MF object name, the build's STL)
PRINTED_PARTS = (("body", "fiducial.stl"), ("mount", "mount.stl"), ("connector", "connector.stl"))

CORE_NS = "http://schemas.microsoft.com/3dmanufacturing/core/2015/02"
MODEL_REL = "http://schemas.microsoft.com/3dmanufacturing/2013/01/3dmodel"
CONTENT_TYPES = (
    '<?xml version="1.0" encoding="UTF-8"?>\n'
    '<Types xmlns="http://schemas.openxmlformats.org/package/2006/content-types">'
    '<Default Extension="rels" ContentType="application/vnd.openxmlformats-package.relationships+xml"/>'
    '<Default Extension="model" ContentType="application/vnd.ms-package.3dmanufacturing-3dmodel+xml"/>'
    "</Types>\n"
)
RELS = (
    '<?xml version="1.0" encoding="UTF-8"?>\n'
    '<Relationships xmlns="http://schemas.openxmlformats.org/package/2006/relationships">'
    f'<Relationship Target="/3D/3dmodel.model" Id="rel0" Type="{MODEL_REL}"/>'
    "</Relationships>\n"
)
#: a fixed time stamp for the zip entries, so equal content gives equal bytes
ZIP_TIME = (1980, 1, 1, 0, 0, 0)


@dataclass(frozen=True)
class MeshPart:
    """One printed part: an indexed triangle mesh (mm), its name and colour (RGBA 0–1)."""

    name: str
    vertices: np.ndarray
    faces: np.ndarray
    color: tuple[float, float, float, float]


def hex_color(rgba: tuple[float, float, float, float]) -> str:
    """``#RRGGBBAA`` (the 3MF display colour form)."""
    return "#" + "".join(f"{int(round(max(0.0, min(1.0, c)) * 255)):02X}" for c in rgba)


def plate_offsets(parts: list[MeshPart], gap: float = PLATE_GAP) -> list[np.ndarray]:
    """Translations that stand each part on z = 0, side by side along x, centred on y = 0."""
    out, x = [], 0.0
    for p in parts:
        lo, hi = p.vertices.min(axis=0), p.vertices.max(axis=0)
        out.append(np.array([x - lo[0], -(lo[1] + hi[1]) / 2, -lo[2]]))
        x += float(hi[0] - lo[0]) + gap
    return out


def model_xml(parts: list[MeshPart], title: str, description: str) -> str:
    """The ``3D/3dmodel.model`` document (unit millimetre)."""
    buf = io.StringIO()
    buf.write('<?xml version="1.0" encoding="UTF-8"?>\n')
    buf.write(f'<model unit="millimeter" xml:lang="en-US" xmlns="{CORE_NS}">\n')
    buf.write(f'<metadata name="Title">{escape(title)}</metadata>\n')
    buf.write(f'<metadata name="Description">{escape(description)}</metadata>\n')
    buf.write('<metadata name="Application">ftrac_design</metadata>\n<resources>\n<basematerials id="1">\n')
    for p in parts:
        buf.write(f'<base name={quoteattr(p.name)} displaycolor="{hex_color(p.color)}"/>\n')
    buf.write("</basematerials>\n")
    for k, p in enumerate(parts):
        buf.write(
            f'<object id="{k + 2}" type="model" name={quoteattr(p.name)} pid="1" pindex="{k}">\n<mesh>\n<vertices>\n'
        )
        buf.writelines(f'<vertex x="{x:.9g}" y="{y:.9g}" z="{z:.9g}"/>\n' for x, y, z in p.vertices.tolist())
        buf.write("</vertices>\n<triangles>\n")
        buf.writelines(f'<triangle v1="{a}" v2="{b}" v3="{c}"/>\n' for a, b, c in p.faces.tolist())
        buf.write("</triangles>\n</mesh>\n</object>\n")
    buf.write("</resources>\n<build>\n")
    for k, t in enumerate(plate_offsets(parts)):
        buf.write(f'<item objectid="{k + 2}" transform="1 0 0 0 1 0 0 0 1 {t[0]:.9g} {t[1]:.9g} {t[2]:.9g}"/>\n')
    buf.write("</build>\n</model>\n")
    return buf.getvalue()


def write_3mf(path: str | Path, parts: list[MeshPart], title: str, description: str = "") -> Path:
    """Write a 3MF package of ``parts`` to ``path`` (replaced only when complete)."""
    from ..fileio import atomic_file

    path = Path(path)
    with atomic_file(path) as tmp:
        with zipfile.ZipFile(tmp, "w", compression=zipfile.ZIP_DEFLATED) as z:
            for name, text in (
                ("[Content_Types].xml", CONTENT_TYPES),
                ("_rels/.rels", RELS),
                ("3D/3dmodel.model", model_xml(parts, title, description)),
            ):
                z.writestr(zipfile.ZipInfo(name, ZIP_TIME), text.encode("utf-8"), zipfile.ZIP_DEFLATED)
    return path


def read_stl_part(path: Path, name: str, color: tuple[float, float, float, float]) -> MeshPart:
    """A build STL as an indexed mesh (vertices merged)."""
    import trimesh

    mesh = trimesh.load_mesh(str(path), file_type="stl", process=True)
    return MeshPart(name, np.asarray(mesh.vertices, float), np.asarray(mesh.faces, np.int64), color)


def print_settings_document(design: Design) -> dict:
    """``print_settings.json``: the slicer settings and the allowances already in the CAD."""
    cuts = cut_sizes(design, "fdm")
    return {
        "format": PRINT_SETTINGS_FORMAT,
        "version": PRINT_SETTINGS_VERSION,
        "design": design.name,
        "design_sha256": design.sha256,
        "profile": "fdm",
        "units": "mm",
        "settings": print_settings(design).as_dict(),
        "orientation": {
            "body": "axis vertical, end face B on the plate",
            "mount": "socket up (frame M +z up)",
            "connector": "pocket up (frame T +z up)",
        },
        "built_into_the_parts": {
            "groove_width_mm": cuts.groove_width,
            "pocket_diameter_mm": cuts.pocket_diameter,
            "hole_allowance_mm": cuts.hole_allowance,
            "socket_diameter_mm": cuts.socket_diameter,
            "pin_hole_diameter_mm": cuts.pin_hole_diameter,
            "slide_clearance_mm": cuts.slide_clearance,
            "fit": cuts.fit,
        },
    }


def write_fdm_files(
    design: Design, out_dir: str | Path, colors: dict[str, tuple[float, float, float, float]]
) -> list[Path]:
    """Write ``fiducial.3mf`` (from the STLs already in ``out_dir``) and ``print_settings.json``.

    Parameters
    ----------
    design : Design
        The design built.
    out_dir : str or pathlib.Path
        The build's directory, holding ``fiducial.stl``, ``mount.stl`` and ``connector.stl``.
    colors : dict
        Each printed part's display colour (RGBA 0–1) by its name in :data:`PRINTED_PARTS`.

    Returns
    -------
    list of pathlib.Path
        The two files written.
    """
    out_dir = Path(out_dir)
    parts = [read_stl_part(out_dir / stl, name, colors[name]) for name, stl in PRINTED_PARTS]
    desc = f"{design.name} printed parts (fdm profile); design sha256 {design.sha256 or 'none'}"
    return [
        write_3mf(out_dir / "fiducial.3mf", parts, design.name, desc),
        write_json_atomic(out_dir / "print_settings.json", print_settings_document(design)),
    ]
