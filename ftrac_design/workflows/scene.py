"""``ftrac-design export --scene``: a tracked run, the fiducial's features and its build's STL
gathered into one 3D Slicer scene folder (:mod:`ftrac_design.igt.scene`), written whole or not
at all.

The model is the STL ``ftrac-design build`` wrote beside ``features.json`` (``fiducial.stl``, in
the fiducial frame F; the CAD room alone makes it), or one given; the beads are the features'
points; the run is every pose with a solution, at its ``time_s`` (else its line index, s).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ..errors import InputError
from ..fileio import atomic_directory, check_output_dir
from ..igt.frames import pose_matrix
from ..igt.markups import points_from_file
from ..igt.scene import MODEL_FILE, SCENE_FILE, SceneContent, is_scene_folder, write_scene_files
from ..pose import read_tracked_poses

#: the first bytes of a binary STL hold an 80-byte header and a triangle count; an ASCII one starts so
_STL_ASCII = b"solid"


@dataclass(frozen=True)
class SceneResult:
    """What :func:`write_scene` wrote.

    Attributes
    ----------
    scene_file : the ``scene.mrml`` to open.
    frames, left_out : frames in the scene's sequence, and frames of the run without a pose.
    beads : beads in the markups.
    run_name : the sequence browser's name.
    """

    scene_file: Path
    frames: int
    left_out: int
    beads: int
    run_name: str


def _model_path(features: Path, model: Path | None) -> Path:
    """The STL to show: ``model``, else the build's ``fiducial.stl`` beside ``features``; checked
    to be an STL (InputError naming it otherwise)."""
    path = Path(model) if model is not None else Path(features).parent / MODEL_FILE
    where = "--model" if model is not None else f"beside {features} (as `ftrac-design build` writes it), or --model"
    try:
        with open(path, "rb") as fh:
            head = fh.read(84)
    except OSError as exc:
        raise InputError(path, None, f"the fiducial's STL model {where} ({exc.strerror or exc})") from None
    binary_ok = len(head) == 84 and path.stat().st_size == 84 + 50 * int.from_bytes(head[80:84], "little")
    if not (binary_ok or head.lstrip().startswith(_STL_ASCII)):
        raise InputError(path, None, f"an STL model of the fiducial ({where})")
    return path


def write_scene(run: Path, out_dir: Path, features: Path, model: Path | None, name: str) -> SceneResult:
    """Write the Slicer scene of the run ``run`` into ``out_dir`` (replaced whole on success).

    Parameters
    ----------
    run : the poses (``track``'s JSON Lines, or one pose.json): SPEC §4, F → X, LPS numbers.
    out_dir : the scene folder: new, empty, or an earlier scene (refused otherwise).
    features : the fiducial's ``features.json`` (its beads, F).
    model : the fiducial's STL in F, or None for ``fiducial.stl`` beside ``features``.
    name : the transform's PLUS name (``FiducialToCArm``).

    Returns
    -------
    SceneResult. InputError (exit 2, nothing written) for a bad run, features file or model, a
    run without any pose, or an output folder holding something else.
    """
    check_output_dir(out_dir, "an earlier scene of `export --scene`", is_scene_folder, parameter="scene")
    records = read_tracked_poses(run)
    beads, frame = points_from_file(features)
    if frame != "fiducial":
        raise InputError(features, "format", "a features.json (the beads in the fiducial frame F)")
    poses = [
        (
            r.provenance.time_s if r.provenance.time_s is not None else float(k),
            pose_matrix(r.pose.rotation, r.pose.translation_mm),
        )
        for k, r in enumerate(records)
        if r.pose.converged
    ]
    if not poses:
        raise InputError(run, None, "at least one pose with a solution (converged) to show in a scene")
    content = SceneContent(_model_path(features, model), beads, poses, name, Path(run).name.split(".")[0] or "run")
    with atomic_directory(out_dir) as tmp:
        write_scene_files(tmp, content)
    return SceneResult(Path(out_dir) / SCENE_FILE, len(poses), len(records) - len(poses), len(beads), content.run_name)
