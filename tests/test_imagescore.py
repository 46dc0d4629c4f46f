"""The image-true score: its trial (common random numbers, executor-independent, outcomes
classified against the truth) and its figures (closed forms on known records)."""

from __future__ import annotations

import numpy as np
import pytest

from ftrac_design.design import load_design
from ftrac_design.design.presets import resolve_design
from ftrac_design.features import compute_features
from ftrac_design.imagescore import (
    WRONG_SIGMA,
    TrialSettings,
    condition_figures,
    error_sigma,
    outcome,
    paired_ratios,
    run_images,
    run_trial,
    trial_figures,
)
from ftrac_design.imagescore import trial as trial_module


@pytest.fixture(scope="module")
def ftrac_2005():
    d = load_design(resolve_design("ftrac_2005"))
    return compute_features(d)


def _records(errors_t, errors_r, outcomes, condition="clean"):
    return [
        {"condition": condition, "k": k, "outcome": o, "translation_mm": et, "rotation_deg": er}
        for k, (et, er, o) in enumerate(zip(errors_t, errors_r, outcomes))
    ]


def test_condition_figures_are_the_percentiles_of_the_right_images():
    rng = np.random.default_rng(3)
    t, r = rng.gamma(2.0, 0.1, 60), rng.gamma(2.0, 0.02, 60)
    outcomes = ["right"] * 50 + ["wrong"] * 4 + ["refused"] * 6
    fig = condition_figures(_records(t, r, outcomes))
    assert (fig["images"], fig["right"], fig["wrong"], fig["refused"]) == (60, 50, 4, 6)
    assert fig["refused_pct"] == pytest.approx(10.0) and fig["wrong_pct"] == pytest.approx(100 * 4 / 60)
    assert fig["translation_p95_mm"] == pytest.approx(np.percentile(t[:50], 95))
    assert fig["rotation_median_deg"] == pytest.approx(np.median(r[:50]))
    lo, hi = fig["translation_p95_95ci_mm"]
    assert lo <= fig["translation_p95_mm"] <= hi


def test_too_few_right_images_give_no_percentile():
    fig = condition_figures(_records([0.1] * 10, [0.01] * 10, ["right"] * 10))
    assert fig["translation_p95_mm"] is None and fig["translation_p95_95ci_mm"] is None


def test_paired_ratio_of_a_scaled_trial_is_the_scale_exactly():
    rng = np.random.default_rng(4)
    t, r = rng.gamma(2.0, 0.1, 80), rng.gamma(2.0, 0.02, 80)
    a = _records(t, r, ["right"] * 80)
    b = _records(1.3 * t, 0.5 * r, ["right"] * 80)
    p = paired_ratios(a, b, "clean")
    assert p["images"] == 80
    assert p["translation_p95_ratio"] == pytest.approx(1.3)
    assert p["translation_p95_ratio_95ci"] == pytest.approx([1.3] * 2)
    assert p["rotation_p95_ratio"] == pytest.approx(0.5)
    assert paired_ratios(a, b, "anatomy") is None


def test_pooled_paired_ratio_matches_images_by_condition_and_index():
    rng = np.random.default_rng(5)
    t, r = rng.gamma(2.0, 0.1, 40), rng.gamma(2.0, 0.02, 40)
    a = _records(t[:20], r[:20], ["right"] * 20) + _records(t[20:], r[20:], ["right"] * 20, "anatomy")
    # the same indices k in both conditions: pooling by index alone would pair the wrong images
    b = _records(2 * t[:20], r[:20], ["right"] * 20) + _records(2 * t[20:], r[20:], ["right"] * 20, "anatomy")
    p = paired_ratios(a, b, None)
    assert p["images"] == 40
    assert p["translation_p95_ratio"] == pytest.approx(2.0)
    assert p["rotation_p95_ratio"] == pytest.approx(1.0)
    assert p["translation_p95_ratio_95ci"] == pytest.approx([2.0, 2.0])
    # an image refused by one design drops out of the pairs
    b[0]["outcome"] = "refused"
    assert paired_ratios(a, b, None)["images"] == 39


def test_error_sigma_is_the_mahalanobis_distance():
    s = np.array([1e-3, 2e-3, 3e-3, 0.5, 1.0, 2.0])
    e = np.array([2e-3, -2e-3, 3e-3, 1.0, 0.0, -4.0])
    assert error_sigma(e, np.diag(s**2)) == pytest.approx(np.sqrt(np.sum((e / s) ** 2)))
    q, _ = np.linalg.qr(np.random.default_rng(1).normal(size=(6, 6)))
    cov = q @ np.diag(s**2) @ q.T  # a rotated covariance: the distance of the rotated error is the same
    assert error_sigma(q @ e, cov) == pytest.approx(np.sqrt(np.sum((e / s) ** 2)), rel=1e-9)
    assert error_sigma(e, None) is None
    assert error_sigma(e, np.full((6, 6), np.nan)) is None
    assert error_sigma(e, np.zeros((6, 6))) is None


