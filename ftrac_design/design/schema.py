"""Typed, validated design parameters of an FTRAC fiducial.

A design file (TOML) describes the fiducial body and where its radiographic features sit
on it. Only independent parameters are typed in; everything derived (seating radii, ellipse
semi-axes, end-points) is computed here or in :mod:`ftrac_design.features`.

Fiducial frame F (SPEC §1): origin on the cylinder axis at mid-length, ``+z`` along the
axis. Azimuths are measured about ``+z`` from ``+x`` toward ``+y``; ``+y = z × x``. The
design's ``nominal_beam_direction`` is the nominal (AP) beam direction, camera ``+z``
expressed in F; the shipped presets use ``[0, -1, 0]``: the source sits on the ``+y`` side
and the beam travels toward ``-y``.

Lengths are millimetres; angles typed in design files are degrees (keys end in ``_deg``)
and become radians through the ``*_rad`` properties.
"""

from __future__ import annotations

import math
from typing import Annotated, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, PrivateAttr, ValidationInfo, field_validator
from pydantic.dataclasses import dataclass

Pos = Annotated[float, Field(gt=0.0)]
NonNeg = Annotated[float, Field(ge=0.0)]
Ident = Annotated[str, Field(pattern=r"^[A-Za-z][A-Za-z0-9_]{0,31}$")]
# TOML arrays arrive as lists; strict mode would refuse them as tuples
Vec3 = Annotated[list[float], Field(min_length=3, max_length=3)]
# a pydantic dataclass takes a table only when it is not strict itself: its fields are, one by one
StrictPos = Annotated[float, Field(gt=0.0, strict=True)]
StrictNonNeg = Annotated[float, Field(ge=0.0, strict=True)]
StrictStr = Annotated[str, Field(strict=True)]


class _Strict(BaseModel):
    # strict: a string where a number belongs is an error, not a silent conversion;
    # TOML's inf and nan are refused too (no geometry is infinite).
    model_config = ConfigDict(extra="forbid", strict=True, frozen=True, allow_inf_nan=False)


@dataclass(frozen=True, config=ConfigDict(extra="forbid", allow_inf_nan=False))
class Body:
    """The hollow cylinder that carries every feature: about F's z axis, centred at the F origin
    (mm). The one body of the package: the design's ``[body]``, the fiducial's
    (:attr:`ftrac_design.features.Features.body`), the one the simulator renders and the tracker
    subtracts.

    A plain frozen dataclass, validated as it is made (each size strictly a number): ``Body(30.0,
    50.0, 20.0)`` or a design file's table. The simulator reads ``material`` through
    :func:`ftrac_design.xray.materials.material_name` (``"acetal (POM-C)"`` is acetal).
    """

    outer_diameter: StrictPos = Field(description="outer diameter of the cylinder, mm")
    length: StrictPos = Field(description="axial length, mm")
    bore_diameter: StrictNonNeg = Field(description="diameter of the axial through-bore (0 = solid), mm")
    material: StrictStr = Field(default="acetal (POM-C)", description="body material")

    # a field validator (not a model validator) so that the error names body.bore_diameter
    @field_validator("bore_diameter")
    @classmethod
    def _bore_inside(cls, v: float, info: ValidationInfo) -> float:
        outer = info.data.get("outer_diameter")
        if outer is not None and v >= outer:
            raise ValueError(f"a bore smaller than outer_diameter ({outer}), got {v!r}")
        return v


class Wire(_Strict):
    """Radio-opaque wire pressed into the grooves (bought part: does not scale with the body)."""

    diameter: Pos = Field(description="wire diameter, mm")
    material: str = "stainless steel 304 (spring temper)"


class Bead(_Strict):
    """Radio-opaque ball pressed into a pocket (bought part)."""

    diameter: Pos = Field(description="ball diameter, mm")
    material: str = "stainless steel 440C ball, grade 25"


class Seating(_Strict):
    """How deep each kind of feature sits: depth of its *centre* below the outer surface, mm.

    Line wires and the beads on them share one depth so that every bead centre lies exactly
    on its line; ellipse wires sit shallower so that a line wire passes beneath an ellipse
    wire where the two cross.
    """

    ellipse_wire_depth: Pos | None = Field(default=None, description="required when the design has ellipses")
    line_wire_depth: Pos | None = Field(default=None, description="required when the design has lines")
    free_bead_depth: Pos | None = Field(
        default=None, description="centre depth of beads that sit on no line (defaults to bead radius)"
    )


