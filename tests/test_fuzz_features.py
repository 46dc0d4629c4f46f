"""Fuzzing ``features.json`` (SPEC §2): the presets' files mutated at any key (type, sign,
magnitude, presence; features added and removed), given to ``solve`` with a valid
observation of the unmutated fiducial and to ``analyze`` at cheap settings, in this process.

Property: exit 0, 1 or 2; exit 2 names file, key and what was expected in one to three
lines and writes nothing; no traceback; nothing half-written. Counts: ``fuzz_support.CASES``.
"""

from __future__ import annotations

import json

from fuzz_support import PRESETS, assert_clean, cases, mutated, run_cli, scratch
from hypothesis import given
from hypothesis import strategies as st
from test_fuzz_observation import BASE, FEATURES

from ftrac_design.features import features_to_dict

DOCS = {p: json.loads(json.dumps(features_to_dict(f))) for p, f in FEATURES.items()}


@st.composite
def features_docs(draw):
    preset = draw(st.sampled_from(PRESETS))
    doc, done = draw(mutated(DOCS[preset]))
    return preset, doc, done


@cases("features_solve")
@given(case=features_docs(), seed=st.integers(0, 2), coefficients=st.booleans())
def test_fuzz_solve_features(case, seed, coefficients):
    preset, doc, done = case
    with scratch() as tmp:
        feats, obs, out = tmp / "features.json", tmp / "obs.json", tmp / "out" / "pose.json"
        feats.write_text(json.dumps(doc), encoding="utf-8")
        obs.write_text(json.dumps(BASE[(preset, seed, coefficients)]), encoding="utf-8")
        run = run_cli(["solve", "--features", feats, obs, "-o", out, "--starts", "16"])
        assert_clean(run, [feats, obs], tmp)
        if run.code == 2:
            assert not out.exists(), run.describe()
        else:
            pose = json.loads(out.read_text())
            assert pose["converged"] == (run.code == 0), run.describe()
            assert pose["converged"] or pose["error"], run.describe()


@cases("features_analyze")
@given(case=features_docs())
def test_fuzz_analyze_features(case):
    preset, doc, done = case
    with scratch() as tmp:
        feats, out = tmp / "features.json", tmp / "analysis"
        feats.write_text(json.dumps(doc), encoding="utf-8")
        run = run_cli(
            [
                "analyze",
                feats,
                "-o",
                out,
                "--poses",
                "100",
                "--atlas-step-deg",
                "15",
                "--no-plots",
                "--score-images",
                "0",
                "--image-atlas-step-deg",
                "0",
            ]
        )
        assert_clean(run, [feats], tmp)
        if run.code == 2:
            assert not out.exists(), run.describe()
        else:
            assert json.loads((out / "analysis.json").read_text())["format"] == "ftrac-analysis"
