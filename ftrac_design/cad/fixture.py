"""The mount, the template connector and its dowel pins, placed in the assembly frame F.

Each part is built in its own frame (mount in M, connector and pins in T) and moved into F
only by the transforms that ``features.json`` carries: the mount by
``inverse(frames.mount_from_fiducial)``, the connector and pins by
``inverse(frames.template_from_fiducial)``. So the assembly shows exactly the frames a user
of ``features.json`` relies on.
"""

from __future__ import annotations

from dataclasses import dataclass

import cadquery as cq
import numpy as np

from ..design.schema import Design
from ..features.model import Features
from ..features.mounting import connector_layout, mount_layout
from ..igt.frames import rigid_inverse
from ..manufacture.profiles import Profile, cut_sizes
from .connector import ConnectorPart, pin_solid
from .mount import MountPart
from .placement import placed

#: assembly colours (RGBA): white acetal mount, grey acetal connector, steel pins
MOUNT_COLOR = (0.97, 0.97, 0.95, 1.0)
CONNECTOR_COLOR = (0.55, 0.57, 0.60, 1.0)
PIN_COLOR = (0.30, 0.30, 0.32, 1.0)


@dataclass(frozen=True)
class FixturePart:
    """A mount-side part as built in its own frame and as placed in F."""

    name: str
    kind: str  # "mount", "connector" or "pin"
    local: cq.Solid
    frame: str  # "M" or "T": the frame ``local`` is built in
    fiducial_from_local: np.ndarray
    color: tuple[float, float, float, float]

    @property
    def solid(self) -> cq.Shape:
        """The part placed in F."""
        return placed(self.local, self.fiducial_from_local)


def fixture_parts(design: Design, features: Features, profile: Profile = "cnc") -> list[FixturePart]:
    """Mount, connector and dowel pins of ``design`` placed by ``features.frames``."""
    cuts = cut_sizes(design, profile)
    mlay = mount_layout(design)
    clay = connector_layout(design, mlay)
    F_from_M = rigid_inverse(features.frames["mount_from_fiducial"])
    F_from_T = rigid_inverse(features.frames["template_from_fiducial"])
    out = [
        FixturePart("mount", "mount", MountPart(mlay, cuts).build(), "M", F_from_M, MOUNT_COLOR),
        FixturePart("connector", "connector", ConnectorPart(clay, cuts).build(), "T", F_from_T, CONNECTOR_COLOR),
    ]
    for k, pin in enumerate(clay.pins, start=1):
        out.append(FixturePart(f"pin_{k}", "pin", pin_solid(pin), "T", F_from_T, PIN_COLOR))
    return out


def add_to_assembly(assy: cq.Assembly, parts: list[FixturePart]) -> cq.Assembly:
    """Add the fixture parts to an assembly in F (named and coloured)."""
    for p in parts:
        assy.add(p.solid, name=p.name, color=cq.Color(*p.color))
    return assy