def test_a_pose_is_wrong_only_when_far_and_inconsistent_with_its_own_covariance():
    # inside the absolute thresholds: right, however small its covariance
    assert outcome(0.5, 2.0, 100.0) == "right"
    # beyond them but as far as its covariance says it may be: the tail of an honest error
    assert outcome(0.4, 4.5, 3.0) == "right"
    assert outcome(1.2, 1.0, WRONG_SIGMA - 1e-9) == "right"
    # beyond both: a confident wrong pose
    assert outcome(0.4, 4.5, WRONG_SIGMA + 1e-9) == "wrong"
    assert outcome(130.0, 1.0, 5e3) == "wrong"
    # no covariance to judge by: the thresholds alone
    assert outcome(0.4, 3.1, None) == "wrong" and outcome(0.4, 2.9, None) == "right"


def test_trial_is_reproducible_and_independent_of_the_executor(ftrac_2005):
    from ftrac_design.optimize.execution import SerialExecutor

    f = ftrac_2005
    s = TrialSettings(images=3, seed=11)
    here = run_trial(f, s)
    assert here == run_trial(f, s, SerialExecutor())
    assert [(r["condition"], r["k"]) for r in here] == [(c, k) for c in ("clean", "anatomy") for k in range(3)]
    clean = [r for r in here if r["condition"] == "clean"]
    assert all(r["outcome"] == "right" for r in clean)
    assert all(r["translation_mm"] < 1.0 and r["rotation_deg"] < 0.3 for r in clean)
    assert set(trial_figures(here)) == {"clean", "anatomy"}


def test_a_pose_far_from_the_truth_is_wrong_and_no_pose_is_refused(ftrac_2005, monkeypatch):
    from ftrac_design.segment import pipeline

    f = ftrac_2005
    s = TrialSettings(images=2, seed=5, conditions=("clean",))
    real = pipeline.track_image

    def shifted(image, features, camera, *a, **k):
        res = real(image, features, camera, *a, **k)
        res.pose.translation_mm = res.pose.translation_mm + np.array([0.0, 0.0, 4.0])
        return res

    monkeypatch.setattr(pipeline, "track_image", shifted)
    recs = run_images(f, s, "clean", [0, 1])
    assert [r["outcome"] for r in recs] == ["wrong", "wrong"]
    assert all(r["translation_mm"] == pytest.approx(4.0, abs=0.5) for r in recs)

    def refuse(image, features, camera, *a, **k):
        res = real(image, features, camera, *a, **k)
        res.pose.converged = False
        return res

    monkeypatch.setattr(pipeline, "track_image", refuse)
    assert [r["outcome"] for r in run_images(f, s, "clean", [0])] == ["refused"]


def test_common_random_numbers_give_two_designs_the_same_poses_and_draws(ftrac_2005, monkeypatch):
    """Image k's pose and noise do not depend on the design (same nominal beam direction)."""
    f = ftrac_2005
    mini = compute_features(load_design(resolve_design("ftrac_mini")))
    seen = []

    def spy(features, condition, R, t, camera, seed, k):
        seen.append((features.name, condition, R.tobytes(), t.tobytes(), seed, k))
        return np.zeros((8, 8))

    monkeypatch.setattr(trial_module, "_image", spy)
    s = TrialSettings(images=4, seed=2)
    for feats in (f, mini):
        run_images(feats, s, "anatomy", [1, 3])
    a, b = seen[:2], seen[2:]
    assert [x[1:] for x in a] == [x[1:] for x in b]


def test_analyze_reports_the_image_true_score_first(tmp_path, capsys):
    import json

    from ftrac_design.cli.main import main

    out = tmp_path / "a"
    assert (
        main(
            [
                "analyze",
                "ftrac_2005",
                "--poses",
                "100",
                "--atlas-step-deg",
                "15",
                "--score-images",
                "3",
                "--workers",
                "0",
                "--image-atlas-step-deg",
                "45",
                "-o",
                str(out),
            ]
        )
        == 0
    )
    text = capsys.readouterr().out
    assert text.index("image-true score") < text.index("the paper's model")
    doc = json.loads((out / "analysis.json").read_text())
    block = doc["image_score"]
    assert len(block["records"]) == 6 and block["model"]["images_per_condition"] == 3
    assert block["figures"] == trial_figures(block["records"], 0)
    assert "image_score.png" in doc["files"] and (out / "image_score.png").read_bytes()[:4] == b"\x89PNG"
    assert "Cramér–Rao" in doc["paper_model"]
    atlas = doc["image_atlas"]
    assert len(atlas["right_share"]) == 4 and len(atlas["right_share"][0]) == 8  # a 45° grid: 4 × 8 directions
    shares = [v for row in atlas["right_share"] for v in row]
    assert all(v in (0.0, 0.5, 1.0) for v in shares) and atlas["right_share_sphere"] == sum(shares) / len(shares)
    assert "image_atlas.png" in doc["files"] and "image-true atlas" in text


