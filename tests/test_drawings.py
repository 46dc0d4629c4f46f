"""The shop drawings and the FDM files that ``build`` writes, read back independently.

Drawings: every dimension printed in a sheet's SVG (a text element under ``dim.<part>.<key>``)
is parsed and compared, to its printed precision, with a value computed here from the
features, the design and the built STEP solids (cylindrical faces, bounding boxes) — not
from the dimension module that printed it; every groove and pocket of the design is on the
body's sheet; no decimal number is printed outside a checked element; the title block
carries the design file's sha256; the PDFs are valid one-page PDFs.

FDM: ``fiducial.3mf`` read back by trimesh and by lib3mf (the 3MF Consortium's library)
has the STLs' triangle counts and volumes per part, names, colours and millimetres;
``print_settings.json`` states what the fdm profile assumes.
"""

from __future__ import annotations

import datetime as dt
import functools
import hashlib
import json
import math
import re
import xml.etree.ElementTree as ET

import cad_support as S
import numpy as np
import pytest
from scipy.optimize import minimize_scalar

pytestmark = pytest.mark.xdist_group("cad")

PRESET = "ftrac_mini"
PARTS = ("body", "mount", "connector")
NUM = re.compile(r"^([ØR]?)(-?\d+\.(\d+))(°?)(?: ±(\d+\.\d+)°?)?( ◆)?(?: × 45°)?$")
SVG_NS = "{http://www.w3.org/2000/svg}"


@functools.cache
def svg_texts(profile: str, part: str, preset: str = PRESET) -> tuple[dict[str, str], list[tuple[str, str]]]:
    """({group id: text} for every id'd text group, [(innermost group id, text)] for all text)."""
    root = ET.parse(S.build(preset, profile).out_dir / f"drawing_{part}.svg").getroot()
    by_id: dict[str, str] = {}
    every: list[tuple[str, str]] = []

    def walk(el, gid):
        own = el.get("id", gid) if el.tag == f"{SVG_NS}g" else gid
        if el.tag == f"{SVG_NS}text":
            text = "".join(el.itertext())
            every.append((own or "", text))
            if own:
                assert own not in by_id, f"two texts under {own}"
                by_id[own] = text
        for child in el:
            walk(child, own)

    walk(root, None)
    return by_id, every


def printed(profile: str, part: str, preset: str = PRESET) -> dict[str, str]:
    """{dimension key: printed text} of one sheet."""
    by_id, _ = svg_texts(profile, part, preset)
    prefix = f"dim.{part}."
    return {k[len(prefix) :]: v for k, v in by_id.items() if k.startswith(prefix)}


def parse(text: str) -> tuple[float, int, float | None, bool]:
    """(value, decimals, ± tolerance or None, fit-critical mark) of a printed dimension."""
    m = NUM.match(text)
    assert m, f"not a dimension: {text!r}"
    tol = float(m.group(5)) if m.group(5) else None
    return float(m.group(2)), len(m.group(3)), tol, bool(m.group(6))


def agrees(text: str, expected: float) -> bool:
    value, dec, _, _ = parse(text)
    return abs(value - expected) <= 0.5 * 10**-dec + 1e-9


# ---- values computed here, independently of manufacture.dimensions ---------------------------------


def _azimuth(p) -> float:
    return math.degrees(math.atan2(p[1], p[0])) % 360.0


def _ellipse_extreme(e, sign: float) -> tuple[float, float]:
    """(A°, z) of the highest (sign = +1) or lowest point of the seated ellipse, by search."""
    s = np.linspace(0, 2 * np.pi, 20001)
    k = int(np.argmax(sign * e.sample(s)[:, 2]))
    res = minimize_scalar(
        lambda t: -sign * e.sample(np.array([t]))[0, 2],
        bounds=(s[k] - 1e-3, s[k] + 1e-3),
        method="bounded",
        options={"xatol": 1e-12},
    )
    p = e.sample(np.array([res.x]))[0]
    return _azimuth(p), float(p[2])


