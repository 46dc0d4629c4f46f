"""Design files (TOML) → validated :class:`Design` parameters, and the fiducial's :class:`Body`."""

from .loader import design_body, design_file_named, load_design, parse_body, parse_design
from .schema import Body, Design

__all__ = ["Body", "Design", "design_body", "design_file_named", "load_design", "parse_body", "parse_design"]
