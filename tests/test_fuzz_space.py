"""Fuzzing search-space files given to ``ftrac-design optimize --space`` (in this process):
the shipped spaces and each preset's default space, every key mutated (bounds of the wrong
type, sign, order and magnitude, unknown parameters, [search] values), plus arbitrary bytes.
Validation is exercised through ``--print-space`` (parses and checks the space, then prints
it; no search), and a few mutated spaces that parse are run for one tiny generation in this
process (``--evaluations 1 --workers 0``, 100 poses, no verification images, no build).

Property: exit 0, 1 or 2; exit 2 names the file in one to three lines; no traceback;
nothing half-written in the output directory. Counts: ``fuzz_support.CASES``.
"""

from __future__ import annotations

import tomllib

from fuzz_support import MODELS, PRESETS, assert_clean, cases, mutated, run_cli, scratch, to_toml
from hypothesis import assume, given
from hypothesis import strategies as st


def _default_space(preset: str) -> dict:
    run = run_cli(["optimize", MODELS / f"{preset}.toml", "--print-space"])
    assert run.code == 0, run.describe()
    return tomllib.loads(run.out)


SPACES = {f"default:{p}": (p, _default_space(p)) for p in PRESETS if p != "nine_bead"}
# A shipped space is named after the preset it searches (``<preset>_<what>.toml``).
SPACES.update(
    {
        f"file:{f.stem}": (
            max((p for p in PRESETS if f.stem.startswith(p + "_")), key=len),
            tomllib.loads(f.read_text()),
        )
        for f in sorted((MODELS / "spaces").glob("*.toml"))
    }
)


@st.composite
def space_files(draw):
    name = draw(st.sampled_from(sorted(SPACES)))
    preset, doc = SPACES[name]
    doc = dict(doc)
    if draw(st.booleans()):
        doc["search"] = {"poses": 100, "popsize": 4}
    mdoc, done = draw(mutated(doc))
    return preset, to_toml(mdoc), [name] + done


@cases("space_optimize")
@given(case=space_files())
def test_fuzz_space_print(case):
    preset, text, done = case
    with scratch() as tmp:
        space = tmp / "space.toml"
        space.write_text(text, encoding="utf-8")
        run = run_cli(["optimize", MODELS / f"{preset}.toml", "--space", space, "--print-space"])
        assert_clean(run, [space], tmp)
        if run.code == 0:
            tomllib.loads(run.out)  # what it prints is a space file again


@cases("space_optimize")
@given(data=st.binary(max_size=300), preset=st.sampled_from(["ftrac_2005", "ftrac_mini"]))
def test_fuzz_space_raw_bytes(data, preset):
    with scratch() as tmp:
        space = tmp / "space.toml"
        space.write_bytes(data)
        run = run_cli(["optimize", MODELS / f"{preset}.toml", "--space", space, "--print-space"])
        assert_clean(run, [space], tmp)
        assert run.code == 2, run.describe()


@cases("space_optimize_run")
@given(case=space_files())
def test_fuzz_space_tiny_run(case):
    preset, text, done = case
    with scratch() as tmp:
        space = tmp / "space.toml"
        space.write_text(text, encoding="utf-8")
        check = run_cli(["optimize", MODELS / f"{preset}.toml", "--space", space, "--print-space"])
        assume(check.code == 0)  # invalid spaces are the test above's
        out = tmp / "opt"
        run = run_cli(
            [
                "optimize",
                MODELS / f"{preset}.toml",
                "--space",
                space,
                "-o",
                out,
                "--evaluations",
                "1",
                "--workers",
                "0",
                "--poses",
                "100",
                "--verify-poses",
                "100",
                "--solver-images",
                "0",
                "--check-images",
                "0",
                "--no-build",
            ]
        )
        assert_clean(run, [space], tmp)
        assert run.code in (0, 1), run.describe()
