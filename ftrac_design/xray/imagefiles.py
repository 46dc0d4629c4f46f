"""Old home of the image readers and writers: thin re-exports of :mod:`ftrac_design.images`."""

from ..images import read_image, write_image  # noqa: F401
from ..images.notes import camera_from_note as _camera_from_dict  # noqa: F401
