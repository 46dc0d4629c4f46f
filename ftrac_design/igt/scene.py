"""A 3D Slicer scene of a tracked run: the fiducial's model moving in the C-arm frame.

The scene is a folder: ``scene.mrml`` (MRML, Slicer's XML scene) and the files it names, each in
a format Slicer's own storage nodes read:

- ``fiducial.stl`` — the fiducial's model in F (as ``ftrac-design build`` writes it), its
  triangles unchanged and its header saying ``SPACE=LPS``, so ``vtkMRMLModelStorageNode`` reads it
  as **LPS** like all our numbers (Slicer takes the coordinate system from a model file's header
  first; a scene's ``coordinateSystem`` attribute alone is overridden for scenes of older
  versions);
- ``beads.mrk.json`` — the beads' centres in F as a point list (``vtkMRMLMarkupsJsonStorageNode``,
  LPS, :mod:`.markups`);
- ``run.seq.mha`` — the run's poses as a linear-transform sequence
  (``vtkMRMLLinearTransformSequenceStorageNode``, RAS "to parent" matrices, :mod:`.sequence`),
  indexed by time (s); only the frames with a pose (a frame without one would show the fiducial
  at the X-ray source).

and, in the MRML: a linear transform ``FiducialToCArm`` (the poses' PLUS name) holding the first
frame's pose, the model and the markups under it (so both move with it), the sequence node, and a
sequence browser whose proxy node for the sequence is that transform: opening the scene and
playing the browser moves the fiducial through the run in the C-arm frame X (origin at the X-ray
source, ``+z`` toward the detector, read as LPS).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

from ..errors import InputError
from .frames import check_transform_name, lps_to_ras
from .markups import markups_dict
from .sequence import SequenceFrame, sequence_bytes

#: the scene's file names inside its folder
SCENE_FILE = "scene.mrml"
MODEL_FILE = "fiducial.stl"
BEADS_FILE = "beads.mrk.json"
SEQUENCE_FILE = "run.seq.mha"
#: written into every scene we write, so a later export may replace the folder
MARKER = "written by ftrac-design export --scene"


@dataclass(frozen=True)
class SceneContent:
    """What a scene holds.

    Attributes
    ----------
    model_stl : the fiducial's STL (F, mm), copied into the scene.
    beads : (label, (3,) centre in F, mm) of each bead.
    poses : (timestamp s, (4, 4) pose F → X in our LPS numbers) of each frame with a pose, in order.
    name : the transform's PLUS name (``FiducialToCArm``).
    run_name : the sequence browser's name (the run's file stem).
    """

    model_stl: Path
    beads: list[tuple[str, np.ndarray]]
    poses: list[tuple[float, np.ndarray]]
    name: str
    run_name: str


def stl_in_lps(data: bytes) -> bytes:
    """The STL ``data`` with its header saying ``SPACE=LPS`` (Slicer's convention, read from a
    binary STL's 80-byte header or an ASCII STL's ``solid`` line); the triangles are untouched."""
    if data.lstrip().startswith(b"solid"):
        first, _, rest = data.partition(b"\n")
        return first.rstrip(b"\r") + b" SPACE=LPS\n" + rest
    header = b"SPACE=LPS; fiducial frame F, mm; " + data[:80].rstrip(b"\0 ")
    return header[:80].ljust(80, b"\0") + data[80:]


def _matrix_text(M: np.ndarray) -> str:
    return "  ".join(" ".join(repr(float(v)) for v in row) for row in np.asarray(M, float))


def _node(tag: str, attrs: dict[str, str]) -> str:
    body = " ".join(f"{k}={quoteattr(v)}" for k, v in attrs.items())
    return f" <{tag}\n  {body}></{tag}>"


def scene_nodes(content: SceneContent) -> list[str]:
    """The MRML elements of the scene, one string each (see the module)."""
    tf, first = "vtkMRMLLinearTransformNode1", lps_to_ras(content.poses[0][1])
    seq, browser = "vtkMRMLSequenceNode1", "vtkMRMLSequenceBrowserNode1"
    return [
        _node(
            "LinearTransform",
            {
                "id": tf,
                "name": content.name,
                "description": f"{MARKER}: the pose of the fiducial frame F in the C-arm frame X",
                "matrixTransformToParent": _matrix_text(first),
            },
        ),
        _node(
            "Model",
            {
                "id": "vtkMRMLModelNode1",
                "name": "Fiducial",
                "references": f"display:vtkMRMLModelDisplayNode1;storage:vtkMRMLModelStorageNode1;transform:{tf};",
            },
        ),
        _node("ModelStorage", {"id": "vtkMRMLModelStorageNode1", "fileName": MODEL_FILE, "coordinateSystem": "LPS"}),
        _node("ModelDisplay", {"id": "vtkMRMLModelDisplayNode1", "color": "0.93 0.92 0.88", "visibility": "true"}),
        _node(
            "MarkupsFiducial",
            {
                "id": "vtkMRMLMarkupsFiducialNode1",
                "name": "Beads",
                "locked": "true",
                "references": "display:vtkMRMLMarkupsFiducialDisplayNode1;"
                f"storage:vtkMRMLMarkupsJsonStorageNode1;transform:{tf};",
            },
        ),
        _node("MarkupsFiducialDisplay", {"id": "vtkMRMLMarkupsFiducialDisplayNode1", "color": "0.25 0.35 0.75"}),
        _node("MarkupsJsonStorage", {"id": "vtkMRMLMarkupsJsonStorageNode1", "fileName": BEADS_FILE}),
        _node(
            "Sequence",
            {
                "id": seq,
                "name": f"{content.name}-Seq",
                "references": "storage:vtkMRMLLinearTransformSequenceStorageNode1;",
                "indexName": "time",
                "indexUnit": "s",
                "indexType": "numeric",
            },
        ),
        _node(
            "LinearTransformSequenceStorage",
            {"id": "vtkMRMLLinearTransformSequenceStorageNode1", "fileName": SEQUENCE_FILE},
        ),
        _node(
            "SequenceBrowser",
            {
                "id": browser,
                "name": content.run_name,
                "references": f"dataNodeRef0:{tf};sequenceNodeRef0:{seq};",
                "virtualNodePostfixes": "0",
                "playbackRateFps": "10",
                "playbackLooped": "true",
                "selectedItemNumber": "0",
                "indexDisplayMode": "[indexValue]",
                "indexDisplayFormat": "%.3f",
                "SynchronizationPropertiesMap0": "playback true recording false overwriteProxyName false "
                "saveChanges false missingItemMode createFromPrevious",
            },
        ),
    ]


def scene_xml(content: SceneContent) -> str:
    """The ``scene.mrml`` text: the nodes of :func:`scene_nodes` in an MRML document."""
    return "\n".join(
        [
            '<?xml version="1.0" encoding="UTF-8"?>',
            # the oldest Slicer that reads every node here (markups JSON, sequence browsers)
            '<MRML version="Slicer4.11.0">',
            *scene_nodes(content),
            "</MRML>",
            "",
        ]
    )


def write_scene_files(folder: Path, content: SceneContent) -> list[Path]:
    """Write the scene's files into the existing ``folder`` (the caller makes it atomic).

    Parameters
    ----------
    folder : where the files go.
    content : the model, beads and poses (see :class:`SceneContent`).

    Returns
    -------
    list of Path : the files written, ``scene.mrml`` first. InputError when there is no pose to
    show, no bead, or the STL cannot be read.
    """
    check_transform_name(content.name)
    if not content.poses:
        raise InputError(None, None, "at least one frame with a pose for a scene", parameter="input")
    if not content.beads:
        raise InputError(None, None, "a features file with at least one bead", parameter="features")
    try:
        (folder / MODEL_FILE).write_bytes(stl_in_lps(Path(content.model_stl).read_bytes()))
    except OSError as exc:
        raise InputError(content.model_stl, None, f"a readable STL model ({exc.strerror or exc})") from None

    (folder / BEADS_FILE).write_text(
        json.dumps(markups_dict(content.beads, "Beads", "fiducial frame F, LPS mm"), indent=2, allow_nan=False) + "\n",
        encoding="utf-8",
    )
    frames = [SequenceFrame(lps_to_ras(M), t) for t, M in content.poses]
    (folder / SEQUENCE_FILE).write_bytes(sequence_bytes(frames, content.name, "mha", "ras"))
    (folder / SCENE_FILE).write_text(scene_xml(content), encoding="utf-8")
    return [folder / f for f in (SCENE_FILE, MODEL_FILE, BEADS_FILE, SEQUENCE_FILE)]


def is_scene_folder(folder: Path) -> bool:
    """Whether ``folder`` holds a scene we wrote (so a new export may replace it whole)."""
    try:
        return MARKER in (Path(folder) / SCENE_FILE).read_text(encoding="utf-8")[:2000]
    except (OSError, UnicodeDecodeError):
        return False
