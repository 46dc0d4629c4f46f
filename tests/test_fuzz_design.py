"""Fuzzing design files: every key of the presets mutated in type, sign, magnitude and
presence, arrays of tables added and removed, run through the real command line in this
process (``check``; ``analyze`` at cheap settings; ``build`` only with designs that must fail
validation, which exit 2 before any CAD — the CAD path on valid designs is ``test_build.py``'s).

Property (SPEC §5): exit 0, 1 or 2; exit 2 prints one to three lines naming the file, the
key and what was expected; no traceback; nothing half-written. Counts: ``fuzz_support.CASES``.
"""

from __future__ import annotations

import json
import tomllib

from fuzz_support import MODELS, PRESETS, assert_clean, cases, mutated, run_cli, scratch, to_toml
from hypothesis import assume, given
from hypothesis import strategies as st

from ftrac_design.design.loader import parse_design
from ftrac_design.errors import InputError

DOCS = {p: tomllib.loads((MODELS / f"{p}.toml").read_text()) for p in PRESETS}


def test_toml_writer_round_trips_the_presets():
    for name, doc in DOCS.items():
        assert tomllib.loads(to_toml(doc)) == doc, name


@st.composite
def design_text(draw) -> tuple[str, str, list[str]]:
    preset = draw(st.sampled_from(PRESETS))
    doc, done = draw(mutated(DOCS[preset]))
    return preset, to_toml(doc), done


def _is_valid(text: str) -> bool:
    try:
        parse_design(tomllib.loads(text))
    except (InputError, tomllib.TOMLDecodeError):
        return False
    return True


@cases("design_check")
@given(case=design_text(), profile=st.sampled_from(["cnc", "fdm"]), as_json=st.booleans())
def test_fuzz_check(case, profile, as_json):
    preset, text, done = case
    with scratch() as tmp:
        path = tmp / f"{preset}.toml"
        path.write_text(text, encoding="utf-8")
        run = run_cli(["check", path, "--profile", profile] + (["--json"] if as_json else []))
        assert_clean(run, [path], tmp)
        if as_json and run.code in (0, 1):
            assert json.loads(run.out)["format"] == "ftrac-check", run.describe()


@cases("design_check")
@given(
    data=st.binary(max_size=200) | st.text(max_size=200).map(lambda s: s.encode("utf-8", "surrogatepass")),
    preset=st.sampled_from(PRESETS),
    cut=st.integers(0, 4000),
)
def test_fuzz_check_raw_bytes(data, preset, cut):
    """Truncated presets with garbage appended, and arbitrary bytes."""
    raw = (MODELS / f"{preset}.toml").read_bytes()[:cut] + data
    with scratch() as tmp:
        path = tmp / "raw.toml"
        path.write_bytes(raw)
        assert_clean(run_cli(["check", path]), [path], tmp)


@cases("design_build")
@given(case=design_text())
def test_fuzz_build_rejects_before_cad(case):
    preset, text, done = case
    assume(not _is_valid(text))
    with scratch() as tmp:
        path = tmp / f"{preset}.toml"
        path.write_text(text, encoding="utf-8")
        out = tmp / "out"
        run = run_cli(["build", path, "-o", out])
        assert_clean(run, [path], tmp)
        assert run.code == 2, run.describe()
        assert not out.exists(), run.describe()


@cases("design_analyze")
@given(case=design_text())
def test_fuzz_analyze_design(case):
    preset, text, done = case
    with scratch() as tmp:
        path = tmp / f"{preset}.toml"
        path.write_text(text, encoding="utf-8")
        out = tmp / "analysis"
        run = run_cli(
            [
                "analyze",
                path,
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
        assert_clean(run, [path], tmp)
        if run.code == 2:
            assert not out.exists(), run.describe()
        else:
            assert json.loads((out / "analysis.json").read_text())["format"] == "ftrac-analysis"