def expected_body(preset: str, profile: str) -> dict[str, float]:
    d, f, _ = S.design_features_cuts(preset, profile)
    R = d.body.outer_diameter / 2
    p = d.manufacturing.cnc if profile == "cnc" else d.manufacturing.fdm
    wire = d.wire.diameter if d.wire else float("nan")  # a design without wires has no grooves
    groove = wire - p.wire_interference if profile == "cnc" else wire + 2 * p.wire_clearance
    pocket = d.bead.diameter - p.bead_interference if profile == "cnc" else d.bead.diameter + 2 * p.bead_clearance
    out = {
        "body.length": d.body.length,
        "body.outer_diameter": d.body.outer_diameter,
        "body.bore_diameter": d.body.bore_diameter,
        "datum_C.A": d.lines[0].azimuth_deg % 360 if d.lines else _azimuth(f.points[0].center),
    }
    for e in f.ellipses:
        seat = float(np.hypot(*e.sample(np.array([0.3]))[0, :2]))
        (a_t, z_t), (a_b, z_b) = _ellipse_extreme(e, 1.0), _ellipse_extreme(e, -1.0)
        out |= {
            f"{e.id}.top.A": a_t,
            f"{e.id}.top.z": z_t,
            f"{e.id}.bottom.A": a_b,
            f"{e.id}.bottom.z": z_b,
            f"{e.id}.width": groove,
            f"{e.id}.depth": R - seat + wire / 2,
        }
    for ln in f.lines:
        out |= {
            f"{ln.id}.A": _azimuth(ln.start),
            f"{ln.id}.start.z": ln.start[2],
            f"{ln.id}.end.z": ln.end[2],
            f"{ln.id}.width": groove,
            f"{ln.id}.depth": R - math.hypot(*ln.start[:2]) + wire / 2,
        }
    for b in f.points:
        out |= {
            f"{b.id}.A": _azimuth(b.center),
            f"{b.id}.z": b.center[2],
            f"{b.id}.diameter": pocket,
            f"{b.id}.depth": R - math.hypot(*b.center[:2]) + b.diameter / 2,
        }
    return out


@functools.cache
def cylinders(profile: str, step: str) -> list[tuple[float, np.ndarray, np.ndarray]]:
    """(radius, point on the axis, axis direction) of every cylindrical face of a built STEP."""
    import cadquery as cq
    from OCP.BRepAdaptor import BRepAdaptor_Surface
    from OCP.GeomAbs import GeomAbs_Cylinder

    shape = cq.importers.importStep(str(S.build(PRESET, profile).out_dir / step)).val()
    out = []
    for face in shape.Faces():
        srf = BRepAdaptor_Surface(face.wrapped)
        if srf.GetType() == GeomAbs_Cylinder:
            c = srf.Cylinder()
            loc, d = c.Location(), c.Axis().Direction()
            out.append((c.Radius(), np.array([loc.X(), loc.Y(), loc.Z()]), np.array([d.X(), d.Y(), d.Z()])))
    return out


def has_cylinder(profile: str, step: str, diameter_text: str, point, direction, slack: float) -> bool:
    """Is there a cylindrical face of the printed Ø whose axis runs through ``point`` along ``direction``?"""
    value, dec, _, _ = parse(diameter_text)
    point, direction = np.asarray(point, float), np.asarray(direction, float)
    for r, q, d in cylinders(profile, step):
        if abs(2 * r - value) > 0.5 * 10**-dec + 1e-9 or abs(abs(d @ direction) - 1) > 1e-9:
            continue
        v = point - q
        if np.linalg.norm(v - (v @ d) * d) <= slack:
            return True
    return False


def bbox(profile: str, step: str):
    import cadquery as cq

    return cq.importers.importStep(str(S.build(PRESET, profile).out_dir / step)).val().BoundingBox(tolerance=1e-6)


# ---- the drawings ---------------------------------------------------------------------------