class Ellipse(_Strict):
    """An ellipse wire: where a plane tilted from the cross-section cuts the cylinder.

    The plane passes through ``(0, 0, z_center)``; its normal is tilted by ``tilt_deg`` from
    ``+z`` toward azimuth ``tilt_azimuth_deg``. On the seating radius r the wire runs at
    ``z(φ) = z_center − r·tan(tilt)·cos(φ − tilt_azimuth)``.
    """

    id: Ident
    tilt_deg: Annotated[float, Field(gt=0.0, lt=80.0)]
    tilt_azimuth_deg: float
    z_center: float

    @property
    def tilt_rad(self) -> float:
        return math.radians(self.tilt_deg)

    @property
    def tilt_azimuth_rad(self) -> float:
        return math.radians(self.tilt_azimuth_deg)


class Line(_Strict):
    """A straight wire parallel to the axis, with beads threaded along it.

    ``beads_z`` are the axial positions of the bead centres on this line (the line's
    end-points may carry beads). Between beads the wire runs in segments that butt against
    the balls.
    """

    id: Ident
    azimuth_deg: float
    z_start: float
    z_end: float
    beads_z: list[float] = Field(default_factory=list)

    @property
    def azimuth_rad(self) -> float:
        return math.radians(self.azimuth_deg)

    @field_validator("z_end")
    @classmethod
    def _ordered(cls, v: float, info: ValidationInfo) -> float:
        start = info.data.get("z_start")
        if start is not None and not v > start:
            raise ValueError(f"a value greater than z_start ({start}), got {v!r}")
        return v


class FreeBead(_Strict):
    """A bead that sits on no line (bead-only fiducials)."""

    id: Ident | None = None
    azimuth_deg: float
    z: float

    @property
    def azimuth_rad(self) -> float:
        return math.radians(self.azimuth_deg)


GridNode = Annotated[list[int], Field(min_length=2, max_length=2)]


class HoleSet(_Strict):
    """One set of parallel through holes for socket-head cap screws, counterbored on the
    set's ``+`` face (the screw heads' side; the table or plate it bolts to is on the ``−`` face).

    Defaults are for M4: clearance hole Ø4.5 (ISO 273, medium series), counterbore Ø8 × 4.4
    for the ISO 4762 head (Ø7.0 × 4.0 max; DIN 974-1 counterbore, head height + 0.4).

    Patterns, in the mount frame M (see :class:`Mount`): the set along ``x`` spreads along
    ``y``, the set along ``y`` along ``z`` and the set along ``z`` along ``x`` (``pair``: two
    holes ``pitch`` apart; ``square``: four holes on a ``pitch`` square, which spreads along
    the third axis as well; ``single``: one hole). With ``pair`` the three sets miss each other
    by construction; other patterns are checked by the ``mount.hole_clearance`` rule.
    """

    pattern: Literal["single", "pair", "square"] = "pair"
    pitch: Pos | None = Field(
        default=None,
        description="hole spacing, mm; default: the mount's grid_pitch, and for the z set the "
        "smallest multiple of it whose holes clear the socket",
    )
    diameter: Pos = Field(default=4.5, description="clearance hole, mm (ISO 273 medium, M4)")
    counterbore_diameter: NonNeg = Field(default=8.0, description="0 = no counterbore, mm")
    counterbore_depth: NonNeg = Field(default=4.4, description="mm")
    screw: str = Field(default="M4", description="thread of the screws, for the bill of materials")

    @field_validator("counterbore_diameter")
    @classmethod
    def _cb_wider(cls, v: float, info: ValidationInfo) -> float:
        d = info.data.get("diameter")
        if v and d is not None and v <= d:
            raise ValueError(f"0 (none) or a counterbore wider than the hole (diameter {d}), got {v!r}")
        return v


#: the slot in the cylinder's end face is this much deeper than the key is high, so that the
#: cylinder always rests on the socket floor, never on the key (mm)
KEY_GAP = 0.2


