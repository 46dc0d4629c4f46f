"""Reconstruction from several tracked images: exact without noise, covariance vs Monte-Carlo,
the frame chain F → M → T as the CAD places the parts (the frames of tests/test_frames.py),
refusals, and the command line's files."""

from __future__ import annotations

import json

import numpy as np
import pytest

from ftrac_design.cli.main import main
from ftrac_design.features import write_features
from ftrac_design.features.mounting import (
    mount_from_fiducial,
    mount_layout,
    template_from_fiducial,
    template_from_mount,
    transform_points,
)
from ftrac_design.pose import Camera, so3
from ftrac_design.pose.simulate import cone_directions, rotations_from_beams
from ftrac_design.reconstruct import Views, triangulate
from ftrac_design.reconstruct import frames as fr

CAM = Camera()


def views_around(
    n: int, spread_deg: float = 20.0, nominal=(0.0, -1.0, 0.0), sigma_px: float = 0.23, pose_cov=None
) -> Views:
    """n views of the F origin at 667 mm, beams on a cone of half-angle spread/2 about ``nominal``."""
    az = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    beams = cone_directions(np.array(nominal), np.full(n, np.radians(spread_deg / 2)), az)
    R = rotations_from_beams(beams, np.radians(np.linspace(-10, 10, n)))
    t = np.column_stack([np.linspace(-5, 5, n), np.linspace(4, -4, n), np.full(n, 667.0)])
    cov = None if pose_cov is None else np.broadcast_to(pose_cov, (n, 6, 6))
    return Views.make(R, t, CAM.intrinsics, sigma_px, cov)


def project(views: Views, P: np.ndarray) -> np.ndarray:
    return np.stack([CAM.project(P @ views.R[i].T + views.t[i]) for i in range(views.N)])


@pytest.mark.parametrize("n", [2, 3, 5])
def test_noise_free_reconstruction_is_exact(n):
    rng = np.random.default_rng(n)
    P = rng.uniform(-60, 60, (20, 3))
    v = views_around(n)
    tri = triangulate(v, project(v, P))
    assert all(r is None for r in tri.refused)
    assert np.abs(tri.P - P).max() < 1e-8
    assert tri.rms_px.max() < 1e-8
    assert np.all(tri.parallax_deg > 2)


def test_points_missing_from_some_views_use_the_others():
    P = np.array([[0.0, 0, 0], [10, -20, 5], [-5, 5, 30]])
    v = views_around(4)
    uv = project(v, P)
    seen = np.ones((4, 3), bool)
    seen[0, 1] = seen[3, 1] = False
    uv[0, 1] = np.nan
    tri = triangulate(v, uv, seen)
    assert np.abs(tri.P - P).max() < 1e-8
    assert tri.used[:, 1].tolist() == [False, True, True, False]


def test_covariance_matches_monte_carlo():
    """Σ_P = (Σ Jᵀ S⁻¹ J)⁻¹ with S = σ²I + C Σθ Cᵀ: poses drawn from their covariance, pixels
    from σ; the sample covariance, whitened by the prediction, has σ's within 15 % of 1."""
    rng = np.random.default_rng(1)
    pose_cov = np.diag([4e-7, 4e-7, 2e-7, 0.01, 0.01, 0.4])  # ~0.04° and 0.1 / 0.1 / 0.6 mm
    v = views_around(3, 25.0, pose_cov=pose_cov)
    P = np.array([[5.0, -90.0, 20.0]])  # a seed 9 cm beyond the fiducial
    uv = project(v, P)
    pred = triangulate(v, uv).cov[0]
    trials = 1500
    err = np.empty((trials, 3))
    for k in range(trials):
        e = rng.multivariate_normal(np.zeros(6), pose_cov, v.N)
        vk = Views(so3.exp(e[:, :3]) @ v.R, v.t + e[:, 3:], v.intr, v.sigma_px, v.pose_cov)
        err[k] = triangulate(vk, uv + rng.normal(0.0, 0.23, uv.shape)).P[0] - P[0]
    L = np.linalg.cholesky(np.linalg.inv(pred))
    w = err @ L  # whitened by the prediction
    s = np.sqrt(np.linalg.eigvalsh(np.cov(w.T)))
    assert np.all((s > 0.85) & (s < 1.15)), s
    assert np.abs(err.mean(0)).max() < 0.2 * np.sqrt(np.diag(pred)).max()


