"""``pose.json`` (SPEC §4): one object, or JSON Lines for several, written atomically (each
object :meth:`.record.TrackedPose.to_dict`)."""

from __future__ import annotations

import json
from pathlib import Path

from ..fileio import write_text_atomic
from .record import Pose, TrackedPose


def pose_text(pose: Pose | TrackedPose, jsonl: bool) -> str:
    """One pose as written: a line of JSON Lines (``jsonl``), or an indented ``pose.json``;
    newline-terminated, strict JSON (a non-finite number is ``null``)."""
    d = pose.to_dict()
    return (json.dumps(d, allow_nan=False) if jsonl else json.dumps(d, indent=2, allow_nan=False)) + "\n"


def pose_lines(poses: list[Pose | TrackedPose], jsonl: bool) -> str:
    """The text :func:`write_poses` writes."""
    if not jsonl:
        return pose_text(poses[0], False)
    return "".join(pose_text(p, True) for p in poses)


def write_poses(path: str | Path, poses: list[Pose | TrackedPose], jsonl: bool | None = None) -> Path:
    """Write ``poses`` to ``path``: a single JSON object for one pose (unless ``jsonl``),
    else one object per line. Non-finite numbers become ``null``."""
    path = Path(path)
    if jsonl is None:
        jsonl = len(poses) != 1 or path.suffix.lower() == ".jsonl"
    return write_text_atomic(path, pose_lines(poses, jsonl))
