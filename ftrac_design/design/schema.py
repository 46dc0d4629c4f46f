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
from pydantic import BaseModel, ConfigDict, Field, PrivateAttr, field_validator, model_validator

Pos = Annotated[float, Field(gt=0.0)]
NonNeg = Annotated[float, Field(ge=0.0)]
Ident = Annotated[str, Field(pattern=r"^[A-Za-z][A-Za-z0-9_]{0,31}$")]
# TOML arrays arrive as lists; strict mode would refuse them as tuples
Vec3 = Annotated[list[float], Field(min_length=3, max_length=3)]


class _Strict(BaseModel):
    # strict: a string where a number belongs is an error, not a silent conversion.
    model_config = ConfigDict(extra="forbid", strict=True, frozen=True)


class Body(_Strict):
    """The hollow cylinder that carries every feature."""

    outer_diameter: Pos = Field(description="outer diameter of the cylinder, mm")
    length: Pos = Field(description="axial length, mm")
    bore_diameter: NonNeg = Field(description="diameter of the axial through-bore (0 = solid), mm")
    material: str = Field(default="acetal (POM-C)", description="body material")

    @model_validator(mode="after")
    def _bore_inside(self) -> "Body":
        if self.bore_diameter >= self.outer_diameter:
            raise ValueError(
                f"bore_diameter ({self.bore_diameter}) must be smaller than "
                f"outer_diameter ({self.outer_diameter})"
            )
        return self


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

    @model_validator(mode="after")
    def _ordered(self) -> "Line":
        if not self.z_end > self.z_start:
            raise ValueError(f"z_end ({self.z_end}) must be greater than z_start ({self.z_start})")
        return self


class FreeBead(_Strict):
    """A bead that sits on no line (bead-only fiducials)."""

    id: Ident | None = None
    azimuth_deg: float
    z: float

    @property
    def azimuth_rad(self) -> float:
        return math.radians(self.azimuth_deg)


class Mount(_Strict):
    """The acetal mount that holds one end of the cylinder.

    Mount frame M: origin at the centre of the socket floor (where the cylinder's ``z = −L/2``
    end face rests), axes parallel to F.
    """

    socket_depth: Pos = Field(default=3.0, description="how far the cylinder end sits in the socket, mm")


class Connector(_Strict):
    """The extender that fixes the fiducial on a brachytherapy template.

    Template frame T: origin at the template's reference grid hole on its front face, ``+x``
    along the grid rows, ``+y`` along the grid columns (away from the patient's posterior),
    ``+z`` along needle insertion. The fiducial axis is parallel to ``+z`` and F is not
    rotated relative to T.
    """

    grid_pitch: Pos = Field(default=5.0, description="template hole pitch, mm")
    fiducial_offset: Vec3 = Field(
        default=[30.0, 80.0, -60.0], description="F origin in T, mm"
    )


class CncProfile(_Strict):
    """CNC milling of acetal with press-fitted wires and balls (see ``cad.profiles``)."""

    tool_diameter: Pos = Field(default=0.4, description="smallest end mill available for grooves, mm")
    wire_interference: NonNeg = Field(default=0.02, description="wire diameter minus groove width, mm")
    bead_interference: NonNeg = Field(default=0.02, description="ball diameter minus pocket diameter, mm")


class FdmProfile(_Strict):
    """FDM printing with a 0.4 mm nozzle; wires and balls glued in (see ``cad.profiles``)."""

    nozzle_diameter: Pos = Field(default=0.4, description="nozzle (extrusion) width, mm")
    wire_clearance: NonNeg = Field(default=0.15, description="gap per side between wire and groove wall, mm")
    bead_clearance: NonNeg = Field(default=0.15, description="gap per side between ball and pocket wall, mm")
    hole_allowance: NonNeg = Field(default=0.2, description="added to round holes' diameters (they print small), mm")


class Manufacturing(_Strict):
    """Per-design settings of the two manufacturing profiles."""

    cnc: CncProfile = Field(default_factory=CncProfile)
    fdm: FdmProfile = Field(default_factory=FdmProfile)


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