class Mount(_Strict):
    """The acetal mount that holds one end of the cylinder (paper §II.A.3): a square block
    with a press-fit socket for the cylinder's ``z = −L/2`` end and three mutually orthogonal
    sets of through holes to bolt it to a rotary table in three orientations.

    Mount frame M: origin at the centre of the socket floor, where the cylinder's
    ``z = −L/2`` end face rests; axes parallel to F (``+z`` out of the socket along the
    cylinder axis). The block spans ``x, y ∈ ±width/2`` and ``z ∈ [−base_height,
    socket_depth]``. With ``key_height > 0`` a key (tongue) across the socket floor along
    azimuth ``key_azimuth_deg`` engages a slot that ``build`` cuts across the cylinder's end
    face, so the cylinder's azimuth in the socket is fixed positively, not by friction alone.
    Off by default (the paper's cylinder is a plain press fit, aligned when pressed in);
    recommended for the template connector, where ``template_from_fiducial`` must hold
    without re-calibration.

    Default hole grid 25 mm: the grid of metric optical breadboards and many rotary-stage
    tops. The screws are M4; a table tapped M6 on that grid needs ``diameter = 6.6``,
    ``counterbore_diameter = 11``, ``counterbore_depth = 6.4`` in each set.
    """

    socket_depth: Pos = Field(default=3.0, description="how far the cylinder end sits in the socket, mm")
    grid_pitch: Pos = Field(default=25.0, description="hole grid of the table the mount bolts to, mm")
    width: Pos | None = Field(
        default=None,
        description="block side along x and y, mm; default: the smallest whole mm "
        "that keeps every hole 1.5 diameters from an edge",
    )
    base_height: Pos | None = Field(
        default=None,
        description="block below the socket floor, mm; default: the smallest whole mm that holds the x and y hole sets",
    )
    holes_x: HoleSet = Field(default_factory=HoleSet)
    holes_y: HoleSet = Field(default_factory=HoleSet)
    holes_z: HoleSet = Field(default_factory=HoleSet)
    key_width: Pos = Field(default=2.0, description="width of the anti-rotation key, mm")
    key_height: NonNeg = Field(default=0.0, description="height of the key above the socket floor (0 = no key), mm")
    key_azimuth_deg: float = Field(default=0.0, description="direction of the key across the socket, about +z from +x")
    material: str = "acetal (POM-C)"

    @property
    def key_azimuth_rad(self) -> float:
        return math.radians(self.key_azimuth_deg)


class Connector(_Strict):
    """The extender that fixes the fiducial on a brachytherapy template (paper §IV, Fig. 10a).

    Template frame T: origin at the centre of the template's reference grid hole on its front
    (operator-side) face; ``+x`` along the grid rows, ``+y`` along the grid columns toward the
    patient's anterior (up, for a patient in lithotomy), ``+z`` along needle insertion, into
    the template and toward the patient. Grid holes sit at ``(i, j) · grid_pitch``.

    The connector is a plate on the template's front face (``z ∈ [−thickness, 0]``). Two dowel
    pins pressed into it enter the grid holes ``pins`` (column i, row j); the plate reaches up
    past the template's top edge, and there a pocket in its ``+z`` face takes the mount's
    block (a positive location in x, y and rotation; the pocket floor locates z), held by
    screws through the mount's z hole set into the plate. The cylinder then points along
    ``+z`` over the template's top edge. With ``source_side = "posterior"`` (X-ray tube under
    the table, the usual C-arm set-up) the AP beam travels along ``+y`` of T, so F (whose
    ``+y`` points toward the source) is turned 180° about z: ``x_F = −x_T``, ``y_F = −y_T``;
    with ``"anterior"`` F is parallel to T.

    Default pin: Ø1.2 mm ISO 2338 m6, the largest ISO dowel size that enters a grid hole made
    for an 18G needle (Ø1.27 mm), so the play is under 0.1 mm.
    """

    grid_pitch: Pos = Field(default=5.0, description="template hole pitch, mm")
    pin_diameter: Pos = Field(default=1.2, description="dowel pins into the template's grid holes, mm")
    pin_length: Pos = Field(default=10.0, description="mm")
    pin_engagement: Pos = Field(default=4.0, description="how far the pins enter the template, mm")
    pins: list[GridNode] = Field(
        default_factory=lambda: [[0, 0], [10, 0]],
        min_length=2,
        max_length=2,
        description="grid nodes [column, row] of the two pins, counted from the reference hole",
    )
    axis_x: float = Field(default=25.0, description="x of the fiducial axis in T, mm")
    axis_height: float = Field(
        default=50.0, description="height (y in T) of the fiducial axis above the reference hole, mm"
    )
    template_edge: float = Field(
        default=10.0, description="height of the template's top edge above the reference hole, mm"
    )
    source_side: Literal["posterior", "anterior"] = Field(
        default="posterior", description="side of the patient the X-ray source is on in the AP view"
    )
    thickness: Pos = Field(default=15.0, description="plate thickness along z, mm")
    pocket_depth: Pos = Field(default=3.0, description="depth of the pocket that locates the mount, mm")
    pocket_wall: Pos = Field(default=5.0, description="plate material around the pocket, mm")
    edge_margin: Pos = Field(default=4.0, description="pin hole centre to plate edge, mm")
    tap_drill: Pos = Field(default=3.3, description="drill for the tapped holes of the mount screws (M4: 3.3), mm")
    material: str = "acetal (POM-C)"


