"""Mount and template connector as solids: valid, closed-form volumes, STEP round trip,
watertight STL, three mutually orthogonal sets of through holes, dowel-pin axes on the
template grid, and profile-dependent cut sizes exactly as each profile states."""

from __future__ import annotations

import math

import numpy as np
import pytest
from fixture_support import (
    PRESETS,
    PROFILES,
    TMP,
    connector_part,
    cylindrical_faces,
    design_of,
    inside,
    mount_part,
    step_round_trip,
    stl_mesh,
)

from ftrac_design.features.mounting import connector_layout, mount_layout, template_from_mount, transform_points
from ftrac_design.manufacture.profiles import cut_sizes

pytestmark = pytest.mark.xdist_group("cad")

CASES = [(p, q) for p in PRESETS for q in PROFILES]


@pytest.mark.parametrize("preset,profile", CASES)
def test_mount_solid_and_volume(preset, profile):
    part, solid = mount_part(preset, profile)
    assert solid.isValid() and len(solid.Solids()) == 1
    assert solid.Volume() == pytest.approx(part.nominal_volume(), rel=1e-9)
    lay = part.layout
    bb = solid.BoundingBox()
    assert (bb.xmin, bb.xmax, bb.ymin, bb.ymax) == pytest.approx((-lay.width / 2, lay.width / 2) * 2)
    assert (bb.zmin, bb.zmax) == pytest.approx((-lay.base_height, lay.socket_depth))


@pytest.mark.parametrize("preset,profile", CASES)
def test_connector_solid_and_volume(preset, profile):
    part, solid = connector_part(preset, profile)
    assert solid.isValid() and len(solid.Solids()) == 1
    assert solid.Volume() == pytest.approx(part.nominal_volume(), rel=1e-9)
    bb = solid.BoundingBox()
    lo, hi = part.layout.lo, part.layout.hi
    assert (bb.xmin, bb.ymin, bb.zmin, bb.xmax, bb.ymax, bb.zmax) == pytest.approx((*lo, *hi))


@pytest.mark.parametrize("which", ["mount", "connector"])
@pytest.mark.parametrize("preset", PRESETS)
def test_step_round_trip_and_watertight_stl(preset, which):
    part, solid = (mount_part if which == "mount" else connector_part)(preset, "cnc")
    back = step_round_trip(solid, TMP / f"{preset}-{which}.step")
    assert back.isValid() and len(back.Solids()) == 1
    assert back.Volume() == pytest.approx(solid.Volume(), rel=1e-9)
    assert back.Center().toTuple() == pytest.approx(solid.Center().toTuple(), abs=1e-9)
    mesh = stl_mesh(solid, TMP / f"{preset}-{which}.stl")
    assert mesh.is_watertight and mesh.is_volume
    assert mesh.volume == pytest.approx(solid.Volume(), rel=2e-3)


@pytest.mark.parametrize("preset,profile", CASES)
def test_mount_hole_sets_orthogonal_and_through(preset, profile):
    part, solid = mount_part(preset, profile)
    lay = part.layout
    faces = cylindrical_faces(solid)
    directions = {}
    for h in lay.holes:
        r = part.hole_diameters[h.name] / 2
        # the B-rep has a cylindrical face of the hole's cut radius on the hole's axis ...
        match = [f for f in faces if abs(f.radius - r) < 1e-9 and f.distance_to_line(h.center, h.direction) < 1e-9]
        assert match, f"no cylindrical face for hole {h.name}"
        directions.setdefault(h.name[0], []).append(match[0].direction)
        # ... and the hole goes through: its axis is outside the solid from face to face,
        # while the block is solid just beyond the hole's (and counterbore's) wall
        for t in np.linspace(h.lo - 0.2, h.hi + 0.2, 41):
            p = np.array(h.center, float)
            p[h.axis] = t
            assert not inside(solid, p), f"hole {h.name} blocked at {p}"
        u = (h.axis + 1) % 3
        p = np.array(h.center, float)
        p[h.axis] = (h.lo + h.hi - h.counterbore_depth) / 2
        p[u] += max(r, part.counterbore_diameters.get(h.name, 0) / 2) + 0.3
        if abs(p[u]) < lay.width / 2:
            assert inside(solid, p)
    # one set along each axis of M; the three sets are mutually orthogonal
    assert set(directions) == {"x", "y", "z"}
    for a, ds in directions.items():
        axis = np.eye(3)["xyz".index(a)]
        assert all(abs(abs(float(d @ axis)) - 1) < 1e-12 for d in ds)
    for a in "xyz":
        for b in "xyz":
            if a < b:
                assert abs(float(directions[a][0] @ directions[b][0])) < 1e-12


