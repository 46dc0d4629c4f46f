"""``pose.json`` (SPEC §4): one object, or JSON Lines for several, written atomically."""

from __future__ import annotations

import json
from pathlib import Path

from ..fileio import write_text_atomic
from .solver import Pose


def pose_lines(poses: list[Pose], jsonl: bool) -> str:
    """The text :func:`write_poses` writes."""
    if not jsonl:
        return json.dumps(poses[0].to_dict(), indent=2, allow_nan=False) + "\n"
    return "".join(json.dumps(p.to_dict(), allow_nan=False) + "\n" for p in poses)


def write_poses(path: str | Path, poses: list[Pose], jsonl: bool | None = None) -> Path:
    """Write ``poses`` to ``path``: a single JSON object for one pose (unless ``jsonl``),
    else one object per line. Non-finite numbers become ``null``."""
    path = Path(path)
    if jsonl is None:
        jsonl = len(poses) != 1 or path.suffix.lower() == ".jsonl"
    return write_text_atomic(path, pose_lines(poses, jsonl))
