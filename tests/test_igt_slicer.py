"""3D Slicer reads what ``ftrac-design export`` writes, with Slicer's own readers: the MRML storage
nodes of ``slicer-core`` (Slicer 5.13's MRML libraries, no GUI), on a 14-frame run tracked from
rendered images, comparing every number.

- ``.tfm`` — ``vtkMRMLTransformStorageNode``: the "to parent" matrix is the pose, in RAS;
- ``.seq.mha`` — ``vtkMRMLLinearTransformSequenceStorageNode``: 14 transforms, the pose's RAS
  matrix for each tracked frame, the identity for the lost one, indexed by time (1 ms);
- ``.mrk.json`` — ``vtkMRMLMarkupsJsonStorageNode``: every bead (and reconstructed point) with
  its label at its RAS position;
- ``.seq.nrrd`` — refused (Slicer's linear-transform sequence reader parses MetaImage headers
  only: such a file loaded as 1 transform of 14);
- the scene of ``export --scene`` — imported by ``vtkMRMLScene`` with the node classes Slicer's
  Markups and Sequences modules register: the model (the build's STL, LPS) and the beads under
  ``FiducialToCArm``, the sequence and its browser, and, as the browser steps through the run,
  every bead where the C-arm saw it.
"""

from __future__ import annotations

import json
import struct

import numpy as np
import pytest
from scipy.spatial import cKDTree

from ftrac_design.cli.main import main
from ftrac_design.igt.frames import LPS_RAS, in_space, pose_matrix

slicer = pytest.importorskip("slicer")
vtk = pytest.importorskip("vtk")

N_FRAMES = 14


def _matrix(node) -> np.ndarray:
    m = vtk.vtkMatrix4x4()
    node.GetMatrixTransformToParent(m)
    return np.array([[m.GetElement(i, j) for j in range(4)] for i in range(4)])


def _ras(M: np.ndarray) -> np.ndarray:
    return in_space(np.asarray(M, float), "ras")


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """A 14-frame run tracked by ``track`` from rendered ftrac_2005 images (one made blank, so one
    frame has no pose), with ``time_s`` put on each line as a C-arm's frame time would."""
    from igt_support import rendered_frames

    d = tmp_path_factory.mktemp("slicer")
    fr = rendered_frames(d, N_FRAMES)
    pixels = fr.pixels.copy()
    pixels[5] = 30000  # nothing to see: that frame is lost
    np.save(d / "run.npy", pixels)
    args = ["track", "--features", str(fr.features_path), str(d / "run.npy"), "--camera", str(fr.camera_path)]
    assert main([*args, "--independent", "-o", str(d / "tracked.jsonl")]) in (0, 1)
    poses = [json.loads(x) for x in (d / "tracked.jsonl").read_text().splitlines()]
    for k, p in enumerate(poses):
        p["time_s"] = k / 7.5  # 7.5 frames/s
    (d / "run.jsonl").write_text("".join(json.dumps(p) + "\n" for p in poses))
    assert [p["converged"] for p in poses].count(False) == 1 and not poses[5]["converged"]
    return d, fr, poses


def test_slicer_reads_the_tfm_as_the_pose_in_ras(run, tmp_path):
    d, _, poses = run
    worst = 0.0
    for k in (0, 7, 13):
        assert main(["export", str(d / "run.jsonl"), "--index", str(k), "-o", str(tmp_path / f"p{k}.tfm")]) == 0
        scene = slicer.vtkMRMLScene()
        node = scene.AddNewNodeByClass("vtkMRMLLinearTransformNode")
        storage = scene.AddNewNodeByClass("vtkMRMLTransformStorageNode")
        storage.SetFileName(str(tmp_path / f"p{k}.tfm"))
        assert storage.ReadData(node) == 1
        want = _ras(pose_matrix(poses[k]["rotation"], poses[k]["translation_mm"]))
        worst = max(worst, float(np.abs(_matrix(node) - want).max()))
    assert worst < 1e-9  # Slicer inverts ITK's resampling direction itself: round-off only