@pytest.mark.parametrize(
    "preset,profile", [(PRESET, "cnc"), (PRESET, "fdm"), ("ftrac_2005", "cnc"), ("nine_bead", "cnc")]
)
def test_body_dimensions_equal_features(preset, profile):
    got = printed(profile, "body", preset)
    want = expected_body(preset, profile)
    assert set(got) == set(want), f"printed but not checked: {set(got) - set(want)}; missing: {set(want) - set(got)}"
    wrong = {k: (got[k], want[k]) for k in want if not agrees(got[k], want[k])}
    assert not wrong, wrong
    _, f, _ = S.design_features_cuts(preset, profile)
    for ident in [*(e.id for e in f.ellipses), *(ln.id for ln in f.lines)]:
        assert parse(got[f"{ident}.width"])[3] and parse(got[f"{ident}.depth"])[3], f"{ident} not marked critical"
    for b in f.points:
        assert parse(got[f"{b.id}.diameter"])[3], f"pocket {b.id} not marked critical"


def test_body_pockets_are_in_the_cad_where_printed():
    """Each pocket's printed (A, z, Ø) is a cylindrical face of fiducial.step: radial axis
    through (0, 0, z) at azimuth A, diameter Ø."""
    got = printed("cnc", "body")
    _, f, _ = S.design_features_cuts(PRESET, "cnc")
    R = S.design_of(PRESET).body.outer_diameter / 2
    for b in f.points:
        a = math.radians(parse(got[f"{b.id}.A"])[0])
        z = parse(got[f"{b.id}.z"])[0]
        slack = 0.5e-3 + R * math.radians(0.005)
        assert has_cylinder(
            "cnc", "fiducial.step", got[f"{b.id}.diameter"], (0, 0, z), (math.cos(a), math.sin(a), 0), slack
        ), b.id


def test_every_groove_and_pocket_is_drawn():
    _, every = svg_texts("cnc", "body")
    texts = {t for _, t in every}
    _, f, _ = S.design_features_cuts(PRESET, "cnc")
    for ident in f.ids:
        assert ident in texts, f"{ident} not labelled on the unrolled view"


def test_tolerances_are_the_profiles():
    from ftrac_design.manufacture.profiles import CNC_GENERAL_TOLERANCE, CNC_TOLERANCE, FDM_TOLERANCE

    for profile, gen, crit in (("cnc", CNC_GENERAL_TOLERANCE, CNC_TOLERANCE), ("fdm", FDM_TOLERANCE, FDM_TOLERANCE)):
        R = S.design_of(PRESET).body.outer_diameter / 2
        ang = math.degrees(crit / R)
        for part in PARTS:
            by_id, _ = svg_texts(profile, part)
            assert agrees(by_id["tol.general"].lstrip("±"), gen) and agrees(by_id["tol.critical"].lstrip("±"), crit)
            for key, text in printed(profile, part).items():
                _, _, tol, critical = parse(text)
                if tol is None:
                    continue
                allowed = [ang] if NUM.match(text).group(4) else [crit] if critical else [gen, crit]
                assert any(agrees(f"{tol:.{parse(text)[1]}f}", a) for a in allowed), (part, key, text)
        assert agrees(svg_texts(profile, "body")[0]["tol.angle"].lstrip("±").rstrip("°"), ang)