def test_pose_covariance_adds_to_pixel_noise():
    P = np.array([[0.0, -50.0, 10.0]])
    exact = views_around(2)
    uncertain = views_around(2, pose_cov=np.diag([1e-6] * 3 + [0.04, 0.04, 1.0]))
    a, b = triangulate(exact, project(exact, P)).cov[0], triangulate(uncertain, project(uncertain, P)).cov[0]
    assert np.all(np.linalg.eigvalsh(b - a) > 0)


def test_one_view_and_parallel_views_are_refused():
    P = np.array([[0.0, 0, 0], [10, 10, 10]])
    one = views_around(2)
    uv = project(one, P)
    seen = np.array([[True, True], [True, False]])
    tri = triangulate(one, uv, seen)
    assert tri.refused[0] is None
    assert "seen in 1 image" in tri.refused[1]
    near = views_around(2, spread_deg=1.0)  # beams 1° apart
    tri = triangulate(near, project(near, P))
    assert all(r is not None and "nearly parallel" in r for r in tri.refused)
    assert triangulate(near, project(near, P), min_parallax_deg=0.5).refused == [None, None]


def test_inconsistent_points_are_refused():
    v = views_around(3)
    uv = project(v, np.array([[0.0, 0, 0]]))
    uv[1, 0, 0] += 20.0
    assert "do not meet in 3-D" in triangulate(v, uv).refused[0]


def test_uncertain_transform_propagation_matches_monte_carlo():
    rng = np.random.default_rng(3)
    M = np.eye(4)
    M[:3, :3] = so3.exp(np.array([0.3, -0.2, 1.0]))
    M[:3, 3] = [10.0, -20.0, 30.0]
    T = fr.RigidTransform(M, "template", "ultrasound", fr.isotropic_covariance(0.5, np.radians(0.5)))
    P, C = np.array([[40.0, 80.0, -30.0]]), np.diag([0.04, 0.09, 0.25])[None]
    Pq, Cq = fr.apply(T, P, C)
    assert np.allclose(Pq, transform_points(M, P))
    samples = []
    for _ in range(4000):
        Mk = fr.sample(T, rng)
        samples.append(transform_points(Mk, rng.multivariate_normal(P[0], C[0])))
    S = np.cov(np.array(samples).reshape(-1, 3).T)
    assert np.allclose(np.sqrt(np.diag(S)), np.sqrt(np.diag(Cq[0])), rtol=0.1)
    # a certain transform rotates the covariance exactly
    Te = fr.RigidTransform(M, "a", "b")
    assert np.allclose(fr.apply(Te, P, C)[1][0], M[:3, :3] @ C[0] @ M[:3, :3].T)


# --------------------------------------------------------------------------- the files and the CLI
@pytest.fixture
def files(tmp_path, features_2005):
    """features.json, poses.jsonl (true poses, a small covariance), camera.json and points.jsonl for
    three views of the beads and of the axis point on the mount's bottom face."""
    from ftrac_design.pose.solver import Pose

    write_features(tmp_path / "features.json", features_2005)
    v = views_around(3, 30.0)
    ids = [p.id for p in features_2005.points]
    P = np.array([p.center for p in features_2005.points])
    lines = []
    for i in range(v.N):
        pose = Pose(v.R[i], v.t[i], True, 0.1, np.diag([1e-8] * 3 + [1e-4] * 3), {}, 1)
        lines.append(json.dumps(pose.to_dict()))
    (tmp_path / "poses.jsonl").write_text("\n".join(lines) + "\n")
    (tmp_path / "camera.json").write_text(json.dumps(CAM.to_dict()))
    return tmp_path, v, ids, P


def write_points(path, v, ids, P):
    uv = project(v, P)
    path.write_text("".join(json.dumps({k: uv[i, j].tolist() for j, k in enumerate(ids)}) + "\n" for i in range(v.N)))


def run(tmp, *extra):
    return main(
        [
            "reconstruct",
            "--features",
            str(tmp / "features.json"),
            "--poses",
            str(tmp / "poses.jsonl"),
            "--points",
            str(tmp / "points.jsonl"),
            "--camera",
            str(tmp / "camera.json"),
            "-o",
            str(tmp / "out.json"),
            *extra,
        ]
    )


