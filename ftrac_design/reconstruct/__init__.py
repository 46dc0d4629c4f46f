"""3-D reconstruction from several tracked images, frames F → T → U, and the C-arm's intrinsics.

- :mod:`.triangulate` — ML triangulation with covariance from pixel noise and pose covariance.
- :mod:`.frames` — points with covariances through rigid (possibly uncertain) transforms.
- :mod:`.io`, :mod:`.pipeline` — the ``ftrac-design reconstruct`` files and their pairing.
- :mod:`.intrinsics` — what one image / several images of the fiducial tell about
  ``(fx, fy, ox, oy)``: Cramér–Rao bounds and joint estimation with shared intrinsics.

numpy/scipy only.
"""

from __future__ import annotations

from .frames import RigidTransform
from .triangulate import MIN_PARALLAX_DEG, Triangulation, Views, triangulate

__all__ = ["MIN_PARALLAX_DEG", "RigidTransform", "Triangulation", "Views", "triangulate"]