def test_mount_dimensions_equal_the_cad():
    from ftrac_design.features.mounting import BLOCK_CHAMFER, mount_layout

    d = S.design_of(PRESET)
    got = printed("cnc", "mount")
    bb = bbox("cnc", "mount.step")
    want = {
        "block.width": bb.xlen,
        "block.height": bb.zlen,
        "block.base": -bb.zmin,
        "block.chamfer": BLOCK_CHAMFER,
        "socket.depth": d.mount.socket_depth,
        "socket.diameter": d.body.outer_diameter - d.manufacturing.cnc.socket_interference,
    }
    assert bb.xlen == pytest.approx(bb.ylen, abs=1e-6) and bb.zmax == pytest.approx(d.mount.socket_depth, abs=1e-6)
    holes = mount_layout(d).holes
    for h in holes:
        hs = getattr(d.mount, f"holes_{h.name[0]}")
        u, v = [k for k in range(3) if k != h.axis]
        want |= {
            f"{h.name}.diameter": hs.diameter,
            f"{h.name}.cbore_diameter": hs.counterbore_diameter,
            f"{h.name}.cbore_depth": hs.counterbore_depth,
        }
        # the position is checked against the solid: a hole of the printed Ø through the printed point
        p = np.zeros(3)
        p[u], p[v] = parse(got[f"{h.name}.{'xyz'[u]}"])[0], parse(got[f"{h.name}.{'xyz'[v]}"])[0]
        assert has_cylinder("cnc", "mount.step", got[f"{h.name}.diameter"], p, np.eye(3)[h.axis], 1e-3), h.name
        want |= {f"{h.name}.{'xyz'[u]}": p[u], f"{h.name}.{'xyz'[v]}": p[v]}
    assert has_cylinder("cnc", "mount.step", got["socket.diameter"], (0, 0, 0), (0, 0, 1), 1e-6)
    assert set(got) == set(want), set(got) ^ set(want)
    wrong = {k: (got[k], want[k]) for k in want if not agrees(got[k], want[k])}
    assert not wrong, wrong
    assert parse(got["socket.diameter"])[3], "the socket's press fit is not marked critical"


def test_connector_dimensions_equal_the_cad():
    from ftrac_design.features.mounting import POCKET_CORNER_RADIUS, connector_layout

    d = S.design_of(PRESET)
    got = printed("cnc", "connector")
    bb, mount_bb = bbox("cnc", "connector.step"), bbox("cnc", "mount.step")
    c = d.connector
    want = {
        "plate.x0": bb.xmin,
        "plate.y0": bb.ymin,
        "plate.width": bb.xlen,
        "plate.height": bb.ylen,
        "plate.thickness": bb.zlen,
        "pocket.x": c.axis_x,
        "pocket.y": c.axis_height,
        "pocket.size": mount_bb.xlen + 2 * d.manufacturing.cnc.slide_clearance,
        "pocket.depth": c.pocket_depth,
        "pocket.radius": POCKET_CORNER_RADIUS,
    }
    for h in connector_layout(d).holes:
        x, y = parse(got[f"{h.name}.x"])[0], parse(got[f"{h.name}.y"])[0]
        assert has_cylinder("cnc", "connector.step", got[f"{h.name}.diameter"], (x, y, 0), (0, 0, 1), 1e-3), h.name
        dia = c.pin_diameter - d.manufacturing.cnc.pin_interference if h.kind == "pin" else c.tap_drill
        want |= {f"{h.name}.x": x, f"{h.name}.y": y, f"{h.name}.diameter": dia}
        if h.kind == "pin":
            i, j = c.pins[int(h.name[-1]) - 1]
            assert agrees(got[f"{h.name}.x"], i * c.grid_pitch) and agrees(got[f"{h.name}.y"], j * c.grid_pitch)
            assert parse(got[f"{h.name}.diameter"])[3]
    assert set(got) == set(want), set(got) ^ set(want)
    wrong = {k: (got[k], want[k]) for k in want if not agrees(got[k], want[k])}
    assert not wrong, wrong


@pytest.mark.parametrize("part", PARTS)
def test_no_unchecked_number_and_the_title_block(part):
    d = S.design_of(PRESET)
    by_id, every = svg_texts("cnc", part)
    stray = [(gid, t) for gid, t in every if re.search(r"\d\.\d", t) and not gid.startswith(("dim.", "tol."))]
    assert not stray, stray
    assert by_id["tb.sha256"] == hashlib.sha256((S.MODELS / f"{PRESET}.toml").read_bytes()).hexdigest()
    assert by_id["tb.sha256"] == d.sha256
    assert by_id["tb.design"] == d.name and by_id["tb.profile"] == "cnc" and by_id["tb.units"] == "mm"
    assert by_id["tb.material"] == getattr(d, "body" if part == "body" else part).material
    assert re.fullmatch(r"(views )?\d+:\d+(, end view \d+:\d+)?(, unrolled \d+:\d+)?", by_id["tb.scale"])
    dt.date.fromisoformat(by_id["tb.date"])
    for letter in ("A", "B", "C"):
        assert by_id[f"datum.{letter}"] == letter


