"""Reading DICOM attributes defensively: every value is converted and checked here, so a
header that lies (a wrong VR string, a negative spacing, a missing item) becomes an
:class:`~ftrac_design.errors.InputError` naming the tag, never another exception.

Enhanced multi-frame objects keep most attributes in functional groups: an attribute of
frame ``i`` is looked up in that frame's item of the Per-frame Functional Groups Sequence
(5200,9230), then in the Shared Functional Groups Sequence (5200,9229), then at the top
level (:func:`lookup`); per-frame values override shared ones.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from ..errors import InputError

PER_FRAME = "PerFrameFunctionalGroupsSequence"
SHARED = "SharedFunctionalGroupsSequence"


def tag_name(keyword: str) -> str:
    """``"Keyword (gggg,eeee)"`` for a DICOM keyword."""
    from pydicom.datadict import tag_for_keyword

    tag = tag_for_keyword(keyword)
    return f"{keyword} ({tag >> 16:04X},{tag & 0xFFFF:04X})" if tag is not None else keyword


def raw_value(ds: Any, keyword: str, path: str | Path) -> Any:
    """The value of ``keyword`` in dataset ``ds`` (None when absent or empty); a value pydicom
    cannot convert is an InputError naming the tag."""
    try:
        if ds is None or keyword not in ds:
            return None
        value = ds[keyword].value
    except Exception as exc:  # pydicom converts lazily: a malformed value raises here (ValueError, …)
        raise InputError(path, tag_name(keyword), f"a valid value ({type(exc).__name__}: {exc})") from None
    if value is None or (isinstance(value, (str, bytes, list, tuple)) and len(value) == 0):
        return None
    return value


def _item(seq: Any, index: int) -> Any:
    try:
        return seq[index] if seq is not None and len(seq) > index else None
    except Exception:
        return None


def group_item(ds: Any, frame: int, macro: str, path: str | Path) -> tuple[Any, str] | None:
    """The item of functional-group ``macro`` (a sequence keyword, e.g. ``"FieldOfViewSequence"``)
    that applies to ``frame``, and ``"per-frame"``/``"shared"``; None when neither has it."""
    for where, seq_kw, idx in (("per-frame", PER_FRAME, frame), ("shared", SHARED, 0)):
        group = _item(raw_value(ds, seq_kw, path), idx)
        if group is None:
            continue
        inner = raw_value(group, macro, path)
        item = _item(inner, 0)
        if item is not None:
            return item, where
    return None


def lookup(ds: Any, frame: int, macro: str | None, keyword: str, path: str | Path) -> tuple[Any, str]:
    """The value of ``keyword`` for ``frame``: inside functional group ``macro`` (per-frame,
    then shared) when given, else at the top level. Returns (value or None, where found)."""
    if macro is not None:
        found = group_item(ds, frame, macro, path)
        if found is not None:
            value = raw_value(found[0], keyword, path)
            if value is not None:
                return value, f"{found[1]} {macro}"
    return raw_value(ds, keyword, path), "top level"


def as_floats(value: Any, keyword: str, path: str | Path, n: int, *, positive: bool = False) -> tuple[float, ...]:
    """``value`` as ``n`` finite floats (positive ones when asked), else InputError naming the tag."""
    items = list(value) if isinstance(value, (list, tuple)) or type(value).__name__ == "MultiValue" else [value]
    what = f"{n} finite {'positive ' if positive else ''}number{'s' if n > 1 else ''}"
    if len(items) != n:
        raise InputError(path, tag_name(keyword), f"{what}, got {len(items)} value(s)")
    try:
        out = tuple(float(x) for x in items)
    except (TypeError, ValueError):
        raise InputError(path, tag_name(keyword), f"{what}, got {items!r}") from None
    if not all(math.isfinite(x) for x in out) or (positive and min(out) <= 0):
        raise InputError(path, tag_name(keyword), f"{what}, got {list(out)}")
    return out


def as_int(value: Any, keyword: str, path: str | Path, lo: int | None = None, hi: int | None = None) -> int:
    """``value`` as an integer within [lo, hi], else InputError naming the tag."""
    try:
        f = float(value)
        i = int(f)
        if i != f:
            raise ValueError
    except (TypeError, ValueError, OverflowError):
        raise InputError(path, tag_name(keyword), f"an integer, got {value!r}") from None
    if (lo is not None and i < lo) or (hi is not None and i > hi):
        rng = f"{lo if lo is not None else '…'} … {hi if hi is not None else '…'}"
        raise InputError(path, tag_name(keyword), f"an integer in {rng}, got {i}")
    return i


def as_text(value: Any) -> str:
    """A CS/LO value as upper-case stripped text ('' when absent); multi-valued → first value."""
    if value is None:
        return ""
    if isinstance(value, (list, tuple)) or type(value).__name__ == "MultiValue":
        value = value[0] if len(value) else ""
    return str(value).strip().upper()