def test_slicer_reads_the_seq_mha_as_14_transforms_with_their_times(run, tmp_path):
    d, _, poses = run
    assert main(["export", str(d / "run.jsonl"), "-o", str(tmp_path / "run.seq.mha")]) == 0
    scene = slicer.vtkMRMLScene()
    seq = scene.AddNewNodeByClass("vtkMRMLSequenceNode")
    storage = scene.AddNewNodeByClass("vtkMRMLLinearTransformSequenceStorageNode")
    storage.SetFileName(str(tmp_path / "run.seq.mha"))
    assert storage.ReadData(seq) == 1
    assert seq.GetNumberOfDataNodes() == N_FRAMES
    assert (seq.GetIndexName(), seq.GetIndexUnit(), seq.GetAttribute("Sequences.Source")) == (
        "time",
        "s",
        "FiducialToCArm",
    )
    for k, p in enumerate(poses):
        assert seq.GetNthIndexValue(k) == f"{p['time_s']:.3f}"
        got = _matrix(seq.GetNthDataNode(k))
        want = _ras(pose_matrix(p["rotation"], p["translation_mm"])) if p["converged"] else np.eye(4)
        assert np.array_equal(got, want)  # the file's shortest round-trip decimals: exact


def test_slicer_reads_the_markups_with_labels_at_their_ras_positions(run, tmp_path):
    d, fr, _ = run
    features = json.loads(fr.features_path.read_text())
    recon = {
        "format": "ftrac-reconstruction",
        "frame": "template",
        "points": {
            "S1": {"position_mm": [1.5, -2.25, 30.0]},
            "S2": {"position_mm": None},
            "S3": {"position_mm": [0, 0, 1]},
        },
    }
    (tmp_path / "recon.json").write_text(json.dumps(recon))
    cases = {
        "beads": (fr.features_path, [(b["id"], b["center"]) for b in features["points"]]),
        "recon": (tmp_path / "recon.json", [("S1", [1.5, -2.25, 30.0]), ("S3", [0, 0, 1])]),
    }
    for name, (src, want) in cases.items():
        out = tmp_path / f"{name}.mrk.json"
        assert main(["export", str(src), "-o", str(out)]) == 0
        scene = slicer.vtkMRMLScene()
        scene.RegisterNodeClass(slicer.vtkMRMLMarkupsJsonStorageNode())  # as the Markups module does
        node = scene.AddNewNodeByClass("vtkMRMLMarkupsFiducialNode")
        storage = scene.AddNewNodeByClass("vtkMRMLMarkupsJsonStorageNode")
        storage.SetFileName(str(out))
        assert storage.ReadData(node) == 1
        assert node.GetNumberOfControlPoints() == len(want)
        for i, (label, lps) in enumerate(want):
            pos = [0.0, 0.0, 0.0]
            node.GetNthControlPointPosition(i, pos)
            assert node.GetNthControlPointLabel(i) == label
            # the same doubles but for Slicer's JSON parsing (an ulp or so)
            assert np.abs(np.array(pos) - [-float(lps[0]), -float(lps[1]), float(lps[2])]).max() < 1e-12