class CncProfile(_Strict):
    """CNC milling of acetal with press-fitted wires and balls (see ``manufacture.profiles``)."""

    tool_diameter: Pos = Field(default=0.4, description="smallest end mill available for grooves, mm")
    wire_interference: NonNeg = Field(default=0.02, description="wire diameter minus groove width, mm")
    bead_interference: NonNeg = Field(default=0.02, description="ball diameter minus pocket diameter, mm")
    socket_interference: NonNeg = Field(default=0.05, description="cylinder diameter minus mount socket diameter, mm")
    pin_interference: NonNeg = Field(default=0.02, description="dowel pin diameter minus its hole in the connector, mm")
    slide_clearance: NonNeg = Field(
        default=0.025, description="gap per side of the sliding fits (mount in pocket, key in slot), mm"
    )
    # cutting data for the 4-axis program (ftrac_design.machining): engineering-plastics milling
    # tables give 91-114 m/min and a feed per tooth of 0.0009 in for a 1/8 in end mill (0.0072 x D)
    pocket_tool_diameter: Pos | None = Field(
        default=None,
        description="end mill for the bead pockets, mm; default: the largest stock size "
        "between half and 0.8 of the pocket diameter",
    )
    flutes: Annotated[int, Field(ge=1, le=8)] = Field(default=2, description="flutes of both end mills")
    cutting_speed: Pos = Field(default=91.0, description="surface speed, m/min (plastics tables: 91-114)")
    spindle_max_rpm: Pos = Field(default=24000.0, description="the spindle's top speed, rpm")
    feed_per_tooth_ratio: Pos = Field(default=0.0072, description="feed per tooth / tool diameter")
    step_down_ratio: Pos = Field(default=0.5, description="depth of cut per level / tool diameter")
    ramp_angle_deg: Annotated[float, Field(gt=0.0, le=30.0)] = Field(
        default=3.0, description="slope of ramped and helical entries, degrees"
    )


class FdmProfile(_Strict):
    """FDM printing with a 0.4 mm nozzle; wires and balls glued in (see ``manufacture.profiles``)."""

    nozzle_diameter: Pos = Field(default=0.4, description="nozzle (extrusion) width, mm")
    wire_clearance: NonNeg = Field(default=0.15, description="gap per side between wire and groove wall, mm")
    bead_clearance: NonNeg = Field(default=0.15, description="gap per side between ball and pocket wall, mm")
    hole_allowance: NonNeg = Field(default=0.2, description="added to round holes' diameters (they print small), mm")
    press_allowance: NonNeg = Field(default=0.1, description="added to press-fit holes (socket, dowel pins), mm")
    slide_clearance: NonNeg = Field(
        default=0.2, description="gap per side of the sliding fits (mount in pocket, key in slot), mm"
    )


class Manufacturing(_Strict):
    """Per-design settings of the two manufacturing profiles."""

    cnc: CncProfile = Field(default_factory=CncProfile)
    fdm: FdmProfile = Field(default_factory=FdmProfile)
    wire_cut_allowance: NonNeg = Field(
        default=5.0, description="extra length per wire piece in the bill of materials, mm"
    )


