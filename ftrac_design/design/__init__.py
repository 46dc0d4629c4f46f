"""Design files (TOML) → validated :class:`Design` parameters."""

from .loader import load_design, parse_design
from .schema import Design

__all__ = ["Design", "load_design", "parse_design"]
