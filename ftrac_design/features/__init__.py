"""Feature geometry: the one source of truth for where every wire and bead sits."""

from .io import features_from_dict, features_to_dict, load_features, write_features
from .model import EllipseFeature, Features, LineFeature, PointFeature

__all__ = [
    "EllipseFeature",
    "Features",
    "LineFeature",
    "PointFeature",
    "features_from_dict",
    "features_to_dict",
    "load_features",
    "write_features",
    "compute_features",
]


def compute_features(design):
    """Seated features of a :class:`~ftrac_design.design.Design` (see :mod:`.geometry`)."""
    from .geometry import compute_features as _cf  # keeps `pose` free of pydantic imports

    return _cf(design)
