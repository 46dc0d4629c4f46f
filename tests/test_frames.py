"""Frames M and T: ``features.json`` carries ``mount_from_fiducial`` and
``template_from_fiducial`` computed from the same layout the CAD builds, and an assembly
STEP built by those transforms has every part where the transforms say (probed on the
re-imported solids)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from fixture_support import PRESETS, TMP, assembly_parts, design_of, inside

from ftrac_design.features import compute_features, features_from_dict, features_to_dict
from ftrac_design.features.mounting import (
    connector_layout,
    mount_layout,
    template_from_fiducial,
    template_from_mount,
    transform_points,
)

pytestmark = pytest.mark.xdist_group("cad")

EPS = 0.05  # mm: probe distance on either side of a face


def is_rigid(T):
    R = T[:3, :3]
    return (
        np.allclose(R @ R.T, np.eye(3), atol=1e-12)
        and math.isclose(np.linalg.det(R), 1.0)
        and np.array_equal(T[3], [0, 0, 0, 1])
    )


@pytest.mark.parametrize("preset", PRESETS)
def test_frames_in_features(preset):
    d = design_of(preset)
    f = compute_features(d)
    M, T = f.frames["mount_from_fiducial"], f.frames["template_from_fiducial"]
    assert is_rigid(M) and is_rigid(T)
    assert np.allclose(T, template_from_mount(d) @ M, atol=1e-12)
    # F -> M: the cylinder's z = -L/2 end-face centre is M's origin, axes parallel
    assert np.allclose(transform_points(M, [0, 0, -d.half_length]), 0, atol=1e-12)
    assert np.allclose(M[:3, :3], np.eye(3))
    # they survive features.json
    g = features_from_dict(features_to_dict(f))
    for k in ("mount_from_fiducial", "template_from_fiducial"):
        assert np.array_equal(g.frames[k], f.frames[k])


@pytest.mark.parametrize("side", ["posterior", "anterior"])
def test_template_orientation(side):
    import tomllib

    from fixture_support import MODELS

    from ftrac_design.design import parse_design

    data = tomllib.loads((MODELS / "ftrac_2005.toml").read_text())
    data.setdefault("connector", {})["source_side"] = side
    d = parse_design(data)
    T = template_from_fiducial(d)
    beam_T = T[:3, :3] @ d.nominal_beam
    # the AP beam runs along the template's y axis: up (+y, source under the table) for posterior
    assert np.allclose(beam_T, [0, 1, 0] if side == "posterior" else [0, -1, 0])
    # the fiducial sits above the template's top edge and in front of it along +z, over the patient
    c = d.connector
    axis_T = transform_points(T, np.array([[0, 0, -d.half_length], [0, 0, d.half_length]]))
    assert np.allclose(axis_T[:, :2], [c.axis_x, c.axis_height])
    assert axis_T[0, 1] - d.outer_radius > c.template_edge
    assert axis_T[1, 2] > axis_T[0, 2] > 0


@pytest.mark.parametrize("preset", PRESETS)
def test_template_frame_arithmetic(preset):
    """T from the parts' stack: axis at (axis_x, axis_height); the mount's bottom on the pocket floor."""
    d = design_of(preset)
    lay = mount_layout(d)
    T = template_from_fiducial(d)
    bottom_F = np.array([0.0, 0.0, -d.half_length - lay.base_height])
    assert np.allclose(
        transform_points(T, bottom_F),
        [d.connector.axis_x, d.connector.axis_height, -d.connector.pocket_depth],
        atol=1e-12,
    )
    con = connector_layout(d, lay)
    assert np.allclose(con.pocket_center, transform_points(T, bottom_F))


@pytest.fixture(scope="module", params=[*PRESETS, "ftrac_2005+key", "ftrac_mini+anterior"])
def assembly(request):
    """An assembly STEP of a stand-in body (blank cylinder, with its key slot if keyed),
    mount, connector and pins, built only through fixture_parts / add_to_assembly, re-imported."""
    import cadquery as cq
    from test_rules import with_param

    from ftrac_design.cad.fixture import add_to_assembly, fixture_parts
    from ftrac_design.cad.mount import key_slot_tool

    name, _, variant = request.param.partition("+")
    if variant == "key":
        d = with_param(name, "mount.key_height", 1.0)
    elif variant == "anterior":
        d = with_param(name, "connector.source_side", "anterior")
    else:
        d = design_of(name)
    f = compute_features(d)
    L = d.body.length
    body = cq.Solid.makeCylinder(d.outer_radius, L, cq.Vector(0, 0, -L / 2)).cut(
        cq.Solid.makeCylinder(d.bore_radius, L + 2, cq.Vector(0, 0, -L / 2 - 1))
    )
    slot = key_slot_tool(d)
    if slot is not None:
        body = body.cut(slot)
    assy = cq.Assembly(name=d.name)
    assy.add(body, name="body", color=cq.Color(0.9, 0.9, 0.85, 1))
    parts = fixture_parts(d, f)
    add_to_assembly(assy, parts)
    path = TMP / f"frames-{request.param}.step"
    assy.export(str(path), exportType="STEP")
    own = {p.name: p.local for p in parts}  # each part in its own frame (M or T)
    return d, f, assembly_parts(path), own


def test_assembly_names_and_colours(assembly):
    from ftrac_design.cad.fixture import CONNECTOR_COLOR, MOUNT_COLOR

    d, f, parts, own = assembly
    assert {"body", "mount", "connector", "pin_1", "pin_2"} <= set(parts)
    assert parts["mount"][1] == pytest.approx(MOUNT_COLOR, abs=1e-6)
    assert parts["connector"][1] == pytest.approx(CONNECTOR_COLOR, abs=1e-6)


def test_mount_from_fiducial_matches_assembly(assembly):
    """The cylinder's end face rests on the socket floor where mount_from_fiducial puts it."""
    d, f, parts, own = assembly
    body, mount = parts["body"][0], parts["mount"][0]
    lay = mount_layout(d)
    side = np.cross([0, 0, 1.0], lay.key.direction)  # away from the key (if there is one)
    r_mid = (d.bore_radius + d.outer_radius) / 2
    P_F = side * r_mid + [0, 0, -d.half_length]  # on the cylinder's end face, in the wall
    up = np.array([0, 0, EPS])
    assert inside(mount, P_F - up) and not inside(mount, P_F + up)
    assert inside(body, P_F + up) and not inside(body, P_F - up)
    # the mount's own STEP frame M: that point is on its socket floor
    mount_M = own["mount"]
    P_M = transform_points(f.frames["mount_from_fiducial"], P_F)
    assert abs(P_M[2]) < 1e-12
    assert inside(mount_M, P_M - up) and not inside(mount_M, P_M + up)
    # and the placed mount is the M solid moved by inverse(mount_from_fiducial)
    c_M = np.array(mount_M.Center().toTuple())
    c_F = np.array(mount.Center().toTuple())
    assert np.allclose(transform_points(f.frames["mount_from_fiducial"], c_F), c_M, atol=1e-6)