def test_compare_of_a_design_with_itself_gives_ratios_of_exactly_one(tmp_path, capsys):
    """Common random numbers end to end: the same design twice sees the same images and tracks them
    the same way, so every paired ratio is 1 with a zero-width interval."""
    import json

    from ftrac_design.cli.main import main

    out = tmp_path / "c.png"
    assert (
        main(
            [
                "compare",
                "ftrac_2005",
                "ftrac_2005",
                "--poses",
                "100",
                "--score-images",
                "24",
                "--workers",
                "0",
                "-o",
                str(out),
            ]
        )
        == 0
    )
    doc = json.loads(out.with_suffix(".json").read_text())
    first, second = (d["image_score"] for d in doc["designs"])
    assert first["figures"] == second["figures"] and first["vs_first"] is None
    clean = second["vs_first"]["clean"]
    assert clean["images"] == first["figures"]["clean"]["right"] >= 20
    assert clean["translation_p95_ratio"] == 1.0 and clean["translation_p95_ratio_95ci"] == [1.0, 1.0]
    assert clean["rotation_p95_ratio"] == 1.0
    assert "image-true score" in capsys.readouterr().out


def test_the_trial_lifts_the_time_budget(ftrac_2005, monkeypatch):
    """A score measures the method, not the machine's load: every image is tracked with the default
    options but an unlimited time budget (a loaded machine would otherwise refuse more images)
    and one thread (its workers fill the cores; the answers are the same with any number)."""
    from ftrac_design.segment import TrackOptions, pipeline

    f = ftrac_2005
    seen = []
    real = pipeline.track_image

    def spy(image, features, camera, options=None, *a, **k):
        seen.append(options)
        return real(image, features, camera, options, *a, **k)

    monkeypatch.setattr(pipeline, "track_image", spy)
    run_images(f, TrialSettings(images=1, seed=8, conditions=("clean",)), "clean", [0])
    (opts,) = seen
    assert opts.time_budget_s == float("inf") and opts.detector_threads == 1
    lifted = ("time_budget_s", "detector_threads")
    assert {k: v for k, v in vars(opts).items() if k not in lifted} == {
        k: v for k, v in vars(TrackOptions()).items() if k not in lifted
    }


def test_the_optimiser_scores_a_candidate_on_images(ftrac_2005):
    """With an image trial the optimiser's figures are the trial's: pooled p95 of the right poses and
    the shares refused and wrong; too few right images refuse the candidate rather than score it."""
    import tomllib

    from ftrac_design.design.presets import preset_path
    from ftrac_design.optimize.evaluate import EvalSettings, evaluate_candidate
    from ftrac_design.optimize.search import objective_violation

    data = tomllib.loads(preset_path("ftrac_2005").read_text())
    f = ftrac_2005
    trial = TrialSettings(images=22, seed=4, conditions=("clean",))
    e = evaluate_candidate(data, EvalSettings(image_trial=trial))
    recs = run_trial(f, trial)
    right = [r for r in recs if r["outcome"] == "right"]
    assert e["feasible"] and len(right) >= 20
    assert e["figures"]["translation_p95_mm"] == pytest.approx(np.percentile([r["translation_mm"] for r in right], 95))
    assert e["figures"]["rotation_p95_deg"] == pytest.approx(np.percentile([r["rotation_deg"] for r in right], 95))
    assert e["figures"]["refused_pct"] == pytest.approx(100 * sum(r["outcome"] == "refused" for r in recs) / 22)
    assert e["figures"]["clean_translation_p95_mm"] == pytest.approx(trial_figures(recs)["clean"]["translation_p95_mm"])
    small = evaluate_candidate(data, EvalSettings(image_trial=TrialSettings(images=4, seed=4, conditions=("clean",))))
    assert not small["feasible"] and "fewer than 20" in small["refused"]
    ref = {"translation_p95_mm": 1.0, "rotation_p95_deg": 1.0, "wrong_pct": 0.0}
    worse = {"translation_p95_mm": 0.5, "rotation_p95_deg": 0.5, "wrong_pct": 2.5}
    assert objective_violation("max", worse, ref) == pytest.approx(2.5)
    assert objective_violation("max", {**worse, "wrong_pct": 0.0}, ref) == 0.0