def test_a_seq_nrrd_is_refused_with_the_reason_and_nothing_written(run, tmp_path, capsys):
    d, _, _ = run
    assert main(["export", str(d / "run.jsonl"), "-o", str(tmp_path / "run.seq.nrrd")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "run.seq.nrrd" in err and ".seq.mha" in err and "Traceback" not in err
    assert list(tmp_path.iterdir()) == []


def _stl_vertices(path) -> np.ndarray:
    data = path.read_bytes()
    n = struct.unpack("<I", data[80:84])[0]
    tri = np.frombuffer(data[84 : 84 + 50 * n], dtype=np.dtype([("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")]))
    return np.unique(tri["v"].reshape(-1, 3), axis=0)


def _import(scene_file):
    """The scene as 3D Slicer imports it: the MRML read by ``vtkMRMLScene`` with the node classes
    the Markups and Sequences modules register, every storage node reading its file."""
    scene = slicer.vtkMRMLScene()
    scene.RegisterNodeClass(slicer.vtkMRMLMarkupsJsonStorageNode())
    sequences = slicer.vtkSlicerSequencesLogic()
    sequences.SetMRMLScene(scene)  # registers the sequence browser node, as the module does
    scene.SetURL(str(scene_file))
    assert scene.Connect() == 1
    return scene, sequences


def _only(scene, cls):
    nodes = scene.GetNodesByClass(cls)
    assert nodes.GetNumberOfItems() == 1, cls
    return nodes.GetItemAsObject(0)


@pytest.mark.slow
def test_the_scene_shows_the_fiducial_moving_in_the_carm_frame(run, tmp_path):
    pytest.importorskip("cadquery")
    from cad_support import build

    d, fr, poses = run
    built = build("ftrac_2005").out_dir
    out = tmp_path / "scene"
    assert main(["export", str(d / "run.jsonl"), "--scene", str(out), "--features", str(built / "features.json")]) == 0
    scene, sequences = _import(out / "scene.mrml")
    tf = _only(scene, "vtkMRMLLinearTransformNode")
    model, beads = _only(scene, "vtkMRMLModelNode"), _only(scene, "vtkMRMLMarkupsFiducialNode")
    seq, browser = _only(scene, "vtkMRMLSequenceNode"), _only(scene, "vtkMRMLSequenceBrowserNode")
    assert tf.GetName() == "FiducialToCArm"
    assert model.GetTransformNodeID() == beads.GetTransformNodeID() == tf.GetID()
    assert browser.GetMasterSequenceNode().GetID() == seq.GetID() and browser.GetProxyNode(seq).GetID() == tf.GetID()
    # the model: the build's STL, read as LPS (its points in RAS are the STL's with x, y negated)
    pts = np.array([model.GetPolyData().GetPoint(i) for i in range(model.GetPolyData().GetNumberOfPoints())])
    stl = _stl_vertices(built / "fiducial.stl")
    back = (pts * [-1, -1, 1]).astype(np.float32)
    assert len(np.unique(back, axis=0)) == len(stl)
    assert cKDTree(stl).query(back)[0].max() == 0.0  # every point of Slicer's model is a vertex of the STL
    # the beads, in F
    f = json.loads((built / "features.json").read_text())
    centres = np.array([b["center"] for b in f["points"]])
    assert beads.GetNumberOfControlPoints() == len(centres)
    # the run: the 13 frames with a pose, at their times; stepping the browser moves every bead to R c + t
    tracked = [p for p in poses if p["converged"]]
    assert seq.GetNumberOfDataNodes() == len(tracked) == N_FRAMES - 1
    worst = 0.0
    for k, p in enumerate(tracked):
        assert seq.GetNthIndexValue(k) == f"{p['time_s']:.3f}"
        browser.SetSelectedItemNumber(k)
        sequences.UpdateProxyNodesFromSequences(browser)
        to_world = vtk.vtkMatrix4x4()
        tf.GetMatrixTransformToWorld(to_world)
        W = np.array([[to_world.GetElement(i, j) for j in range(4)] for i in range(4)])
        R, t = np.array(p["rotation"]), np.array(p["translation_mm"])
        for i, c in enumerate(centres):
            local = [0.0, 0.0, 0.0]
            beads.GetNthControlPointPosition(i, local)
            world_ras = W @ [*local, 1.0]
            want_lps = R @ c + t  # where the C-arm saw bead i (SPEC §4), in X read as LPS
            worst = max(worst, float(np.abs((LPS_RAS @ world_ras)[:3] - want_lps).max()))
    assert worst < 1e-9