@pytest.mark.parametrize("preset,profile", CASES)
def test_connector_pin_axes_on_the_template_grid(preset, profile):
    part, solid = connector_part(preset, profile)
    d = design_of(preset)
    pitch = d.connector.grid_pitch
    r = part.pin_hole_diameter / 2
    axes = [f for f in cylindrical_faces(solid) if abs(f.radius - r) < 1e-9]
    found = set()
    for f in axes:
        assert abs(abs(f.direction[2]) - 1) < 1e-12  # along the needles (z of T)
        node = f.point[:2] / pitch
        assert np.allclose(node, np.round(node), atol=1e-9), f"pin axis {f.point[:2]} is off the grid"
        found.add(tuple(int(v) for v in np.round(node)))
    assert found == {tuple(p) for p in d.connector.pins}
    # tapped holes sit under the mount's z hole set, mapped by template_from_mount
    mount = mount_layout(d)
    T_TM = template_from_mount(d, mount)
    tap_r = part.tap_hole_diameter / 2
    taps = [f for f in cylindrical_faces(solid) if abs(f.radius - tap_r) < 1e-9]
    for h in mount.set("z"):
        q = transform_points(T_TM, np.array([h.center[0], h.center[1], 0.0]))
        assert any(f.distance_to_line(q, np.array([0.0, 0.0, 1.0])) < 1e-9 for f in taps)


def radii(shape) -> list[float]:
    """The distinct cylinder radii of ``shape``'s faces, to 1e-9 mm."""
    return sorted({round(f.radius, 9) for f in cylindrical_faces(shape)})


@pytest.mark.parametrize("preset", PRESETS)
def test_profiles_change_hole_sizes_exactly_as_stated(preset):
    d = design_of(preset)
    cnc, fdm = cut_sizes(d, "cnc"), cut_sizes(d, "fdm")
    (mc, ms), (mf, mfs) = mount_part(preset, "cnc"), mount_part(preset, "fdm")
    (cc, cs), (cf, cfs) = connector_part(preset, "cnc"), connector_part(preset, "fdm")
    # same layout (feature geometry), different cut sizes
    assert np.array_equal([h.center for h in mc.layout.holes], [h.center for h in mf.layout.holes])
    assert (mc.layout.width, mc.layout.base_height) == (mf.layout.width, mf.layout.base_height)
    fdm_cfg = d.manufacturing.fdm
    cnc_cfg = d.manufacturing.cnc
    assert ms.isValid() and mfs.isValid()
    assert round(d.body.outer_diameter / 2 - cnc_cfg.socket_interference / 2, 9) in radii(ms)
    assert round(d.body.outer_diameter / 2 + fdm_cfg.press_allowance / 2, 9) in radii(mfs)
    for h in mc.layout.holes:
        assert mf.hole_diameters[h.name] - mc.hole_diameters[h.name] == pytest.approx(fdm_cfg.hole_allowance)
        assert round(mc.hole_diameters[h.name] / 2, 9) in radii(ms)
        assert round(mf.hole_diameters[h.name] / 2, 9) in radii(mfs)
    assert cc.pin_hole_diameter == pytest.approx(d.connector.pin_diameter - cnc_cfg.pin_interference)
    assert cf.pin_hole_diameter == pytest.approx(d.connector.pin_diameter + fdm_cfg.press_allowance)
    assert cf.pocket_size - cc.pocket_size == pytest.approx(2 * (fdm_cfg.slide_clearance - cnc_cfg.slide_clearance))
    assert (cnc.slide_clearance, fdm.slide_clearance) == (cnc_cfg.slide_clearance, fdm_cfg.slide_clearance)
    # outer sizes and positions do not change
    assert cs.BoundingBox().xlen == pytest.approx(cfs.BoundingBox().xlen)
    assert ms.BoundingBox().zlen == pytest.approx(mfs.BoundingBox().zlen)


