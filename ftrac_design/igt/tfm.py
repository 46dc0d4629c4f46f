"""ITK text transform files (``.tfm``), the form 3D Slicer reads and writes linear transforms in.

The file holds ONE ``AffineTransform_double_3_3`` in **LPS** coordinates and in **ITK's
resampling direction**: ITK's transform maps a point of the *fixed* space to the *moving*
space, the inverse of the point mapping a pose is. For a pose ``FiducialToCArm``
(``P_X = R P_F + t``, SPEC §4) the file therefore holds ``Rᵀ`` and ``−Rᵀ t``: it maps C-arm
(X) coordinates to fiducial (F) coordinates. 3D Slicer reads such a file as a transform whose
"to parent" mapping is F → X (it inverts and converts to RAS itself), so a model of the
fiducial placed under it appears where the C-arm saw it. Every file we write says this in
its comment header.

Text form (ITK's ``TxtTransformIO``): ``#Insight Transform File V1.0``, ``#Transform 0``,
``Transform: AffineTransform_double_3_3``, ``Parameters:`` the 3×3 matrix row by row then the
translation, ``FixedParameters:`` the centre ``c``. The mapping is ``y = A (x − c) + c + T``.
We write ``c = 0``; the reader accepts any centre.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..fileio import read_text_input, write_text_atomic
from .frames import rigid_inverse, split_transform_name

MAGIC = "#Insight Transform File V1.0"
#: the transform types read: every one is ``y = A (x − c) + c + T`` with 12 parameters
AFFINE_TYPES = (
    "AffineTransform_double_3_3",
    "AffineTransform_float_3_3",
    "MatrixOffsetTransformBase_double_3_3",
    "MatrixOffsetTransformBase_float_3_3",
)


@dataclass(frozen=True)
class TfmTransform:
    """One affine transform of a ``.tfm`` file.

    Attributes
    ----------
    resampling : (4, 4) ITK's mapping as stored (fixed → moving), LPS, offset folded in.
    type_name : the file's ``Transform:`` type.
    """

    resampling: np.ndarray
    type_name: str

    @property
    def point_mapping(self) -> np.ndarray:
        """(4, 4) the inverse of :attr:`resampling`: moving → fixed, Slicer's "to parent"
        (for our files: the pose, F → X, LPS)."""
        return np.linalg.inv(self.resampling)


def _g(x: float) -> str:
    return repr(float(x)) if float(x) != 0.0 else "0"


def tfm_text(M: np.ndarray, name: str, note: str = "") -> str:
    """The ``.tfm`` text of the point mapping ``M`` (From → To, LPS, mm) named ``name``.

    Parameters
    ----------
    M : (4, 4) the point mapping, e.g. a SPEC §4 pose F → X as :func:`.frames.pose_matrix`.
    name : its PLUS name ``<From>To<To>`` (e.g. ``FiducialToCArm``), stated in the comment.
    note : one more comment line (e.g. the source file and frame), or "".

    Returns
    -------
    str : the file's text; its parameters are ``M``'s inverse (ITK's resampling direction),
    every number as Python's shortest round-tripping repr.
    """
    frm, to = split_transform_name(name)
    inv = rigid_inverse(M) if np.allclose(np.asarray(M)[3], [0, 0, 0, 1]) else np.linalg.inv(M)
    params = [*inv[:3, :3].reshape(-1), *inv[:3, 3]]
    lines = [
        MAGIC,
        f"# {name}: written by ftrac-design. Coordinates LPS (as DICOM and ITK), millimetres.",
        f"# ITK resampling direction: these parameters map a point in {to} coordinates to {frm}",
        f"# coordinates, the INVERSE of the {name} point mapping (P_{to} = R P_{frm} + t).",
        f"# 3D Slicer loads it as {name} with 'to parent' {frm} -> {to}.",
    ]
    if note:
        lines.append("# " + " ".join(note.split()))
    lines += [
        "#Transform 0",
        "Transform: AffineTransform_double_3_3",
        "Parameters: " + " ".join(_g(p) for p in params),
        "FixedParameters: 0 0 0",
    ]
    return "\n".join(lines) + "\n"


def write_tfm(path: str | Path, M: np.ndarray, name: str, note: str = "") -> Path:
    """Write :func:`tfm_text` to ``path`` atomically (InputError if it cannot be written)."""
    try:
        return write_text_atomic(path, tfm_text(M, name, note))
    except OSError as exc:
        raise InputError(path, None, f"a writable output path ({exc.strerror or exc})") from None


def _numbers(value: str, n: int, path: str | Path, key: str) -> np.ndarray:
    try:
        vals = np.array([float(v) for v in value.split()])
    except ValueError:
        raise InputError(path, key, f"{n} numbers, got {value.strip()[:40]!r}") from None
    if vals.size != n or not np.isfinite(vals).all():
        raise InputError(path, key, f"{n} finite numbers, got {vals.size}")
    return vals


def read_tfm(path: str | Path) -> TfmTransform:
    """Read a ``.tfm`` file holding one affine transform.

    Parameters
    ----------
    path : the file.

    Returns
    -------
    TfmTransform : ITK's mapping as stored and, as its inverse, the point mapping. InputError
    for anything else (no magic line, another transform type, several transforms, bad numbers,
    a singular matrix).
    """
    text = read_text_input(path)
    lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
    if not lines or lines[0] != MAGIC:
        raise InputError(path, None, f"an ITK text transform file starting with {MAGIC!r}")
    fields: dict[str, list[str]] = {}
    for ln in lines[1:]:
        if ln.startswith("#") or ":" not in ln:
            continue
        key, value = ln.split(":", 1)
        fields.setdefault(key.strip(), []).append(value.strip())
    kinds = fields.get("Transform", [])
    if len(kinds) != 1:
        raise InputError(path, "Transform", f"exactly one transform, got {len(kinds)}")
    if kinds[0] not in AFFINE_TYPES:
        raise InputError(path, "Transform", f"one of {', '.join(AFFINE_TYPES)}; got {kinds[0]!r}")
    for key in ("Parameters", "FixedParameters"):
        if len(fields.get(key, [])) != 1:
            raise InputError(path, key, "one line of numbers (the key is required)")
    p = _numbers(fields["Parameters"][0], 12, path, "Parameters")
    c = _numbers(fields["FixedParameters"][0], 3, path, "FixedParameters")
    A = p[:9].reshape(3, 3)
    if abs(np.linalg.det(A)) < 1e-12:
        raise InputError(path, "Parameters", "an invertible 3x3 matrix")
    M = np.eye(4)
    M[:3, :3] = A
    M[:3, 3] = p[9:] + c - A @ c
    return TfmTransform(M, kinds[0])