def test_template_from_fiducial_matches_assembly(assembly):
    """A point on the cylinder axis, mapped by template_from_fiducial, lands on the connector's
    pocket floor in the connector's own frame and in the assembly; the pins sit on the grid."""
    d, f, parts, own = assembly
    T = f.frames["template_from_fiducial"]
    lay = mount_layout(d)
    A_F = np.array([0.0, 0.0, -d.half_length - lay.base_height])  # axis point: the mount's bottom face
    A_T = transform_points(T, A_F)
    up = np.array([0, 0, EPS])
    conn, mount = parts["connector"][0], parts["mount"][0]
    assert inside(conn, A_F - up) and not inside(conn, A_F + up)
    assert inside(mount, A_F + up) and not inside(mount, A_F - up)
    conn_T = own["connector"]
    assert inside(conn_T, A_T - up) and not inside(conn_T, A_T + up)
    assert np.allclose(A_T[:2], [d.connector.axis_x, d.connector.axis_height])
    # pins in the assembly, mapped into T, stand on grid nodes along +z
    pitch = d.connector.grid_pitch
    for k, node in enumerate(d.connector.pins, start=1):
        pin = parts[f"pin_{k}"][0]
        bb = pin.BoundingBox()
        c_T = transform_points(T, np.array(pin.Center().toTuple()))
        assert np.allclose(c_T[:2] / pitch, node, atol=1e-9)
        tip = transform_points(T, np.array([bb.center.x, bb.center.y, bb.zmax]))
        assert tip[2] == pytest.approx(d.connector.pin_engagement, abs=1e-9)