@pytest.mark.parametrize("preset", PRESETS)
def test_mount_key_and_body_slot(preset):
    import cadquery as cq
    from test_rules import with_param

    from ftrac_design.cad.mount import MountPart, key_slot_tool

    assert design_of(preset).mount.key_height == 0 and key_slot_tool(design_of(preset)) is None
    d = with_param(preset, "mount.key_height", 1.0)
    part = MountPart.of(d, "cnc")
    solid = part.build()
    assert solid.isValid() and solid.Volume() == pytest.approx(part.nominal_volume(), rel=1e-9)
    k = part.layout.key
    # the key stands on the socket floor, across the socket, along its azimuth
    assert inside(solid, [0.0, 0.0, k.height / 2])
    assert not inside(solid, [0.0, 0.0, k.height + 0.05])
    side = np.cross([0, 0, 1.0], k.direction)
    assert not inside(solid, side * (k.width / 2 + 0.05) + [0, 0, k.height / 2])
    # the slot in the cylinder's end face (F) is wider and deeper than the key
    tool = key_slot_tool(d, "cnc")
    bb = tool.BoundingBox()
    assert bb.zmax == pytest.approx(-d.half_length + k.slot_depth)
    cuts = cut_sizes(d, "cnc")
    slot_width = cuts.slide(k.width)
    assert tool.isInside(cq.Vector(*(side * (slot_width / 2 - 1e-3) + [0, 0, -d.half_length + 0.1])))
    assert not tool.isInside(cq.Vector(*(side * (slot_width / 2 + 1e-3) + [0, 0, -d.half_length + 0.1])))


def test_derived_mount_sizes():
    """Default mount: 25 mm grid; the z pitch grows to 50 mm on the Ø30 body to clear the socket."""
    big, mini = mount_layout(design_of("ftrac_2005")), mount_layout(design_of("ftrac_mini"))
    assert big.pitches == {"x": 25.0, "y": 25.0, "z": 50.0}
    assert mini.pitches == {"x": 25.0, "y": 25.0, "z": 25.0}
    assert (big.width, mini.width) == (64.0, 39.0)
    for lay in (big, mini):
        assert all(math.isclose(h.diameter, 4.5) and h.counterbore_diameter == 8.0 for h in lay.holes)
    c = connector_layout(design_of("ftrac_2005"))
    assert [p.node for p in c.pins] == [(0, 0), (10, 0)]


@pytest.mark.parametrize("preset", PRESETS)
@pytest.mark.parametrize("profile", PROFILES)
def test_bill_of_materials(preset, profile):
    from ftrac_design.features import compute_features
    from ftrac_design.manufacture.bom import ISO4762_LENGTHS, bill_of_materials

    d = design_of(preset)
    f = compute_features(d)
    bom = bill_of_materials(d, f, profile)
    assert bom["profile"] == profile
    allowance = d.manufacturing.wire_cut_allowance
    if f.ellipses or f.lines:
        for feat in (*f.ellipses, *f.lines):
            pieces = [p for p in bom["wires"]["pieces"] if p["feature"] == feat.id]
            assert sum(p["length"] for p in pieces) == pytest.approx(f.wire_length(feat.id), abs=1e-3 * len(pieces))
            for p in pieces:
                assert p["cut_length"] == pytest.approx(p["length"] + allowance, abs=0.06)
    else:
        assert bom["wires"] is None
    assert bom["beads"]["count"] == len(f.points) and bom["beads"]["diameter"] == d.bead.diameter
    stock = {s["part"]: s for s in bom["stock"]}
    lay = mount_layout(d)
    if profile == "cnc":
        assert stock["body"]["diameter"] >= d.body.outer_diameter + 2
        assert stock["body"]["length"] > d.body.length
        assert all(s >= fin + 2 for s, fin in zip(stock["mount"]["size"], stock["mount"]["finished"]))
    else:
        assert stock["mount"]["size"] == stock["mount"]["finished"] == [lay.width, lay.width, lay.height]
    fix = bom["screws"][0]
    n = int(fix["item"].split(" x ")[1])
    assert n in ISO4762_LENGTHS and fix["qty"] == len(lay.set("z"))
    clamp = lay.height - d.mount.holes_z.counterbore_depth
    assert n <= clamp + d.connector.thickness - d.connector.pocket_depth  # never out of the plate's back
    assert fix["thread_engagement"] >= fix["recommended_engagement"]
    (pins,) = bom["dowel_pins"]
    assert pins["qty"] == 2 and pins["grid_nodes"] == d.connector.pins
    assert pins["item"].startswith("ISO 2338 1.2 m6")
