"""Our own header note: a JSON object after ``ftrac:`` in a PNG ``tEXt`` chunk, the TIFF
ImageDescription or the DICOM ImageComments, written by :func:`~ftrac_design.images.write_image`.

It may hold ``camera`` (SPEC §3 object), ``polarity`` (``dense_dark``/``dense_bright``),
``quantity`` (``log``/``raw``/free), ``formation`` and ``rescale_slope``/``rescale_intercept``
(value = stored × slope + intercept).
"""

from __future__ import annotations

import json
import math
from typing import Any

from ..pose.camera import Camera
from .frame import Formation, Polarity, polarity_from_legacy

NOTE_PREFIX = "ftrac:"


def parse_note(text: str | None) -> dict[str, Any]:
    """The note's JSON object from a header text, or {} when there is none or it is not ours."""
    if not text:
        return {}
    i = text.find(NOTE_PREFIX)
    blob = text[i + len(NOTE_PREFIX) :] if i >= 0 else text
    try:
        d = json.loads(blob)
    except ValueError:
        return {}
    if isinstance(d, dict) and isinstance(d.get("ftrac"), dict):
        d = d["ftrac"]
    return d if isinstance(d, dict) else {}


def camera_from_note(d: Any) -> Camera | None:
    """A valid :class:`Camera` from a SPEC §3 camera dict, else None."""
    try:
        cam = Camera(
            float(d["focal_length_mm"]),
            tuple(float(x) for x in d["pixel_size_mm"]),
            tuple(float(x) for x in d["principal_point_px"]),
        )
        if len(cam.pixel_size_mm) != 2 or len(cam.principal_point_px) != 2:
            return None
        cam.validate()
    except (KeyError, TypeError, ValueError, IndexError):
        return None
    return cam


def note_polarity(note: dict[str, Any]) -> Polarity | None:
    """The polarity our note states, or None."""
    return polarity_from_legacy(note.get("polarity"))


def note_formation(note: dict[str, Any]) -> Formation | None:
    """The formation our note states (``formation``, or ``quantity`` log/raw), or None."""
    f = note.get("formation")
    if f in ("linear", "log", "display"):
        return f
    return {"log": "log", "raw": "linear"}.get(note.get("quantity")) if isinstance(note.get("quantity"), str) else None


def note_rescale(note: dict[str, Any]) -> tuple[float, float] | None:
    """(slope, intercept) of our note's linear map when both are finite numbers, else None."""
    try:
        s, b = float(note["rescale_slope"]), float(note["rescale_intercept"])
    except (KeyError, TypeError, ValueError):
        return None
    return (s, b) if math.isfinite(s) and math.isfinite(b) and s != 0 else None
