"""PLUS-style sequence files holding a tracked run: one transform per frame, its status and time.

PLUS and 3D Slicer's Sequences module store a tracked run of linear transforms as a MetaImage
(``.seq.mha``) header with per-frame fields (frame number ``NNNN`` zero-padded to 4):

- ``Seq_FrameNNNN_FrameNumber``: the 0-based index in the run;
- ``Seq_FrameNNNN_<Name>Transform``: the 4×4 matrix, 16 numbers row by row (Slicer reads it
  as the transform's "to parent" matrix, RAS);
- ``Seq_FrameNNNN_<Name>TransformStatus``: ``OK``, or ``INVALID`` (no pose: the identity is
  written, as Slicer writes it);
- ``Seq_FrameNNNN_Timestamp`` and ``…_UnfilteredTimestamp``: seconds (the pose's ``time_s``,
  else the frame's index in the file);
- ``Seq_FrameNNNN_ImageStatus``: ``INVALID`` — the file holds the transforms only.

The ``.seq.mha`` is laid out as Slicer writes a transform-only sequence (``DimSize = 0 0 N``,
``ElementDataFile = LOCAL`` last, no pixel data); Slicer's ``vtkMRMLLinearTransformSequenceStorageNode``
reads it as one linear transform per frame, indexed by the timestamps (rounded to 1 ms).
``FtracTransformSpace`` says whether the matrices are RAS (default, for Slicer) or our LPS
numbers unchanged. No ``.seq.nrrd`` is written: Slicer reads a ``.seq.nrrd`` as a sequence of
images or of grid transforms, and its linear-transform sequence reader parses only MetaImage
headers (a ``.seq.nrrd`` of these fields loads as one transform). :func:`read_sequence_fields`
still reads either header, as PLUS writes both.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np

from ..errors import InputError
from ..fileio import atomic_file, read_text_input
from .frames import Space, check_transform_name

SequenceFormat = Literal["mha"]
PREFIX = "Seq_Frame"


@dataclass(frozen=True)
class SequenceFrame:
    """One frame of a tracked run as a sequence file stores it.

    Attributes
    ----------
    matrix : (4, 4) the transform (in the file's space), or None when the frame has no pose.
    timestamp_s : the frame's time (s).
    """

    matrix: np.ndarray | None
    timestamp_s: float


def _fmt(x: float) -> str:
    return repr(float(x)) if float(x) != 0.0 else "0"


def frame_fields(frames: list[SequenceFrame], name: str) -> list[tuple[str, str]]:
    """The per-frame (key, value) fields, in PLUS's order, for the transform ``name``.

    Parameters
    ----------
    frames : the run, in order.
    name : the PLUS transform name (``FiducialToCArm``); the fields are ``<name>Transform`` and
        ``<name>TransformStatus``.

    Returns
    -------
    list of (key, value) strings.
    """
    check_transform_name(name)
    out: list[tuple[str, str]] = []
    for k, fr in enumerate(frames):
        p = f"{PREFIX}{k:04d}_"
        ok = fr.matrix is not None and np.isfinite(fr.matrix).all()
        M = np.asarray(fr.matrix, float) if ok else np.eye(4)
        out += [
            (p + "FrameNumber", str(k)),
            (p + f"{name}Transform", " ".join(_fmt(v) for v in M.reshape(-1))),
            (p + f"{name}TransformStatus", "OK" if ok else "INVALID"),
            (p + "Timestamp", _fmt(fr.timestamp_s)),
            (p + "UnfilteredTimestamp", _fmt(fr.timestamp_s)),
            (p + "ImageStatus", "INVALID"),
        ]
    return out


def sequence_bytes(frames: list[SequenceFrame], name: str, fmt: SequenceFormat, space: Space) -> bytes:
    """The whole file (a header with no pixel data) as bytes.

    Parameters
    ----------
    frames, name : as :func:`frame_fields`.
    fmt : ``"mha"`` (the one format written).
    space : what the matrices are in (``"ras"`` or ``"lps"``), recorded in the file.
    """
    if not frames:
        raise InputError(None, None, "at least one frame", parameter="frames")
    fields = frame_fields(frames, name)
    n = len(frames)
    if fmt == "mha":
        head = [
            "ObjectType = Image",
            "NDims = 3",
            "AnatomicalOrientation = RAI",
            "BinaryData = True",
            "CompressedData = False",
            f"DimSize = 0 0 {n}",
            "ElementSpacing = 1 1 1",
            "Offset = 0 0 0",
            "TransformMatrix = 1 0 0 0 1 0 0 0 1",
            "ElementType = MET_UCHAR",
            "Kinds = domain domain list",
            f"FtracTransformSpace = {space.upper()}",
        ]
        body = [f"{k} = {v}" for k, v in fields]
        return ("\n".join(head + body + ["ElementDataFile = LOCAL"]) + "\n").encode("ascii")
    raise InputError(None, None, f'"mha", got {fmt!r}', parameter="fmt")


def write_sequence(path: str | Path, frames: list[SequenceFrame], name: str, fmt: SequenceFormat, space: Space) -> Path:
    """Write :func:`sequence_bytes` to ``path`` atomically (InputError if it cannot be written)."""
    data = sequence_bytes(frames, name, fmt, space)
    try:
        with atomic_file(path) as tmp:
            tmp.write_bytes(data)
    except OSError as exc:
        raise InputError(path, None, f"a writable output path ({exc.strerror or exc})") from None
    return Path(path)


def read_sequence_fields(path: str | Path) -> dict[str, str]:
    """The header's key → value fields of a ``.seq.mha`` or ``.seq.nrrd`` (either separator).

    Parameters
    ----------
    path : the file.

    Returns
    -------
    dict : every ``key = value`` (MetaImage) or ``key: value`` / ``key:=value`` (NRRD) line of the
    header, in order; comments and the NRRD magic skipped. InputError when unreadable.
    """
    try:
        raw = Path(path).read_bytes()
    except OSError:
        read_text_input(path)  # raises the InputError naming the problem
        raise
    nrrd = raw.startswith(b"NRRD")
    head = raw.split(b"\n\n", 1)[0] if nrrd else raw
    out: dict[str, str] = {}
    for line in head.decode("ascii", errors="replace").splitlines():
        if nrrd and (line.startswith("#") or line.startswith("NRRD")):
            continue
        sep = ":=" if nrrd and ":=" in line else (":" if nrrd else "=")
        if sep not in line:
            continue
        k, v = line.split(sep, 1)
        out[k.strip()] = v.strip()
        if not nrrd and k.strip() == "ElementDataFile":
            break
    return out
