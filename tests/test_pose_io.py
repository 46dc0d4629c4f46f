"""Observation files, pose files and the `solve` command (SPEC §3–5)."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from ftrac_design.cli.main import main
from ftrac_design.errors import InputError
from ftrac_design.features import write_features
from ftrac_design.pose import Camera, observation_from_dict, read_observations
from ftrac_design.pose.simulate import Workspace, simulate_observation


@pytest.fixture()
def workdir(tmp_path, features_2005, monkeypatch):
    monkeypatch.chdir(tmp_path)
    write_features(tmp_path / "features.json", features_2005)
    rng = np.random.default_rng(0)
    R, t = Workspace().sample(3, features_2005.nominal_beam_direction, rng)
    obs = [simulate_observation(features_2005, Camera(), R[i], t[i], 0.25, rng).to_dict() for i in range(3)]
    (tmp_path / "obs.json").write_text(json.dumps(obs[0]))
    (tmp_path / "batch.jsonl").write_text("".join(json.dumps(o) + "\n" for o in obs))
    return tmp_path, obs, (R, t)


def _bad(obs: dict, edit) -> dict:
    o = json.loads(json.dumps(obs))
    edit(o)
    return o


BAD_CASES = [
    ("string where a number belongs", lambda o: o["points"].__setitem__("B1", [1.0, "x"]), "points.B1[1]"),
    ("unknown feature id", lambda o: o["lines"].__setitem__("L9", o["lines"]["L1"]), "lines.L9"),
    ("bead id given as a line", lambda o: o["lines"].__setitem__("B1", o["lines"]["L1"]), "lines.B1"),
    (
        "too few ellipse points",
        lambda o: o["ellipses"]["E1"].__setitem__("points", o["ellipses"]["E1"]["points"][:4]),
        "ellipses.E1.points",
    ),
    (
        "collinear ellipse points",
        lambda o: o["ellipses"]["E1"].__setitem__("points", [[i, 2 * i] for i in range(8)]),
        "ellipses.E1.points",
    ),
    ("negative focal length", lambda o: o["camera"].__setitem__("focal_length_mm", -5), "camera.focal_length_mm"),
    ("missing camera key", lambda o: o["camera"].pop("pixel_size_mm"), "camera.pixel_size_mm"),
    (
        "conic that is no ellipse",
        lambda o: o["ellipses"].__setitem__("E2", {"conic": [1, 0, -1, 0, 0, -1]}),
        "ellipses.E2.conic",
    ),
    ("both points and coefficients", lambda o: o["lines"]["L2"].__setitem__("coefficients", [1, 0, 0]), "lines.L2"),
    ("wrong format", lambda o: o.__setitem__("format", "something-else"), "format"),
]


@pytest.mark.parametrize("name, edit, key", BAD_CASES, ids=[c[0] for c in BAD_CASES])
def test_bad_observation_exits_2_with_one_line(workdir, capsys, name, edit, key):
    tmp, obs, _ = workdir
    (tmp / "bad.json").write_text(json.dumps(_bad(obs[0], edit)))
    rc = main(["solve", "--features", "features.json", "bad.json", "-o", "out.json"])
    err = capsys.readouterr().err
    assert rc == 2
    assert len(err.strip().splitlines()) == 1
    assert "bad.json" in err and key in err
    assert "Traceback" not in err
    assert not (tmp / "out.json").exists()


def test_non_finite_json_constants_are_rejected(workdir, capsys):
    tmp, obs, _ = workdir
    text = json.dumps(obs[0]).replace(str(obs[0]["points"]["B2"][0]), "NaN", 1)
    (tmp / "nan.json").write_text(text)
    assert main(["solve", "--features", "features.json", "nan.json"]) == 2
    err = capsys.readouterr().err
    assert "nan.json" in err and "finite" in err


def test_bad_line_in_a_batch_names_the_line(workdir, capsys):
    tmp, obs, _ = workdir
    lines = (tmp / "batch.jsonl").read_text().splitlines()
    lines[1] = "{not json"
    (tmp / "b2.jsonl").write_text("\n".join(lines) + "\n")
    assert main(["solve", "--features", "features.json", "b2.jsonl", "-o", "out.jsonl"]) == 2
    assert "b2.jsonl:2" in capsys.readouterr().err
    assert not (tmp / "out.jsonl").exists()


def test_solve_one_writes_pose_json(workdir, capsys):
    tmp, obs, (R, t) = workdir
    assert main(["solve", "--features", "features.json", "obs.json"]) == 0
    pose = json.loads((tmp / "pose.json").read_text())
    assert pose["format"] == "ftrac-pose" and pose["version"] == 1 and pose["converged"] is True
    assert pose["covariance_order"] == ["rx", "ry", "rz", "tx", "ty", "tz"]
    Rm = np.array(pose["rotation"])
    assert np.allclose(Rm @ Rm.T, np.eye(3), atol=1e-12)
    assert np.linalg.norm(np.array(pose["translation_mm"]) - t[0]) < 3.0
    cov = np.array(pose["covariance"])
    assert cov.shape == (6, 6) and np.allclose(cov, cov.T) and np.all(np.linalg.eigvalsh(cov) > 0)


def test_solve_batch_writes_json_lines(workdir):
    tmp, obs, _ = workdir
    assert main(["solve", "--features", "features.json", "batch.jsonl", "obs.json", "-o", "all.jsonl"]) == 0
    rows = [json.loads(x) for x in (tmp / "all.jsonl").read_text().splitlines()]
    assert len(rows) == 4 and all(r["converged"] for r in rows)
    assert rows[0]["observation"].endswith("batch.jsonl:1")


def test_unsolvable_image_exits_1_and_still_writes(workdir, capsys):
    tmp, obs, _ = workdir
    few = {"camera": obs[0]["camera"], "points": {k: obs[0]["points"][k] for k in ("B1", "B5")}}
    (tmp / "few.json").write_text(json.dumps(few))
    assert main(["solve", "--features", "features.json", "few.json", "-o", "few_pose.json"]) == 1
    pose = json.loads((tmp / "few_pose.json").read_text())
    assert pose["converged"] is False and "do not constrain" in pose["error"]
    assert pose["rotation"] is None


@pytest.mark.parametrize(
    "argv, needle",
    [
        (["solve", "obs.json"], "--features"),
        (["solve", "--features", "missing.json", "obs.json"], "missing.json"),
        (["solve", "--features", "features.json", "obs.json", "--starts", "0"], "--starts"),
        (["solve", "--features", "features.json"], "OBSERVATIONS"),
    ],
)
def test_usage_errors_exit_2(workdir, capsys, argv, needle):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert needle in err and len(err.strip().splitlines()) == 1


def test_bad_features_file_is_named(workdir, capsys):
    tmp, obs, _ = workdir
    f = json.loads((tmp / "features.json").read_text())
    f["ellipses"][0]["minor_axis"] = [1.0, 1.0, 0.0]
    (tmp / "f2.json").write_text(json.dumps(f))
    assert main(["solve", "--features", "f2.json", "obs.json"]) == 2
    err = capsys.readouterr().err
    assert "f2.json" in err and "ellipses[0]" in err


def test_console_entry_runs_as_a_process(workdir):
    tmp, _, _ = workdir
    r = subprocess.run(
        [sys.executable, "-m", "ftrac_design.cli.main", "solve", "--features", "features.json", "obs.json", "-o", "-"],
        capture_output=True,
        text=True,
        cwd=tmp,
    )
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["converged"] is True


def test_observation_round_trip(features_2005):
    R, t = Workspace().sample(1, features_2005.nominal_beam_direction, np.random.default_rng(1))
    o = simulate_observation(features_2005, Camera(), R[0], t[0], 0.25, np.random.default_rng(2))
    o2 = observation_from_dict(json.loads(json.dumps(o.to_dict())))
    assert o2.structure == o.structure
    assert np.allclose(o2.ellipses["E1"].points, o.ellipses["E1"].points)


def test_empty_jsonl_is_bad_input(tmp_path):
    (tmp_path / "e.jsonl").write_text("\n\n")
    with pytest.raises(InputError, match="e.jsonl"):
        list(read_observations(tmp_path / "e.jsonl"))


def test_a_noisy_thin_ellipse_is_not_an_input_error(features_2005):
    """A nearly edge-on ellipse under heavy noise can fit as a thin hyperbola; that is the
    solver's to weigh (thin-ellipse down-weighting), not a malformed observation."""
    from ftrac_design.pose import compile_problem
    from ftrac_design.pose.fitting import fit_conic

    R, t = Workspace().sample(1, features_2005.nominal_beam_direction, np.random.default_rng(5))
    obs = simulate_observation(features_2005, Camera(), R[0], t[0], 0.25, np.random.default_rng(6))
    s = np.linspace(0, 2 * np.pi, 24, endpoint=False)
    pts = np.stack([300 + 80 * np.cos(s), 200 + 1.0 * np.sin(s)], -1) + np.random.default_rng(0).normal(0, 2, (24, 2))
    th = fit_conic(pts[None]).theta[0]
    assert 4 * th[0] * th[2] - th[1] ** 2 <= 0  # the premise: it fits as a hyperbola
    obs.ellipses["E1"].points = pts
    prob = compile_problem(features_2005, [obs])
    assert prob.e_info.shape[1] == 2