def test_cli_frame_chain_F_M_T_as_the_cad_places_the_parts(files, design_2005, capsys):
    """An axis point on the mount's bottom face, reconstructed with --to template, lands where
    tests/test_frames.py finds it in the connector's own frame: (axis_x, axis_height, −pocket_depth);
    every point's T position is template_from_mount · mount_from_fiducial · P_F."""
    tmp, v, ids, P = files
    d = design_2005
    A_F = np.array([0.0, 0.0, -d.half_length - mount_layout(d).base_height])
    write_points(tmp / "points.jsonl", v, ids + ["A"], np.vstack([P, A_F]))
    assert run(tmp, "--to", "template") == 0
    out = json.loads((tmp / "out.json").read_text())
    assert out["format"] == "ftrac-reconstruction" and out["version"] == 1 and out["frame"] == "template"
    assert out["frame_chain"] == ["fiducial", "template"]
    a = out["points"]["A"]
    assert np.allclose(
        a["position_mm"], [d.connector.axis_x, d.connector.axis_height, -d.connector.pocket_depth], atol=1e-6
    )
    chain = template_from_mount(d) @ mount_from_fiducial(d)
    assert np.allclose(chain, template_from_fiducial(d))
    for j, k in enumerate(ids):
        e = out["points"][k]
        assert np.allclose(e["position_fiducial_mm"], P[j], atol=1e-6)
        assert np.allclose(e["position_mm"], transform_points(chain, P[j]), atol=1e-6)
        R = chain[:3, :3]
        assert np.allclose(np.array(e["covariance_mm2"]), R @ np.array(e["covariance_fiducial_mm2"]) @ R.T, atol=1e-8)
        assert e["views"] == [0, 1, 2] and e["rms_reprojection_px"] < 1e-6


