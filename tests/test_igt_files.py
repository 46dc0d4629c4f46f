"""The exports 3D Slicer, ITK and PLUS read: ``.tfm`` read back by ITK itself (SimpleITK) gives
the matrix written, in LPS and ITK's resampling direction, checked on poses whose answer is
known by hand; markups round trip in LPS; sequence headers read back by field (3D Slicer's own
readers: test_igt_slicer.py); ``ftrac-design export`` (and ``--scene``) refuses bad input with
one line and writes nothing."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import SimpleITK as sitk

from ftrac_design.cli.main import main
from ftrac_design.errors import InputError
from ftrac_design.features import write_features
from ftrac_design.igt.frames import (
    LPS_RAS,
    check_transform_name,
    in_space,
    pose_matrix,
    rigid_inverse,
    split_transform_name,
)
from ftrac_design.igt.markups import read_markups, write_markups
from ftrac_design.igt.sequence import SequenceFrame, read_sequence_fields, write_sequence
from ftrac_design.igt.tfm import read_tfm, tfm_text, write_tfm
from ftrac_design.pose import read_tracked_poses, so3

RZ90 = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
RX90 = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


def _pose(R, t, **kw) -> dict:
    return {
        "format": "ftrac-pose",
        "version": 1,
        "rotation": np.asarray(R).tolist(),
        "translation_mm": list(map(float, t)),
        "converged": True,
        "rms_residual_px": 0.1,
        "covariance": (np.eye(6) * 1e-4).tolist(),
        **kw,
    }


def _random_pose(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return pose_matrix(so3.exp(rng.normal(size=3)), rng.normal(size=3) * 50 + [0, 0, 667])


def test_tfm_of_a_pose_known_by_hand_holds_its_inverse_in_lps(tmp_path):
    # F → X: a quarter turn about z then (10, 20, 600): the fiducial's (1, 0, 0) lands at (10, 21, 600)
    M = pose_matrix(RZ90, [10.0, 20.0, 600.0])
    path = write_tfm(tmp_path / "pose.tfm", M, "FiducialToCArm")
    text = path.read_text()
    assert text.startswith("#Insight Transform File V1.0\n") and "LPS" in text and "INVERSE" in text
    # ITK's resampling direction, written out by hand: Rᵀ row by row, then −Rᵀ t
    params = [float(v) for v in next(ln for ln in text.splitlines() if ln.startswith("Parameters:")).split()[1:]]
    assert params == [0, 1, 0, -1, 0, 0, 0, 0, 1, -20, 10, -600]
    # ITK itself reads the same twelve numbers and maps the C-arm point back onto the fiducial's
    tx = sitk.ReadTransform(str(path))
    assert list(tx.GetParameters()) == params and list(tx.GetFixedParameters()) == [0, 0, 0]
    assert np.allclose(tx.TransformPoint((10.0, 21.0, 600.0)), (1.0, 0.0, 0.0), atol=1e-12)
    # our reader inverts it back to the pose
    assert np.array_equal(read_tfm(path).point_mapping, M)


@pytest.mark.parametrize(
    "R, t, ras_R, ras_t",
    [
        # about z (the axis LPS and RAS share) the rotation is the same; the translation's x, y flip
        (RZ90, [10.0, 20.0, 600.0], RZ90, [-10.0, -20.0, 600.0]),
        # +90° about L (LPS x) is −90° about R (RAS x)
        (RX90, [0.0, 0.0, 0.0], RX90.T, [0.0, 0.0, 0.0]),
    ],
)
def test_ras_matrix_of_a_pose_known_by_hand(R, t, ras_R, ras_t):
    M = in_space(pose_matrix(R, t), "ras")
    assert np.array_equal(M[:3, :3], np.asarray(ras_R)) and np.array_equal(M[:3, 3], ras_t)
    assert np.array_equal(in_space(pose_matrix(R, t), "lps"), pose_matrix(R, t))


@pytest.mark.parametrize("seed", range(4))
def test_itk_reads_back_any_pose_and_slicers_ras_to_parent_is_the_openigtlink_matrix(seed, tmp_path):
    M = _random_pose(seed)
    path = write_tfm(tmp_path / "p.tfm", M, "FiducialToCArm", note="frame 3 of run.jsonl")
    tx = sitk.ReadTransform(str(path))
    A = np.array(tx.GetParameters()[:9]).reshape(3, 3)
    assert np.array_equal(A, M[:3, :3].T) and np.allclose(
        tx.GetParameters()[9:], -M[:3, :3].T @ M[:3, 3], rtol=0, atol=1e-12
    )
    # every point: ITK maps X → F, the pose maps F → X
    P = np.random.default_rng(seed).normal(size=(5, 3)) * 40
    X = P @ M[:3, :3].T + M[:3, 3]
    assert np.allclose([tx.TransformPoint(tuple(x)) for x in X], P, rtol=0, atol=1e-9)
    # Slicer's "to parent" in RAS: S · inverse(file) · S, the matrix `serve` sends by default
    slicer = LPS_RAS @ np.linalg.inv(read_tfm(path).resampling) @ LPS_RAS
    assert np.allclose(slicer, in_space(M, "ras"), rtol=0, atol=1e-12)


def test_tfm_reader_takes_a_centre_and_refuses_what_is_not_one_affine(tmp_path):
    # ITK's own writer with a centre of rotation: y = A (x − c) + c + T
    tx = sitk.AffineTransform(3)
    tx.SetMatrix(RZ90.reshape(-1).tolist())
    tx.SetTranslation((1.0, 2.0, 3.0))
    tx.SetCenter((5.0, -4.0, 7.0))
    sitk.WriteTransform(tx, str(tmp_path / "itk.tfm"))
    ours = read_tfm(tmp_path / "itk.tfm").resampling
    x = np.array([3.0, 1.0, -2.0])
    assert np.allclose(ours[:3, :3] @ x + ours[:3, 3], tx.TransformPoint(tuple(x)), rtol=0, atol=1e-12)
    good = tfm_text(np.eye(4), "FiducialToCArm")
    for bad, key in [
        ("no magic\n", None),
        (good.replace("AffineTransform_double_3_3", "BSplineTransform"), "Transform"),
        (good.replace("FixedParameters: 0 0 0", "FixedParameters: 0 0"), "FixedParameters"),
        (good.replace("Parameters: ", "Parameters: x "), "Parameters"),
        (good + good.split("#Transform 0\n")[1], "Transform"),
    ]:
        (tmp_path / "bad.tfm").write_text(bad)
        with pytest.raises(InputError) as e:
            read_tfm(tmp_path / "bad.tfm")
        assert e.value.key == key


def test_plus_transform_names():
    assert split_transform_name("FiducialToCArm") == ("Fiducial", "CArm")
    assert check_transform_name("ImageToProbe") == "ImageToProbe"
    for bad in (
        "fiducialToCArm",
        "Fiducial2CArm",
        "FiducialToCArmToTracker",
        "VeryLongFiducialToCArm",
        "ToCArm",
        "FiducialTo",
    ):
        with pytest.raises(InputError):
            check_transform_name(bad)


def test_rigid_inverse():
    M = _random_pose(7)
    assert np.allclose(rigid_inverse(M) @ M, np.eye(4), rtol=0, atol=1e-12)


def test_markups_round_trip_in_lps_and_a_ras_file_is_converted(tmp_path):
    pts = [("B1", np.array([1.5, -2.25, 30.0])), ("seed 7", np.array([-0.1, 0.2, 1e-3]))]
    path = write_markups(tmp_path / "p.mrk.json", pts, "reconstruction", "fiducial frame")
    d = json.loads(path.read_text())
    assert d["markups"][0]["coordinateSystem"] == "LPS" and d["markups"][0]["type"] == "Fiducial"
    back = read_markups(path)
    assert [k for k, _ in back] == ["B1", "seed 7"] and all(np.array_equal(a, b) for (_, a), (_, b) in zip(back, pts))
    d["markups"][0]["coordinateSystem"] = "RAS"
    (tmp_path / "ras.mrk.json").write_text(json.dumps(d))
    assert np.array_equal(read_markups(tmp_path / "ras.mrk.json")[0][1], [-1.5, 2.25, 30.0])


def test_export_markups_of_a_features_file_and_of_a_reconstruction(features_2005, tmp_path, capsys):
    fpath = write_features(tmp_path / "f.json", features_2005)
    assert main(["export", str(fpath), "-o", str(tmp_path / "beads.mrk.json")]) == 0
    back = dict(read_markups(tmp_path / "beads.mrk.json"))
    assert set(back) == {p.id for p in features_2005.points}
    for p in features_2005.points:
        assert np.array_equal(back[p.id], p.center)
    rec = {
        "format": "ftrac-reconstruction",
        "version": 1,
        "frame": "template",
        "points": {"s1": {"position_mm": [1.0, 2.0, 3.0]}, "s2": {"refused": "one view", "views": [0]}},
    }
    (tmp_path / "rec.json").write_text(json.dumps(rec))
    assert main(["export", str(tmp_path / "rec.json"), "-o", str(tmp_path / "rec.mrk.json")]) == 0
    assert [(k, v.tolist()) for k, v in read_markups(tmp_path / "rec.mrk.json")] == [("s1", [1.0, 2.0, 3.0])]


@pytest.fixture()
def run_file(tmp_path) -> tuple[Path, list[np.ndarray]]:
    """A three-frame run with its middle frame lost."""
    Ms = [_random_pose(s) for s in (1, 2, 3)]
    lines = [
        _pose(Ms[0][:3, :3], Ms[0][:3, 3], frame=0, time_s=0.0, status="tracked"),
        {
            "format": "ftrac-pose",
            "version": 1,
            "rotation": None,
            "translation_mm": None,
            "converged": False,
            "error": "no fiducial",
            "frame": 1,
            "time_s": 0.04,
            "status": "lost",
        },
        _pose(Ms[2][:3, :3], Ms[2][:3, 3], frame=2, time_s=0.08, status="tracked"),
    ]
    p = tmp_path / "run.jsonl"
    p.write_text("".join(json.dumps(d) + "\n" for d in lines))
    return p, Ms


def _matrix_field(v: str) -> np.ndarray:
    return np.array([float(x) for x in v.split()]).reshape(4, 4)


@pytest.mark.parametrize("space", ["ras", "lps"])
def test_sequence_header_fields(run_file, space, tmp_path, capsys):
    path, Ms = run_file
    out = tmp_path / "run.seq.mha"
    assert main(["export", str(path), "-o", str(out), "--space", space]) == 0
    f = read_sequence_fields(out)
    for k, M in ((0, Ms[0]), (2, Ms[2])):
        assert np.array_equal(_matrix_field(f[f"Seq_Frame{k:04d}_FiducialToCArmTransform"]), in_space(M, space))
        assert f[f"Seq_Frame{k:04d}_FiducialToCArmTransformStatus"] == "OK"
    assert f["Seq_Frame0001_FiducialToCArmTransformStatus"] == "INVALID"
    assert np.array_equal(_matrix_field(f["Seq_Frame0001_FiducialToCArmTransform"]), np.eye(4))
    assert [float(f[f"Seq_Frame{k:04d}_Timestamp"]) for k in range(3)] == [0.0, 0.04, 0.08]
    assert f["FtracTransformSpace"] == space.upper()
    assert f["DimSize"] == "0 0 3" and out.read_text().rstrip().endswith("ElementDataFile = LOCAL")


def test_sequence_without_times_uses_the_line_index(tmp_path):
    out = write_sequence(
        tmp_path / "s.seq.mha",
        [SequenceFrame(np.eye(4), 0.0), SequenceFrame(None, 1.0)],
        "FiducialToCArm",
        "mha",
        "ras",
    )
    f = read_sequence_fields(out)
    assert f["Seq_Frame0001_Timestamp"] == "1.0" and f["Seq_Frame0001_FiducialToCArmTransformStatus"] == "INVALID"


def test_export_tfm_from_a_run_needs_index_and_a_solved_pose(run_file, tmp_path, capsys):
    path, Ms = run_file
    assert main(["export", str(path), "--index", "2", "-o", str(tmp_path / "p.tfm")]) == 0
    assert np.allclose(read_tfm(tmp_path / "p.tfm").point_mapping, Ms[2], rtol=0, atol=1e-12)
    capsys.readouterr()
    for args, words in [([], "--index"), (["--index", "1"], "converged"), (["--index", "9"], "--index")]:
        out = tmp_path / "q.tfm"
        assert main(["export", str(path), "-o", str(out), *args]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and words in err and "Traceback" not in err and not out.exists()


@pytest.mark.parametrize(
    "text, key",
    [
        ("", None),
        ("{not json\n", None),
        ('{"format": "ftrac-observation"}\n', "format"),
        (json.dumps(_pose(np.eye(3), [0, 0, 1])).replace('"rotation"', '"rot"') + "\n", "rotation"),
        (json.dumps(_pose(np.eye(3) * 2, [0, 0, 1])) + "\n", "rotation"),
        (json.dumps(_pose(np.eye(3), [0, 0])) + "\n", "translation_mm"),
        (json.dumps(_pose(np.eye(3), [0, 0, 1])) + "\n" + "[1, 2]\n", None),
        (json.dumps(_pose(np.eye(3), [0, 0, 1], converged="yes")) + "\n", "converged"),
        (json.dumps(_pose(np.eye(3), [0, 0, 1], time_s="soon")) + "\n", "time_s"),
        (json.dumps(_pose(np.eye(3), [0, 0, 1])).replace("0.1", "NaN") + "\n", None),
    ],
)
@pytest.mark.parametrize("suffix", [".tfm", ".seq.mha"])
def test_malformed_pose_files_exit_2_with_one_line_and_write_nothing(text, key, suffix, tmp_path, capsys):
    src = tmp_path / "poses.jsonl"
    src.write_text(text)
    out = tmp_path / f"out{suffix}"
    assert main(["export", str(src), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(src) in err and "Traceback" not in err
    if key is not None:
        assert key in err
    assert not out.exists() and [p.name for p in tmp_path.iterdir()] == ["poses.jsonl"]
    if key is not None and text:
        with pytest.raises(InputError):
            read_tracked_poses(src)


def test_export_refuses_an_unknown_suffix_and_a_bad_name(run_file, tmp_path, capsys):
    path, _ = run_file
    assert main(["export", str(path), "-o", str(tmp_path / "x.txt")]) == 2
    assert main(["export", str(path), "-o", str(tmp_path / "x.seq.mha"), "--name", "Fiducial_CArm"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 2 and "--output" in err and "--name" in err


# --------------------------------------------------------------------------- export --scene, bad input
def _features_and_model(tmp_path):
    from ftrac_design.design import load_design
    from ftrac_design.design.presets import PRESETS_DIR
    from ftrac_design.features import compute_features

    build = tmp_path / "build"
    build.mkdir()
    write_features(build / "features.json", compute_features(load_design(PRESETS_DIR / "nine_bead.toml")))
    # a binary STL of one triangle (the build's is larger; the scene copies its triangles unchanged)
    tri = np.zeros(1, dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
    tri["v"] = [[[0, 0, 0], [1, 0, 0], [0, 1, 0]]]
    (build / "fiducial.stl").write_bytes(b"made by a test".ljust(80, b"\0") + (1).to_bytes(4, "little") + tri.tobytes())
    return build


def test_a_scene_holds_the_models_triangles_with_an_lps_header_and_only_frames_with_a_pose(run_file, tmp_path):
    path, Ms = run_file
    build = _features_and_model(tmp_path)
    out = tmp_path / "scene"
    assert main(["export", str(path), "--scene", str(out), "--features", str(build / "features.json")]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["beads.mrk.json", "fiducial.stl", "run.seq.mha", "scene.mrml"]
    stl, src = (out / "fiducial.stl").read_bytes(), (build / "fiducial.stl").read_bytes()
    assert stl.startswith(b"SPACE=LPS") and stl[80:] == src[80:]
    f = read_sequence_fields(out / "run.seq.mha")
    assert "Seq_Frame0002_FiducialToCArmTransform" not in f  # 3 lines, one without a pose
    assert np.array_equal(_matrix_field(f["Seq_Frame0001_FiducialToCArmTransform"]), in_space(Ms[2], "ras"))
    # an earlier scene is replaced whole
    assert main(["export", str(path), "--scene", str(out), "--features", str(build / "features.json")]) == 0


@pytest.mark.parametrize(
    "case, key",
    [
        ("no features", "--features"),
        ("no model", "fiducial.stl"),
        ("lps", "--space"),
        ("occupied", "--scene"),
        ("both", "--output"),
    ],
)
def test_export_scene_bad_input_exits_2_with_one_line_and_writes_nothing(run_file, tmp_path, capsys, case, key):
    path, _ = run_file
    build = _features_and_model(tmp_path)
    out = tmp_path / "scene"
    args = ["export", str(path), "--scene", str(out), "--features", str(build / "features.json")]
    if case == "no features":
        args = args[:4]
    elif case == "no model":
        (build / "fiducial.stl").unlink()
    elif case == "lps":
        args += ["--space", "lps"]
    elif case == "occupied":
        out.mkdir()
        (out / "notes.txt").write_text("mine")
    else:
        args += ["-o", str(tmp_path / "x.tfm")]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and key in err and "Traceback" not in err
    assert not out.exists() or [p.name for p in out.iterdir()] == ["notes.txt"]
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]
