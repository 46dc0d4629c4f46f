"""Frames and matrices: SPEC §1's F and X as PLUS names them, LPS ↔ RAS, 4×4 from a pose.

- The fiducial frame F is called ``Fiducial``, the C-arm frame X (origin at the X-ray source,
  ``+z`` toward the detector) ``CArm``. A SPEC §4 pose maps F into X, so in PLUS's
  ``<From>To<To>`` naming (the matrix maps coordinates in From into To) it is
  ``FiducialToCArm``.
- Our coordinates are LPS coordinates as far as Slicer and ITK are concerned (see the
  package); :func:`lps_to_ras` gives the same mapping for Slicer's RAS scene:
  ``M_RAS = S · M_LPS · S``, ``S = diag(-1, -1, 1, 1)`` (its own inverse).
"""

from __future__ import annotations

import re
from typing import Literal

import numpy as np

from ..errors import InputError

#: PLUS / OpenIGTLink name of SPEC §1's fiducial frame F
FIDUCIAL_FRAME = "Fiducial"
#: PLUS / OpenIGTLink name of SPEC §1's camera (C-arm) frame X
CARM_FRAME = "CArm"
#: the transform a SPEC §4 pose is: F → X
POSE_TRANSFORM = f"{FIDUCIAL_FRAME}To{CARM_FRAME}"
#: OpenIGTLink's device-name field: 20 bytes; longer names are cut by senders
MAX_NAME_BYTES = 20
#: LPS ↔ RAS: negate the first two axes (its own inverse)
LPS_RAS = np.diag([-1.0, -1.0, 1.0, 1.0])

#: which coordinates a matrix handed to Slicer is in: "ras" (Slicer's scene, our LPS numbers
#: converted) or "lps" (our numbers as they are)
Space = Literal["ras", "lps"]

_FRAME_NAME = re.compile(r"[A-Z][A-Za-z0-9]*")


def check_transform_name(name: str, parameter: str = "name") -> str:
    """``name`` if it is a PLUS transform name that fits OpenIGTLink, else InputError.

    A PLUS name is ``<From>To<To>``: two frame names, each starting upper-case, letters and
    digits only, and neither holding "To" followed by an upper-case letter (so the split is
    unambiguous); at most :data:`MAX_NAME_BYTES` ASCII bytes.

    Parameters
    ----------
    name : the transform name, e.g. ``"FiducialToCArm"``.
    parameter : the argument named in the error.

    Returns
    -------
    str : ``name``.
    """
    splits = [m.start() for m in re.finditer(r"To(?=[A-Z])", name)]
    ok = (
        name.isascii()
        and len(name) <= MAX_NAME_BYTES
        and len(splits) == 1
        and _FRAME_NAME.fullmatch(name[: splits[0]])
        and _FRAME_NAME.fullmatch(name[splits[0] + 2 :])
    )
    if not ok:
        raise InputError(
            None,
            None,
            f"a PLUS transform name <From>To<To> of at most {MAX_NAME_BYTES} ASCII "
            f"characters, each frame name starting upper-case (e.g. {POSE_TRANSFORM}); "
            f"got {name!r}",
            parameter=parameter,
        )
    return name


def split_transform_name(name: str) -> tuple[str, str]:
    """(From, To) of a PLUS transform name (checked by :func:`check_transform_name`)."""
    check_transform_name(name)
    k = re.search(r"To(?=[A-Z])", name).start()
    return name[:k], name[k + 2 :]


def pose_matrix(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """The 4×4 homogeneous ``[[R, t], [0, 1]]`` of a pose (``P_X = R P_F + t``, mm)."""
    M = np.eye(4)
    M[:3, :3] = np.asarray(R, float)
    M[:3, 3] = np.asarray(t, float)
    return M


def rigid_inverse(M: np.ndarray) -> np.ndarray:
    """The inverse of a rigid 4×4 ``[[R, t], [0, 1]]``: ``[[Rᵀ, −Rᵀ t], [0, 1]]``."""
    M = np.asarray(M, float)
    inv = np.eye(4)
    inv[:3, :3] = M[:3, :3].T
    inv[:3, 3] = -M[:3, :3].T @ M[:3, 3]
    return inv


def lps_to_ras(M: np.ndarray) -> np.ndarray:
    """The same mapping as the 4×4 ``M`` (between two LPS-labelled frames) written for RAS
    coordinates: ``S M S``, ``S = diag(-1, -1, 1, 1)``. Its own inverse operation."""
    return LPS_RAS @ np.asarray(M, float) @ LPS_RAS


def in_space(M: np.ndarray, space: Space) -> np.ndarray:
    """``M`` (our LPS numbers) for a receiver working in ``space``: RAS (:func:`lps_to_ras`)
    or LPS (unchanged)."""
    if space == "ras":
        return lps_to_ras(M)
    if space == "lps":
        return np.asarray(M, float).copy()
    raise InputError(None, None, f'"ras" or "lps", got {space!r}', parameter="space")