def test_cli_transform_and_refusals(files, capsys):
    tmp, v, ids, P = files
    write_points(tmp / "points.jsonl", v, ids, P)
    lines = (tmp / "points.jsonl").read_text().splitlines()
    # B1 in the first image only
    rows = [json.loads(s) for s in lines]
    for r in rows[1:]:
        del r["B1"]
    (tmp / "points.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    M = np.eye(4)
    M[:3, 3] = [1.0, 2.0, 3.0]
    (tmp / "tu.json").write_text(
        json.dumps({"matrix": M.tolist(), "name": "ultrasound", "covariance": np.diag([0, 0, 0, 1.0, 1, 1]).tolist()})
    )
    assert run(tmp, "--to", "template", "--transform", str(tmp / "tu.json")) == 0
    out = json.loads((tmp / "out.json").read_text())
    assert out["frame"] == "ultrasound" and out["frame_chain"] == ["fiducial", "template", "ultrasound"]
    assert "seen in 1 image" in out["points"]["B1"]["refused"] and out["refused"] == 1
    assert min(out["points"]["B2"]["std_mm"]) > 1.0  # the transform's 1 mm σ is in it
    assert "B1: refused" in capsys.readouterr().out


def test_cli_exits_1_when_nothing_can_be_reconstructed(files, capsys):
    tmp, v, ids, P = files
    uv = project(v, P)
    (tmp / "points.jsonl").write_text("".join(json.dumps({ids[i]: uv[i, i].tolist()}) + "\n" for i in range(v.N)))
    assert run(tmp) == 1
    out = json.loads((tmp / "out.json").read_text())
    assert out["reconstructed"] == 0


@pytest.mark.parametrize(
    "what, key",
    [
        ("points_bad_json", "points.jsonl:2"),
        ("points_not_uv", "points.jsonl:1: B1"),
        ("points_count", "one line per pose"),
        ("pose_no_rotation", "poses.jsonl:2: rotation"),
        ("pose_bad_cov", "poses.jsonl:1: covariance"),
        ("no_camera", "poses.jsonl:1: camera"),
        ("transform_not_rigid", "tu.json: matrix"),
        ("camera_bad", "camera.json: camera.focal_length_mm"),
    ],
)
def test_cli_malformed_files_exit_2_with_one_line(files, capsys, what, key):
    tmp, v, ids, P = files
    write_points(tmp / "points.jsonl", v, ids, P)
    extra: list[str] = []
    pts = (tmp / "points.jsonl").read_text().splitlines()
    poses = (tmp / "poses.jsonl").read_text().splitlines()
    if what == "points_bad_json":
        pts[1] = pts[1][:-3]
    elif what == "points_not_uv":
        pts[0] = json.dumps({**json.loads(pts[0]), "B1": [1.0]})
    elif what == "points_count":
        pts = pts[:2]
    elif what == "pose_no_rotation":
        d = {k: v for k, v in json.loads(poses[1]).items() if k != "rotation"}
        poses[1] = json.dumps({**d, "converged": True})
    elif what == "pose_bad_cov":
        poses[0] = json.dumps({**json.loads(poses[0]), "covariance": [[1.0] * 5] * 6})
    elif what == "transform_not_rigid":
        (tmp / "tu.json").write_text(json.dumps((2 * np.eye(4)).tolist()))
        extra = ["--transform", str(tmp / "tu.json")]
    elif what == "camera_bad":
        (tmp / "camera.json").write_text(json.dumps({**CAM.to_dict(), "focal_length_mm": "far"}))
    (tmp / "points.jsonl").write_text("\n".join(pts) + "\n")
    (tmp / "poses.jsonl").write_text("\n".join(poses) + "\n")
    if what == "no_camera":
        rc = main(
            [
                "reconstruct",
                "--features",
                str(tmp / "features.json"),
                "--poses",
                str(tmp / "poses.jsonl"),
                "--points",
                str(tmp / "points.jsonl"),
                "-o",
                str(tmp / "out.json"),
            ]
        )
    else:
        rc = run(tmp, *extra)
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2
    assert len(err) == 1 and key in err[0], err
    assert not (tmp / "out.json").exists()


def test_cli_camera_per_line_extension(files):
    """Without --camera, a "camera" key in a points line gives that image's camera."""
    tmp, v, ids, P = files
    write_points(tmp / "points.jsonl", v, ids, P)
    rows = [json.loads(s) for s in (tmp / "points.jsonl").read_text().splitlines()]
    for r in rows:
        r["camera"] = CAM.to_dict()
    (tmp / "points.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    rc = main(
        [
            "reconstruct",
            "--features",
            str(tmp / "features.json"),
            "--poses",
            str(tmp / "poses.jsonl"),
            "--points",
            str(tmp / "points.jsonl"),
            "-o",
            str(tmp / "out.json"),
        ]
    )
    assert rc == 0
    out = json.loads((tmp / "out.json").read_text())
    assert "camera" not in out["points"] and out["reconstructed"] == len(ids)


def test_demo_step(tmp_path):
    from ftrac_design.demo.reconstruct import demo_step

    text = demo_step(tmp_path)
    assert "mean |error|" in text and (tmp_path / "reconstruction.json").exists()
    out = json.loads((tmp_path / "reconstruction.json").read_text())
    assert out["reconstructed"] == 14


def test_cli_unsolved_pose_leaves_its_image_out(files):
    tmp, v, ids, P = files
    write_points(tmp / "points.jsonl", v, ids, P)
    poses = (tmp / "poses.jsonl").read_text().splitlines()
    d = json.loads(poses[2])
    d.update(converged=False, rotation=None, translation_mm=None, covariance=None, error="ambiguous")
    poses[2] = json.dumps(d)
    (tmp / "poses.jsonl").write_text("\n".join(poses) + "\n")
    assert run(tmp) == 0
    out = json.loads((tmp / "out.json").read_text())
    assert out["images_used"] == [0, 1] and out["images_skipped"][0]["index"] == 2
    assert "ambiguous" in out["images_skipped"][0]["reason"]
    assert all(e["views"] == [0, 1] for e in out["points"].values())


def test_cli_template_tolerance_widens_the_covariance(files):
    tmp, v, ids, P = files
    write_points(tmp / "points.jsonl", v, ids, P)
    assert run(tmp, "--to", "template") == 0
    exact = json.loads((tmp / "out.json").read_text())["points"]["B1"]
    assert run(tmp, "--to", "template", "--template-sigma-mm", "0.5") == 0
    loose = json.loads((tmp / "out.json").read_text())["points"]["B1"]
    assert exact["position_mm"] == loose["position_mm"]
    # σ² adds: 0.25 mm² of translation plus the tilt-free part (no rotation σ given)
    assert np.allclose(
        np.array(loose["covariance_mm2"]) - np.array(exact["covariance_mm2"]), 0.25 * np.eye(3), atol=1e-6
    )