class Analysis(_Strict):
    """Workspace and pass/fail thresholds of the conditioning analysis (``ftrac-design
    analyze``; see :mod:`ftrac_design.analysis.score`). Command-line options override these.

    The workspace (SPEC §1) is every beam within ``cone_deg`` of the nominal beam (180: the
    whole sphere), every roll in ``roll_range_deg``,
    the fiducial origin ``depth`` ± ``depth_range`` from the source and within ``lateral`` of
    the principal ray. Thresholds bound the worst predicted 1σ 3-D RMS error over it at the
    stated segmentation error (the paper's uniform error magnitude, mm at the detector).
    """

    cone_deg: Annotated[float, Field(gt=0.0, le=180.0)] = 25.0
    depth: Pos = Field(default=667.0, description="source to fiducial origin, mm")
    depth_range: NonNeg = Field(default=25.0, description="mm")
    lateral: NonNeg = Field(default=25.0, description="offset from the principal ray, mm")
    roll_range_deg: Annotated[list[float], Field(min_length=2, max_length=2)] = Field(
        default_factory=lambda: [0.0, 360.0], description="roll about the beam, [from, to] degrees"
    )
    segmentation_error: Pos = Field(default=0.25, description="mm at the detector")
    # a part's image localises better or worse than another size's (ftrac_design.xray.localization):
    # the optimiser writes these when it changes stock sizes, so `analyze` scores the design it wrote
    bead_error_factor: Pos = Field(default=1.0, description="bead centres' segmentation error / segmentation_error")
    wire_error_factor: Pos = Field(default=1.0, description="wire contours' segmentation error / segmentation_error")
    poses: Annotated[int, Field(ge=100, le=10_000_000)] = 20_000
    max_translation: Pos = Field(default=1.0, description="worst predicted translation error, mm")
    max_rotation_deg: Pos = 0.5
    max_condition: Annotated[float, Field(ge=1.0)] = 1000.0
    # segmentability (ftrac_design.analysis.segmentability): judged only where set
    max_overlap_share: Annotated[float, Field(ge=0.0, le=1.0)] | None = Field(
        default=None, description="largest share of workspace poses where features' images overlap"
    )
    min_clearance_px: float | None = Field(
        default=None, description="smallest 5th-percentile image clearance between features, px beyond their widths"
    )


class Design(_Strict):
    """A complete, validated fiducial design."""

    name: Ident
    description: str = ""
    nominal_beam_direction: Vec3
    body: Body
    wire: Wire | None = None
    bead: Bead | None = None
    seating: Seating
    ellipses: list[Ellipse] = Field(default_factory=list)
    lines: list[Line] = Field(default_factory=list)
    beads: list[FreeBead] = Field(default_factory=list)
    mount: Mount = Field(default_factory=Mount)
    connector: Connector = Field(default_factory=Connector)
    manufacturing: Manufacturing = Field(default_factory=Manufacturing)
    analysis: Analysis = Field(default_factory=Analysis)
    units: Literal["mm"] = "mm"

    # where the design was read from; set by ftrac_design.design.load_design
    _source: str | None = PrivateAttr(default=None)
    _sha256: str | None = PrivateAttr(default=None)

    @property
    def source(self) -> str | None:
        """Path of the design file as given by the user, or None for an in-memory design."""
        return self._source

    @property
    def sha256(self) -> str | None:
        """sha256 of the design file's bytes, or None for an in-memory design."""
        return self._sha256

    # ---- derived values (mm) -------------------------------------------------------------
    @property
    def outer_radius(self) -> float:
        return self.body.outer_diameter / 2.0

    @property
    def bore_radius(self) -> float:
        return self.body.bore_diameter / 2.0

    @property
    def half_length(self) -> float:
        return self.body.length / 2.0

    @property
    def ellipse_seat_radius(self) -> float:
        """Radius of the ellipse wires' centre-lines, mm."""
        return self.outer_radius - (self.seating.ellipse_wire_depth or 0.0)

    @property
    def line_seat_radius(self) -> float:
        """Radius of the line wires' centre-lines and of the beads on them, mm."""
        return self.outer_radius - (self.seating.line_wire_depth or 0.0)

    @property
    def free_bead_depth(self) -> float:
        if self.seating.free_bead_depth is not None:
            return self.seating.free_bead_depth
        return self.bead.diameter / 2.0 if self.bead else 0.0

    @property
    def free_bead_seat_radius(self) -> float:
        return self.outer_radius - self.free_bead_depth

    @property
    def nominal_beam(self) -> np.ndarray:
        """Unit nominal beam direction in F."""
        v = np.asarray(self.nominal_beam_direction, float)
        return v / np.linalg.norm(v)

    @field_validator("nominal_beam_direction")
    @classmethod
    def _unit(cls, v: list[float]) -> list[float]:
        n = math.sqrt(sum(c * c for c in v))
        if not math.isfinite(n) or n < 1e-9:
            raise ValueError("a non-zero 3-vector")
        return [c / n for c in v]