@pytest.mark.parametrize("part", PARTS)
def test_pdf_is_valid(part):
    pypdf = pytest.importorskip("pypdf")
    path = S.build(PRESET, "cnc").out_dir / f"drawing_{part}.pdf"
    raw = path.read_bytes()
    assert raw.startswith(b"%PDF-") and raw.rstrip().endswith(b"%%EOF")
    reader = pypdf.PdfReader(str(path), strict=True)
    assert len(reader.pages) == 1
    w, h = (float(x) for x in reader.pages[0].mediabox.upper_right)
    assert (w, h) == pytest.approx((420 / 25.4 * 72, 297 / 25.4 * 72), abs=0.5)  # A3 landscape, true scale


def test_drawings_in_the_manifest():
    from ftrac_design.fileio import sha256_file

    res = S.build(PRESET, "fdm")
    files = json.loads((res.out_dir / "manifest.json").read_text())["files"]
    for name in [f"drawing_{p}.{x}" for p in PARTS for x in ("svg", "pdf")] + ["fiducial.3mf", "print_settings.json"]:
        assert files[name]["sha256"] == sha256_file(res.out_dir / name)


# ---- FDM ------------------------------------------------------------------------------------


def test_3mf_reads_back_like_the_stls():
    import trimesh

    pytest.importorskip("lxml")  # trimesh's 3MF reader
    out = S.build(PRESET, "fdm").out_dir
    scene = trimesh.load(str(out / "fiducial.3mf"))
    assert set(scene.geometry) == {"body", "mount", "connector"}
    placed = scene.dump(concatenate=False)
    for name, stl in (("body", "fiducial.stl"), ("mount", "mount.stl"), ("connector", "connector.stl")):
        ref = trimesh.load_mesh(str(out / stl))
        mesh = scene.geometry[name]
        assert len(mesh.faces) == len(ref.faces) and mesh.is_volume
        assert mesh.volume == pytest.approx(ref.volume, rel=1e-7)
    lows = [m.bounds[0][2] for m in placed]
    assert lows == pytest.approx([0.0] * 3, abs=1e-6)  # every part stands on the plate
    spans = sorted((m.bounds[0][0], m.bounds[1][0]) for m in placed)
    assert all(a[1] < b[0] for a, b in zip(spans, spans[1:]))  # side by side, not overlapping


def test_3mf_units_names_colours_by_lib3mf():
    lib3mf = pytest.importorskip("lib3mf")
    from ftrac_design.cad.export import BODY_COLOR
    from ftrac_design.cad.fixture import CONNECTOR_COLOR, MOUNT_COLOR

    out = S.build(PRESET, "fdm").out_dir
    model = lib3mf.get_wrapper().CreateModel()
    reader = model.QueryReader("3mf")
    reader.SetStrictModeActive(True)
    reader.ReadFromFile(str(out / "fiducial.3mf"))
    assert reader.GetWarningCount() == 0
    assert model.GetUnit() == lib3mf.ModelUnit.MilliMeter
    colors = {}
    groups = model.GetBaseMaterialGroups()
    while groups.MoveNext():
        g = groups.GetCurrentBaseMaterialGroup()
        for pid in g.GetAllPropertyIDs():
            c = g.GetDisplayColor(pid)
            colors[(g.GetResourceID(), pid)] = (c.Red, c.Green, c.Blue, c.Alpha)
    meshes = {}
    it = model.GetMeshObjects()
    while it.MoveNext():
        o = it.GetCurrentMeshObject()
        rid, pid, has = o.GetObjectLevelProperty()
        assert has and o.IsManifoldAndOriented()
        meshes[o.GetName()] = colors[(rid, pid)]
    want = {"body": BODY_COLOR, "mount": MOUNT_COLOR, "connector": CONNECTOR_COLOR}
    assert set(meshes) == set(want)
    for name, rgba in want.items():
        assert meshes[name] == tuple(int(round(c * 255)) for c in rgba)


def test_print_settings_state_what_the_profile_assumes():
    from ftrac_design.manufacture.profiles import FDM_WALL_MIN, FDM_WALL_RECOMMENDED, cut_sizes

    d = S.design_of(PRESET)
    doc = json.loads((S.build(PRESET, "fdm").out_dir / "print_settings.json").read_text())
    s = doc["settings"]
    nozzle = d.manufacturing.fdm.nozzle_diameter
    assert doc["format"] == "ftrac-print-settings" and doc["design_sha256"] == d.sha256 and doc["units"] == "mm"
    assert s["nozzle_diameter_mm"] == nozzle and s["line_width_mm"] == nozzle
    assert 0.2 * nozzle <= s["layer_height_mm"] <= 0.8 * nozzle  # the slicers' usable range
    # the walls the fdm rules demand are whole perimeters
    assert s["perimeters"] * s["line_width_mm"] >= FDM_WALL_RECOMMENDED >= FDM_WALL_MIN
    assert s["infill_percent"] == 100 and s["xy_hole_compensation_mm"] == 0.0
    assert set(s["sources"]) >= {"line_width", "layer_height", "perimeters", "infill_percent"}
    cuts = cut_sizes(d, "fdm")
    assert doc["built_into_the_parts"]["groove_width_mm"] == cuts.groove_width
    assert doc["built_into_the_parts"]["pocket_diameter_mm"] == cuts.pocket_diameter
    assert not (S.build(PRESET, "cnc").out_dir / "fiducial.3mf").exists()


# ---- the drawings command, on a keyed design -------------------------------------------------


def test_drawings_command_keyed_design(tmp_path, capsys):
    """``ftrac-design drawings`` on ftrac_mini with a key: the key slot is dimensioned on the
    body, the key on the mount, and datum C is the key's azimuth; a directory holding other
    files is refused (exit 2, nothing written)."""
    from ftrac_design.cli.main import main
    from ftrac_design.design import load_design
    from ftrac_design.design.schema import KEY_GAP

    text = (S.MODELS / f"{PRESET}.toml").read_text()
    assert "\n[mount]\n" in text
    src = tmp_path / "keyed.toml"
    key = "key_height = 0.4\nkey_width = 1.0\nkey_azimuth_deg = 30.0\n"
    src.write_text(text.replace("\n[mount]\n", "\n[mount]\n" + key))
    d = load_design(src)
    out = tmp_path / "drawn"
    assert main(["drawings", str(src), "-o", str(out)]) == 0
    assert sorted(p.name for p in out.iterdir()) == sorted(f"drawing_{p}.{x}" for p in PARTS for x in ("svg", "pdf"))

    def dims(part):
        root = ET.parse(out / f"drawing_{part}.svg").getroot()
        return {
            g.get("id")[len(f"dim.{part}.") :]: "".join(g.itertext()).strip()
            for g in root.iter(f"{SVG_NS}g")
            if (g.get("id") or "").startswith(f"dim.{part}.")
        }

    body, mount = dims("body"), dims("mount")
    m = d.mount
    assert agrees(body["key_slot.width"], m.key_width + 2 * d.manufacturing.cnc.slide_clearance)
    assert agrees(body["key_slot.depth"], m.key_height + KEY_GAP)
    assert agrees(body["datum_C.A"], m.key_azimuth_deg) and agrees(mount["key.A"], m.key_azimuth_deg)
    assert agrees(mount["key.width"], m.key_width) and agrees(mount["key.height"], m.key_height)
    assert parse(body["key_slot.width"])[3] and parse(mount["key.width"])[3]

    other = tmp_path / "other"
    other.mkdir()
    (other / "keep.txt").write_text("x")
    capsys.readouterr()
    assert main(["drawings", str(src), "-o", str(other)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "other" in err[0]
    assert sorted(p.name for p in other.iterdir()) == ["keep.txt"]
